"""A user's motion from samples or a file: derivatives, their estimate, refusals, and
inverse dynamics at the file's own times (``rrt-pin inverse --trajectory``)."""

from __future__ import annotations

import numpy as np
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.errors import InputError
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.sampled import (
    MIN_SAMPLES,
    motion_from_frame,
    read_motion,
    sampled_motion,
)
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.robots import chapter_arm, get


def _sines(t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    q = np.column_stack([np.sin(t), 0.5 * np.cos(2 * t), 0.1 * t**2])
    qd = np.column_stack([np.cos(t), -np.sin(2 * t), 0.2 * t])
    qdd = np.column_stack([-np.sin(t), -2 * np.cos(2 * t), np.full_like(t, 0.2)])
    return q, qd, qdd


@pytest.mark.parametrize("count", [21, 201, 2001])
def test_derivatives_of_a_smooth_motion_and_their_estimate(count):
    t = np.linspace(0.0, 2.0, count)
    q, qd, qdd = _sines(t)
    m = sampled_motion(t, q, robot=chapter_arm())
    assert m.derived == ("qd", "qdd") and m.method.startswith("quintic")
    true_qd, true_qdd = np.abs(m.qd - qd).max(), np.abs(m.qdd - qdd).max()
    assert true_qdd < 2e-3  # even at 10 samples a second
    # the estimate follows the true error (never below a third of it)
    for estimate, true in ((m.error_qd, true_qd), (m.error_qdd, true_qdd)):
        assert true / 3 <= estimate <= 30 * true + 1e-12, (estimate, true)
    assert "estimated error" in m.describe()


def test_given_derivatives_are_used_as_they_are():
    t = np.linspace(0.0, 1.0, 11)
    q, qd, qdd = _sines(t)
    m = sampled_motion(t, q, qd, qdd)
    assert m.derived == () and m.error_qd is None and np.array_equal(m.qdd, qdd)
    assert m.describe() == "velocities and accelerations as given"
    only_qd = sampled_motion(t, q, qd)  # q̈ from the spline through q̇
    assert only_qd.derived == ("qdd",) and np.array_equal(only_qd.qd, qd)
    assert np.abs(only_qd.qdd - qdd).max() < 1e-3 and only_qd.error_qdd > 0


@pytest.mark.parametrize(
    "change, words",
    [
        ({"t": np.linspace(0, 1, MIN_SAMPLES - 1)}, "5 samples are too few to differentiate"),
        ({"t": np.array([0.0, 0.1, 0.1, 0.3, 0.4, 0.5, 0.6])}, "times must increase strictly"),
        ({"q_nan": True}, "q[3, 1]=nan is not finite"),
        ({"degrees": True}, "given in degrees?"),
        ({"q": np.zeros((7, 2))}, "q has shape (7, 2); it needs (7, 3)"),
    ],
)
def test_bad_samples_are_one_line(change, words):
    t = change.get("t", np.linspace(0.0, 0.6, 7))
    q = change.get("q", np.zeros((t.size, 3)))
    if change.get("q_nan"):
        q[3, 1] = np.nan
    if change.get("degrees"):
        q[:, 0] = np.linspace(0.0, 90.0, t.size)  # degrees for a revolute joint
    with pytest.raises(InputError) as info:
        sampled_motion(t, q, robot=chapter_arm())
    assert words in str(info.value) and "\n" not in str(info.value)


def test_a_continuous_joint_may_wind_past_two_turns():
    robot = get("double_pendulum_continuous")
    t = np.linspace(0.0, 1.0, 11)
    q = np.column_stack([np.linspace(0.0, 30.0, 11), np.zeros(11)])  # five turns
    assert sampled_motion(t, q, robot=robot).q[-1, 0] == 30.0


def test_a_csv_written_by_inverse_comes_back_bit_for_bit(tmp_path, capsys):
    first, second = tmp_path / "eq30.csv", tmp_path / "again.csv"
    assert main(["inverse", "--dt", "0.01", "--csv", str(first)]) == 0
    assert main(["inverse", "--trajectory", str(first), "--csv", str(second)]) == 0
    out = capsys.readouterr().out
    assert "along the motion in eq30.csv" in out and "as given" in out
    assert first.read_bytes() == second.read_bytes()  # its qd, qdd taken as they are
    # with t and q only: the spline's derivatives, efforts to 1e-8 of eq. (30)'s exact ones
    lines = first.read_text().splitlines()
    q_only = tmp_path / "q.csv"
    q_only.write_text("\n".join(",".join(line.split(",")[:4]) for line in lines) + "\n")
    third = tmp_path / "spline.csv"
    assert main(["inverse", "--trajectory", str(q_only), "--csv", str(third),
                 "--json", str(tmp_path / "s.json")]) == 0  # fmt: skip
    a = np.loadtxt(first, delimiter=",", skiprows=1)
    b = np.loadtxt(third, delimiter=",", skiprows=1)
    assert np.array_equal(a[:, :4], b[:, :4])
    assert np.abs(a[:, 10:] - b[:, 10:]).max() < 1e-8
    import json

    derivatives = json.loads((tmp_path / "s.json").read_text())["metadata"]["derivatives"]
    assert derivatives["derived"] == ["qd", "qdd"] and derivatives["error_qdd"] > 0


def test_a_parquet_motion_and_its_units(tmp_path, capsys):
    import pyarrow.parquet as pq  # the parquet extra, part of test

    run = tmp_path / "run.parquet"
    assert main(["inverse", "--dt", "0.05", "--csv", str(run)]) == 0
    arm = chapter_arm()
    m = read_motion(run, arm)
    assert m.derived == () and m.t.size == 301
    table = pq.read_table(run)
    meta = dict(table.schema.metadata)
    meta[b"rrt_pin.units"] = meta[b"rrt_pin.units"].replace(b'"q1": "rad"', b'"q1": "deg"')
    wrong = tmp_path / "wrong.parquet"
    pq.write_table(table.replace_schema_metadata(meta), wrong)
    with pytest.raises(InputError, match=r"column 'q1' is in deg; RRT arm needs rad"):
        read_motion(wrong, arm)


def test_inverse_dynamics_takes_a_motion_or_a_frame():
    arm = chapter_arm()
    d = arm.defaults
    traj = rest_to_rest(d.q0, d.qf, d.Tp, np.linspace(0.0, d.Tp, 1501))
    exact = inverse_dynamics(arm, traj.q, traj.qd, traj.qdd)
    assert np.array_equal(inverse_dynamics(arm, traj), exact)
    import pandas as pd  # the parquet extra, part of test

    frame = pd.DataFrame({"t": traj.t, **{n: traj.q[:, k] for k, n in enumerate(arm.q_names)}})
    assert np.abs(inverse_dynamics(arm, frame) - exact).max() < 1e-8
    assert motion_from_frame(frame, arm).derived == ("qd", "qdd")
    with pytest.raises(InputError, match="needs q, qd and qdd, or a motion"):
        inverse_dynamics(arm, traj.q)
    with pytest.raises(InputError, match="needs qd and qdd with q"):
        inverse_dynamics(arm, traj, traj.qd)


def test_a_ur5_round_trip_through_files(tmp_path, capsys):
    """A UR5 motion known analytically, at 1 kHz: efforts from the file equal a pin.rnea loop
    (derivatives given) or come within the estimate (q only); played back open loop, the
    efforts move the arm along the motion."""
    import pinocchio as pin

    ur5 = get("ur5")
    t = np.linspace(0.0, 1.0, 1001)
    w = np.arange(1, 7) * 0.7
    q = 0.4 * np.sin(np.outer(t, w))
    qd = 0.4 * w * np.cos(np.outer(t, w))
    qdd = -0.4 * w**2 * np.sin(np.outer(t, w))
    data = ur5.model.createData()
    ref = np.array([pin.rnea(ur5.model, data, a, b, c) for a, b, c in zip(q, qd, qdd, strict=True)])
    names = [*ur5.q_names, *ur5.qd_names, *ur5.qdd_names]

    def write(path, columns):
        head = ",".join(["t", *names[: columns.shape[1]]])
        rows = "\n".join(
            ",".join(repr(float(x)) for x in (s, *r)) for s, r in zip(t, columns, strict=True)
        )
        path.write_text(head + "\n" + rows + "\n")

    full, only_q = tmp_path / "full.csv", tmp_path / "q.csv"
    write(full, np.hstack([q, qd, qdd]))
    write(only_q, q)
    scale = np.abs(ref).max()
    for source, bound in ((full, 1e-12), (only_q, 1e-6)):
        out = tmp_path / f"tau_{source.name}"
        assert (
            main(["inverse", "--robot", "ur5", "--trajectory", str(source), "--csv", str(out)]) == 0
        )
        tau = np.loadtxt(out, delimiter=",", skiprows=1)[:, 19:25]
        assert np.abs(tau - ref).max() / scale <= bound, source.name
    # the efforts (with the motion, as inverse wrote them) played back open loop
    replay = tmp_path / "replay.csv"
    assert main(["simulate", "--robot", "ur5", "--efforts", str(tmp_path / "tau_full.csv"),
                 "--tf", "1", "--dt", "0.01", "--csv", str(replay)]) == 0  # fmt: skip
    got = np.loadtxt(replay, delimiter=",", skiprows=1)[:, 1:7]
    assert np.abs(got - q[::10]).max() <= 2e-5
    capsys.readouterr()
