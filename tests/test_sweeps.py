"""Sweeps: specs, metrics equal to single runs, Dask workers (killed too), resume, determinism."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.errors import SpecError
from rrt_pin.robot.robot import Robot
from rrt_pin.sweeps.run import sweep
from rrt_pin.sweeps.spec import spec_from_dict

pytestmark = pytest.mark.usefixtures("auto_backend")  # sweeps choose their backend

ROOT = Path(__file__).resolve().parents[1]

SPEC = {
    "sweep": {"tf": 3.0, "dt": 0.02, "count": 1500, "seed": 11, "chunk": 1000},
    "vary": {
        "m3": [35.0, 45.0],
        "gamma01": {"uniform": [225.0, 375.0]},
        "q10": {"normal": [0.1745, 0.05]},
        "beta23": {"lhs": [120.0, 180.0]},
    },
    "keep": {"trajectories": [3, 1000]},
}


def _rows(out: Path):
    table = pq.read_table(out / "chunks").sort_by("variant")
    return {name: table.column(name).to_numpy(zero_copy_only=False) for name in table.column_names}


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """The sweep in this process (no Dask), chunks of 500."""
    out = tmp_path_factory.mktemp("sweep") / "ref"
    result = sweep(SPEC, out, workers=1, progress=False)
    assert result.variants == 3000 and result.chunks == 3 and result.computed == 3
    return out, _rows(out)


def test_spec_values_are_a_grid_times_random_samples():
    spec = spec_from_dict(SPEC)
    assert spec.variants == 2 * 1500 and spec.chunks[-1] == (2000, 3000)
    v = spec.values(0, 3000)
    assert set(np.unique(v["m3"])) == {35.0, 45.0} and (v["m3"][:1500] == 35.0).all()
    np.testing.assert_array_equal(v["gamma01"][:1500], v["gamma01"][1500:])  # same samples
    assert 225 <= v["gamma01"].min() and v["gamma01"].max() <= 375
    # Latin hypercube: one sample in each of the 1500 strata
    strata = np.floor((v["beta23"][:1500] - 120.0) / 60.0 * 1500).astype(int)
    assert sorted(strata) == list(range(1500))
    # a range's values never depend on how it is cut
    parts = [spec.values(a, b) for a, b in ((0, 333), (333, 3000))]
    for name in v:
        np.testing.assert_array_equal(np.concatenate([p[name] for p in parts]), v[name])


def test_metrics_equal_single_runs(reference):
    """Every metric of sampled variants equals a single simulate() of its parameters (1e-9)."""
    from rrt_pin.core.grid import time_grid
    from rrt_pin.robot.params import Params
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.simulate import simulate
    from rrt_pin.simulate.control import regulator
    from rrt_pin.simulate.metrics import settling_times

    _, rows = reference
    t = time_grid(3.0, 0.02)
    for i in (0, 1499, 1500, 2999):
        p = Params(**{n: float(rows[n][i]) for n in ("m3", "gamma01", "q10", "beta23")})
        arm = chapter_arm(p)
        for backend, tol in (("compiled", 0.0), ("pinocchio", 1e-9)):
            run = simulate(arm, regulator(arm), p.q0, p.qd0, t, backend=backend, method="DOP853")
            for k, name in enumerate(("q1", "q2", "q3")):
                err = abs(run.q[-1, k] - p.qf[k])
                assert abs(rows[f"final_error_{name}"][i] - err) <= tol
                assert (
                    abs(rows[f"excursion_{name}"][i] - np.abs(run.q[:, k] - run.q[0, k]).max())
                    <= tol
                )
            settle = settling_times(run.t, run.q, p.q0, p.qf)
            got = [rows[f"settling_time_{n}"][i] for n in ("q1", "q2", "q3")]
            assert [np.nan if s is None else s for s in settle] == pytest.approx(got, nan_ok=True)
            for k, name in enumerate(("T01x", "T12y", "F23z")):
                j = int(np.argmax(np.abs(run.tau[:, k])))
                assert (
                    abs(rows[f"peak_effort_{name}"][i] - abs(run.tau[j, k]))
                    <= 1e-9 * abs(run.tau[j, k]) + tol
                )
            power = np.abs(run.tau * run.qd).sum(axis=1)
            energy = float(np.sum(0.5 * (power[1:] + power[:-1]) * np.diff(run.t)))
            assert abs(rows["control_energy"][i] - energy) <= 1e-9 * energy
            if backend == "compiled":
                assert rows["evaluations"][i] == run.n_evals
    assert not rows["diverged"].any() and (rows["variant"] == np.arange(3000)).all()


def test_kept_trajectories_and_metadata(reference):
    out, rows = reference
    import pandas as pd  # as the README reads the results

    frame = pd.read_parquet(out / "chunks")
    assert len(frame) == 3000 and set(frame["variant"]) == set(range(3000))
    dense = pq.read_table(out / "trajectories" / "variant-1000.parquet")
    assert dense.column_names[:4] == ["t", "q1", "q2", "q3"] and dense.num_rows == 151
    q3 = dense.column("q3").to_numpy()
    assert rows["excursion_q3"][1000] == pytest.approx(np.abs(q3 - q3[0]).max(), rel=1e-12)
    meta = pq.read_schema(out / "chunks" / "chunk-000000.parquet").metadata
    import json

    units = json.loads(meta[b"rrt_pin.units"])
    assert units["m3"] == "kg" and units["settling_time_q1"] == "s"
    assert units["peak_effort_F23z"] == "N" and units["control_energy"] == "J"


def test_two_dask_workers_and_another_chunk_size_give_the_same_bits(reference, tmp_path):
    _, ref = reference
    spec = {**SPEC, "sweep": {**SPEC["sweep"], "chunk": 256}}
    result = sweep(spec, tmp_path / "two", workers=2, progress=False)
    assert result.chunks == 12
    rows = _rows(tmp_path / "two")
    for name, col in ref.items():
        np.testing.assert_array_equal(rows[name], col, err_msg=name)


def test_a_killed_worker_loses_nothing(reference, tmp_path):
    """SIGKILL one of two workers mid-sweep: Dask retries its chunk; every variant once."""
    import psutil
    from distributed import LocalCluster

    _, ref = reference
    spec = {**SPEC, "sweep": {**SPEC["sweep"], "chunk": 200}}
    out = tmp_path / "killed"
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:  # fmt: skip
        # the worker processes: this process's new children (no second client here)
        pids = [p.pid for p in psutil.Process().children(recursive=True)
                if p.pid not in before and "python" in p.name()]  # fmt: skip
        assert len(pids) >= 2
        killed = []

        def killer():
            deadline = time.monotonic() + 60
            while time.monotonic() < deadline and not killed:
                if len(list((out / "chunks").glob("*.parquet"))) >= 2:
                    os.kill(pids[0], signal.SIGKILL)
                    killed.append(pids[0])
                time.sleep(0.01)

        thread = threading.Thread(target=killer)
        thread.start()
        result = sweep(spec, out, scheduler=cluster.scheduler_address, progress=False)
        thread.join()
    assert killed and result.computed == 15
    rows = _rows(out)
    assert (rows["variant"] == np.arange(3000)).all()
    for name, col in ref.items():
        np.testing.assert_array_equal(rows[name], col, err_msg=name)


def test_resume_after_a_kill_computes_only_what_is_missing(reference, tmp_path):
    _, ref = reference
    spec_file = tmp_path / "spec.toml"
    spec_file.write_text(
        "[sweep]\ntf = 3.0\ndt = 0.02\ncount = 1500\nseed = 11\nchunk = 200\n"
        "[vary]\nm3 = [35.0, 45.0]\ngamma01 = { uniform = [225.0, 375.0] }\n"
        "q10 = { normal = [0.1745, 0.05] }\nbeta23 = { lhs = [120.0, 180.0] }\n"
        "[keep]\ntrajectories = [3, 1000]\n"
    )
    out = tmp_path / "out"
    argv = [sys.executable, "-m", "rrt_pin", "sweep", str(spec_file), "--out", str(out)]
    proc = subprocess.Popen([*argv, "--workers", "1", "--no-progress"], cwd=ROOT,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and len(list(out.glob("chunks/*.parquet"))) < 3:
        time.sleep(0.01)
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = len(list(out.glob("chunks/*.parquet")))
    assert 3 <= before < 15
    # without --resume the folder is refused; a changed spec is refused
    assert main([*argv[3:], "--workers", "1", "--no-progress"]) == 2
    changed = tmp_path / "changed.toml"
    changed.write_text(spec_file.read_text().replace("seed = 11", "seed = 12"))
    assert main(["sweep", str(changed), "--out", str(out), "--resume", "--no-progress"]) == 2
    result = sweep(spec_file, out, workers=1, resume=True, progress=False)
    assert result.computed <= 15 - before + 1  # at most the chunk being written when killed
    rows = _rows(out)
    for name, col in ref.items():
        np.testing.assert_array_equal(rows[name], col, err_msg=name)


def test_diverging_variants_are_rows_not_crashes(tmp_path):
    spec = {
        "sweep": {"tf": 2.0, "dt": 0.05, "method": "rk4"},
        "vary": {"gamma23": [50.0, 1e9]},  # stiff: rk4 at 50 ms blows up
    }
    result = sweep(spec, tmp_path / "d", workers=1, progress=False)
    rows = _rows(tmp_path / "d")
    assert list(rows["diverged"]) == [False, True] and result.diverged == 1
    assert rows["diverged_time"][1] > 0 and rows["diverged_coordinate"][1].startswith(("q", "qd"))
    assert np.isnan(rows["final_error_q1"][1]) and np.isfinite(rows["final_error_q1"][0])


def test_a_urdf_sweep_gives_the_same_bits_in_any_chunks_and_workers(tmp_path):
    """A URDF's variants run side by side in the compiled lanes: no chunk changes a bit."""
    from tests.support import robot_urdf

    spec = {
        "sweep": {"urdf": str(robot_urdf("ur5")), "tf": 1.0, "dt": 0.05, "chunk": 10},
        "base": {"q0": 0.0, "qf": [0.3, -0.4, 0.5, 0.0, 0.2, 0.1], "kp": 100.0, "kd": 20.0},
        "vary": {"kp_1": {"linspace": [50.0, 150.0, 70]}},
        "keep": {"metrics": ["final_error", "evaluations"]},
    }
    a = sweep(spec, tmp_path / "a", workers=1, progress=False)
    assert a.chunks == 7  # as asked: the compiled backend's variants are independent
    b_spec = {**spec, "sweep": {**spec["sweep"], "chunk": 200}}
    sweep(b_spec, tmp_path / "b", workers=2, progress=False)
    ra, rb = _rows(tmp_path / "a"), _rows(tmp_path / "b")
    for name in ra:
        np.testing.assert_array_equal(ra[name], rb[name], err_msg=name)
    # a variant against a single run of its own parameters
    from rrt_pin.core.grid import time_grid
    from rrt_pin.simulate import simulate
    from rrt_pin.simulate.control import pd_gravity_controller

    robot = Robot.from_urdf(robot_urdf("ur5"))
    qf = np.array(spec["base"]["qf"])
    kp = np.full(6, 100.0)
    kp[0] = ra["kp_1"][35]
    run = simulate(robot, pd_gravity_controller(robot, kp, 20.0, qf), np.zeros(6), None,
                   time_grid(1.0, 0.05))  # fmt: skip
    errors = np.abs(run.q[-1] - qf)
    assert abs(ra["final_error_q_shoulder_pan_joint"][35] - errors[0]) <= 1e-8
    assert abs(ra["final_error_q_wrist_3_joint"][35] - errors[5]) <= 1e-8


def test_a_urdf_sweeps_diverging_variant_is_a_row(tmp_path):
    """A variant that fails is recorded (time, coordinate, reason); the others are kept.

    Variant 1 starts at 1e200 rad/s (its Coriolis efforts overflow at once); the effort
    limits would keep any gain finite.
    """
    spec = {
        "sweep": {"robot": "ur5", "tf": 0.5, "dt": 0.05},
        "base": {"q0": 0.0, "qf": [0.3, -0.4, 0.5, 0.0, 0.2, 0.1], "kp": 100.0, "kd": 20.0},
        "vary": {"qd0_1": [0.0, 1e200, 0.1]},
        "keep": {"metrics": ["final_error", "diverged", "evaluations"]},
    }
    sweep(spec, tmp_path / "out", workers=1, progress=False)
    rows = _rows(tmp_path / "out")
    assert list(rows["diverged"]) == [False, True, False]
    assert np.isnan(rows["final_error_q_shoulder_pan_joint"][1])
    assert np.isfinite(rows["final_error_q_shoulder_pan_joint"][[0, 2]]).all()
    assert rows["diverged_coordinate"][1] and np.isfinite(rows["diverged_time"][1])
    assert (rows["evaluations"][[0, 2]] > 0).all()


def test_a_robot_by_name_is_its_urdf(tmp_path):
    """``robot = "ur5"`` in [sweep] runs the robot of rrt_pin.robots: the same rows as its URDF."""
    from tests.support import robot_urdf

    sweep_keys = {"tf": 0.5, "dt": 0.05, "chunk": 64}
    rest = {
        "base": {"q0": 0.0, "qf": [0.3, -0.4, 0.5, 0.0, 0.2, 0.1], "kp": 100.0, "kd": 20.0},
        "vary": {"kd_2": [10.0, 30.0]},
        "keep": {"metrics": ["final_error", "peak_effort"]},
    }
    named = {"sweep": {"robot": "ur5", **sweep_keys}, **rest}
    by_file = {"sweep": {"urdf": str(robot_urdf("ur5")), **sweep_keys}, **rest}
    sweep(named, tmp_path / "named", workers=1, progress=False)
    sweep(by_file, tmp_path / "file", workers=1, progress=False)
    a, b = _rows(tmp_path / "named"), _rows(tmp_path / "file")
    assert "peak_effort_tau_wrist_3_joint" in a and len(a["kd_2"]) == 2
    for name in a:
        np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_an_inverse_sweep(tmp_path):
    spec = {
        "sweep": {"task": "inverse", "tf": 15.0, "dt": 0.01},
        "vary": {"m3": {"linspace": [30.0, 50.0, 3]}},
    }
    sweep(spec, tmp_path / "inv", workers=1, progress=False)
    rows = _rows(tmp_path / "inv")
    peaks = rows["peak_effort_F23z"]
    assert peaks[0] < peaks[1] < peaks[2]  # a heavier slider needs more force
    assert abs(peaks[1] - 339.828) < 0.01  # the chapter's arm (m3 = 40 kg)


def test_cli_summary_and_plot(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(
        "[sweep]\ntf = 2.0\ndt = 0.05\n[vary]\ngamma01 = { linspace = [200, 400, 5] }\n"
        "m3 = [30, 40]\n"
    )
    out = tmp_path / "out"
    code = main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--plot",
                 "settling_time_q1", "--no-progress"])  # fmt: skip
    captured = capsys.readouterr()
    assert code == 0 and "sweep of 10 variants" in captured.out
    assert "worst max final_error" in captured.out
    assert (out / "settling_time_q1.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    "change, words",
    [
        ({"vary": {"mass": [1.0]}}, "[vary] mass: unknown name"),
        ({"vary": {"m3": []}}, "[vary] m3 is an empty list"),
        ({"vary": {"m3": {"uniform": [5.0, 5.0]}}}, "uniform needs low < high"),
        ({"sweep": {"count": -3}, "vary": {"m3": {"uniform": [1.0, 2.0]}}}, "count=-3"),
        ({"vary": {"m1": {"linspace": [-10.0, 10.0, 3]}}}, "[vary] m1 reaches -10: parameter m1"),
        ({"keep": {"metrics": ["joy"]}}, "metric 'joy' is not one of"),
        ({"vary": {"m3": {"uniform": [1.0, 2.0]}}}, "random axes need count"),
    ],
)
def test_bad_specs_are_one_line(tmp_path, change, words):
    spec = {**{"sweep": {"tf": 1.0, "dt": 0.1}}, **change}
    with pytest.raises(SpecError) as info:
        sweep(spec, tmp_path / "out", workers=1, progress=False)
    assert words in str(info.value) and "\n" not in str(info.value)
    assert not (tmp_path / "out").exists()


def _on_backend(monkeypatch, name: str) -> list:
    """Make ``backends.choose`` pick ``name`` for sweeps; the calls it got."""
    from rrt_pin.core import backends
    from rrt_pin.sweeps import compute

    calls: list = []

    def fake(robot, task, method=None, work=0.0, **job):  # noqa: ANN001, ANN202
        calls.append((robot.name, task, job.get("build"), job.get("batch")))
        return backends.Choice(name, "a test's choice")

    monkeypatch.setattr(backends, "choose", fake)
    compute._plan.cache_clear()
    return calls


def test_a_sweep_runs_where_backends_choose_says(tmp_path, monkeypatch):
    """``backends.choose`` (the one ``auto`` policy) decides, told the job may build its code.

    On Pinocchio (whose batch holds its variants to one error test) a URDF sweep's chunks
    are rounded to blocks of 64 so that no variant depends on its chunk; the metrics still
    agree with the compiled backend's to the accuracy asked.
    """
    from rrt_pin.sweeps import compute
    from tests.support import robot_urdf

    spec = {
        "sweep": {"urdf": str(robot_urdf("ur5")), "tf": 0.5, "dt": 0.05, "chunk": 10},
        "base": {"q0": 0.0, "qf": [0.3, -0.4, 0.5, 0.0, 0.2, 0.1], "kp": 100.0, "kd": 20.0},
        "vary": {"kp_1": {"linspace": [50.0, 150.0, 70]}},
        "keep": {"metrics": ["final_error", "evaluations"]},
    }
    try:
        calls = _on_backend(monkeypatch, "pinocchio")
        slow = sweep(spec, tmp_path / "p", workers=1, progress=False)
        assert calls and all(c[1:] == ("simulate", True, True) for c in calls), calls
        assert slow.chunks == 2  # 64-variant blocks
        manifest = (tmp_path / "p" / "manifest.json").read_text()
        assert '"backend": "pinocchio"' in manifest and "a test's choice" in manifest
        _on_backend(monkeypatch, "compiled")
        fast = sweep(spec, tmp_path / "c", workers=1, progress=False)
        assert fast.chunks == 7
    finally:
        compute._plan.cache_clear()
    p, c = _rows(tmp_path / "p"), _rows(tmp_path / "c")
    for name in p:
        if name.startswith("final_error"):
            np.testing.assert_allclose(p[name], c[name], rtol=0, atol=1e-8, err_msg=name)
    assert not np.array_equal(p["evaluations"], c["evaluations"])  # two engines, truly


def test_a_sweep_resumes_only_on_its_own_backend(tmp_path, monkeypatch):
    from rrt_pin.core.errors import InputError
    from rrt_pin.sweeps import compute

    spec = {"sweep": {"tf": 0.2, "dt": 0.05}, "vary": {"m3": [40.0, 45.0]}}
    try:
        _on_backend(monkeypatch, "pinocchio")
        sweep(spec, tmp_path / "s", workers=1, progress=False)
        before = sorted(p.name for p in (tmp_path / "s").rglob("*"))
        _on_backend(monkeypatch, "compiled")
        with pytest.raises(InputError, match="ran on backend 'pinocchio'"):
            sweep(spec, tmp_path / "s", workers=1, progress=False, resume=True)
        assert sorted(p.name for p in (tmp_path / "s").rglob("*")) == before
    finally:
        compute._plan.cache_clear()
