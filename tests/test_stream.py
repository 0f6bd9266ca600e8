"""Outputs written in blocks: same numbers as the whole-array computation, flat memory,
Parquet with units and metadata, ``--json``, the summary always, refusals up front."""

from __future__ import annotations

import json
import sys
import tracemalloc

import numpy as np
import pytest

import rrt_pin
import rrt_pin.io.csvio
import rrt_pin.io.tables
from rrt_pin.cli.app import main
from rrt_pin.cli.commands import inverse as inverse_cmd
from rrt_pin.cli.commands import simulate as simulate_cmd
from rrt_pin.cli.commands._progress import Progress
from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import MAX_SAMPLES, grid_size, grid_slice, time_grid
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.dynamics.wrenches import joint_wrenches, wrench_table
from rrt_pin.io.csvio import read_csv
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate.control import chapter_controller

pa = pytest.importorskip("pyarrow")
pq = pytest.importorskip("pyarrow.parquet")


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def bits(a):
    return np.ascontiguousarray(a, dtype=float).view(np.int64)


@pytest.mark.parametrize(
    "tf, dt, t0", [(15.0, 0.001, 0.0), (3.3, 0.7, 0.0), (1.0, 0.1, 0.2), (7.77, 1e-4, -1.3)]
)
@pytest.mark.parametrize("block", [1, 7, 4096])
def test_grid_slices_are_the_grid_bit_for_bit(tf, dt, t0, block):
    whole = time_grid(tf, dt, t0)
    g = grid_size(tf, dt, t0)
    assert g.size == whole.size
    pieces = np.concatenate([grid_slice(g, i, i + block) for i in range(0, g.size, block)])
    np.testing.assert_array_equal(bits(pieces), bits(whole))


@pytest.mark.parametrize("tf, dt", [(1e6, 1e-6), (1e300, 1e-3), (1.0, 5e-324)])
def test_absurd_grids_are_refused_without_building_them(tf, dt):
    with pytest.raises(InputError, match=f"over the {MAX_SAMPLES:,} allowed"):
        grid_size(tf, dt)
    with pytest.raises(InputError, match="allowed"):
        time_grid(tf, dt)


def whole_inverse(p, dt, tf=None, wrenches=False):
    """The table as the pre-streaming code computed it: every sample at once."""
    arm = chapter_arm(p)
    t = time_grid(tf or p.Tp, dt)
    traj = rest_to_rest(p.q0, p.qf, p.Tp, t)
    tau = inverse_dynamics(arm, traj.q, traj.qd, traj.qdd)
    cols = [t[:, None], traj.q, traj.qd, traj.qdd, tau]
    if wrenches:
        cols.append(wrench_table(joint_wrenches(arm, traj.q, traj.qd, traj.qdd), True)[1])
    return np.hstack(cols)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_blocks_give_the_whole_computation_bit_for_bit(tmp_path, capsys, monkeypatch, suffix):
    monkeypatch.setattr(rrt_pin.io.tables, "BLOCK_ROWS", 333)  # many blocks, a short last one
    path = tmp_path / f"w{suffix}"
    argv = ["inverse", "--wrenches", "--dt", "0.01", "--csv", str(path)]
    code, out, err = run(argv, capsys)
    assert code == 0, err
    expected = whole_inverse(Params(), 0.01, wrenches=True)
    if suffix == ".csv":
        header, data = read_csv(path)
    else:
        table = pq.read_table(path)
        header, data = table.column_names, np.column_stack([c.to_numpy() for c in table.columns])
    assert len(header) == expected.shape[1] == 28
    np.testing.assert_array_equal(bits(data), bits(expected))
    # The summary's peaks are those of the whole arrays.
    for k, name in enumerate(("T01x", "T12y", "F23z")):
        line = next(x for x in out.splitlines() if x.startswith(name))
        i = int(np.argmax(np.abs(expected[:, 10 + k])))
        assert float(line.split()[1]) == pytest.approx(abs(expected[i, 10 + k]), rel=1e-5)
        assert float(line.split()[3]) == pytest.approx(expected[i, 0], abs=1e-9)


def traced_peak(argv):
    tracemalloc.start()
    try:
        code = main(argv)
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert code == 0
    return peak


def test_memory_stays_flat_while_writing(tmp_path, capsys, monkeypatch):
    """Four times the rows, about the same peak of the Python heap (blocks of 5,000 rows)."""
    monkeypatch.setattr(rrt_pin.io.tables, "BLOCK_ROWS", 5_000)
    main(["inverse", "--tf", "1", "--dt", "0.5"])  # imports and builds the model first
    peaks, sizes = [], []
    for tf in ("20", "80"):  # 20,001 and 80,001 rows
        path = tmp_path / f"{tf}.csv"
        peaks.append(traced_peak(["inverse", "--tf", tf, "--dt", "0.001", "--csv", str(path)]))
        sizes.append(path.stat().st_size)
    capsys.readouterr()
    assert sizes[1] > 2.5 * sizes[0] and sizes[1] > 10e6
    assert peaks[1] < 1.3 * peaks[0], peaks
    assert peaks[1] < sizes[1] / 2, (peaks, sizes)  # the text is never held whole
    _, data = read_csv(tmp_path / "80.csv")
    assert data.shape == (80_001, 13) and data[-1, 0] == 80.0


def test_csv_to_stdout_puts_the_summary_on_stderr(capsys):
    code, out, err = run(["inverse", "--dt", "0.5", "--csv", "-"], capsys)
    assert code == 0
    lines = out.splitlines()
    assert lines[0].startswith("t,q1,q2,q3") and len(lines) == 32
    assert "inverse dynamics of the RRT arm" in err and "T12y" in err
    assert "peak" not in out


def test_the_summary_is_printed_with_a_csv_and_matches_json(tmp_path, capsys):
    csv, js = tmp_path / "s.csv", tmp_path / "s.json"
    code, out, err = run(["simulate", "--tf", "3", "--csv", str(csv), "--json", str(js)], capsys)
    assert code == 0
    doc = json.loads(js.read_text())
    facts = doc["summary"]
    assert out == simulate_cmd.summary_text(facts)  # one dict, two renderings
    _, data = read_csv(csv)
    assert facts["samples"] == data.shape[0] == 301
    for k, j in enumerate(facts["joints"]):
        assert j["q_tf"] == data[-1, 1 + k]  # bit for bit: both come from the result
    for k, p in enumerate(facts["peaks"]):
        i = int(np.argmax(np.abs(data[:, 7 + k])))
        assert p["peak"] == abs(data[i, 7 + k]) and p["t"] == data[i, 0]
    meta = doc["metadata"]
    assert meta["rrt_pin_version"] == rrt_pin.__version__
    assert meta["command_line"][:2] == ["rrt-pin", "simulate"] and str(js) in meta["command_line"]
    from rrt_pin.simulate import methods

    assert meta["method"] == "odepack" and meta["backend"] == "pinocchio"
    assert meta["rtol"] == methods.get("odepack").rtol  # the registry's default, recorded
    assert meta["parameters"]["m3"] == Params().m3 and meta["units"]["F23z"] == "N"
    # The error estimate: in the summary, the JSON and the metadata, the same numbers.
    est = facts["error_estimate"]
    assert meta["error_estimate"] == est and 0 < est["max"] < 1e-8
    assert [e["name"] for e in est["per_coordinate"]] == ["q1", "q2", "q3"]
    assert est["max"] == max(e["value"] for e in est["per_coordinate"])
    assert f"{est['max']:.2g}" in out


def test_inverse_summary_dict_is_pure_and_complete(tmp_path, capsys):
    js = tmp_path / "i.json"
    code, out, _ = run(["inverse", "--dt", "0.01", "--wrenches", "--json", str(js)], capsys)
    facts = json.loads(js.read_text())["summary"]
    assert code == 0 and out == inverse_cmd.summary_text(facts)
    assert [p["kind"] for p in facts["peaks"]] == ["effort"] * 3 + ["load"] * 6
    expected = whole_inverse(Params(), 0.01)
    assert facts["peaks"][1]["peak"] == np.abs(expected[:, 11]).max()


def test_parquet_carries_units_and_the_runs_metadata(tmp_path, capsys):
    path = tmp_path / "run.pq"
    code, out, err = run(["simulate", "--tf", "2", "--set", "m3=35", "--csv", str(path)], capsys)
    assert code == 0 and out.startswith("simulated the RRT arm")
    table = pq.read_table(path)
    units = {f.name: f.metadata[b"unit"].decode() for f in table.schema}
    assert units == {
        "t": "s", "q1": "rad", "q2": "rad", "q3": "m", "qd1": "rad/s", "qd2": "rad/s",
        "qd3": "m/s", "T01x": "N·m", "T12y": "N·m", "F23z": "N",
    }  # fmt: skip
    meta = json.loads(table.schema.metadata[b"rrt_pin.run"])
    assert meta["parameters"]["m3"] == 35.0 and meta["method"] == "odepack"
    assert meta["robot"] == "RRT arm" and meta["command"] == "simulate"
    assert json.loads(table.schema.metadata[b"rrt_pin.units"]) == units
    p = Params(m3=35.0)
    arm = chapter_arm(p)
    expected = rrt_pin.simulate(arm, chapter_controller(p), p.q0, p.qd0, time_grid(2.0, 0.01))
    got = np.column_stack([c.to_numpy() for c in table.columns])
    np.testing.assert_array_equal(got, expected.table())


def test_parquet_without_pyarrow_is_one_line(tmp_path, capsys, monkeypatch):
    monkeypatch.setitem(sys.modules, "pyarrow", None)
    monkeypatch.setitem(sys.modules, "pyarrow.parquet", None)
    code, out, err = run(["inverse", "--csv", str(tmp_path / "x.parquet")], capsys)
    assert code == 2 and out == "" and err.count("\n") == 1
    assert "pyarrow not found (needed for --csv .parquet output)" in err and "[parquet]" in err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("name", ["x.txt", "x", "x.CSV", "x.dat"])
def test_any_other_suffix_writes_csv(tmp_path, capsys, name):
    path = tmp_path / name
    assert run(["inverse", "--dt", "0.5", "--csv", str(path)], capsys)[0] == 0
    assert path.read_text().startswith("t,q1,")


def test_output_larger_than_the_free_space_is_refused_up_front(tmp_path, capsys, monkeypatch):
    import shutil

    class Usage:
        total, used, free = 10**9, 10**9 - 10**6, 10**6

    monkeypatch.setattr(shutil, "disk_usage", lambda path: Usage)
    (tmp_path / "keep.csv").write_text("old")
    argv = ["inverse", "--tf", "100", "--csv", str(tmp_path / "keep.csv")]  # 100,001 rows
    code, out, err = run(argv, capsys)
    assert code == 2 and err.count("\n") == 1 and out == ""
    assert "no space left on device" in err and "1 MB free" in err
    assert (tmp_path / "keep.csv").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["keep.csv"]


def test_progress_only_when_asked_or_on_a_terminal(tmp_path, capsys, monkeypatch):
    import rrt_pin.cli.commands._progress as progress

    monkeypatch.setattr(progress, "DELAY", 0.0)
    path = str(tmp_path / "a.csv")
    code, _, err = run(["inverse", "--dt", "0.01", "--csv", path], capsys)
    assert code == 0 and err == f"rrt-pin: wrote {path} (backend pinocchio)\n"  # not a TTY: nothing
    code, _, err = run(["inverse", "--dt", "0.01", "--csv", path, "--progress"], capsys)
    assert code == 0 and "rrt-pin: writing" in err and "1,501 / 1,501 rows" in err


def test_progress_counts_and_ends_its_line():
    import io

    class Tty(io.StringIO):
        def isatty(self):
            return True

    stream = Tty()
    p = Progress(10, "computing", stream=stream)
    p.start -= 10.0  # as if the run had lasted 10 s
    p.update(4)
    p.update(6)
    p.close()
    text = stream.getvalue()
    assert text.startswith("\rrrt-pin: computing") and "10 / 10 rows" in text
    assert text.endswith("\n")
    quiet = io.StringIO()
    q = Progress(10, "computing", stream=quiet)
    q.start -= 10.0
    q.update(10)
    q.close()
    assert quiet.getvalue() == ""


def test_to_frame_has_the_table_and_its_units():
    pd = pytest.importorskip("pandas")
    p = Params()
    r = rrt_pin.simulate(chapter_arm(p), chapter_controller(p), p.q0, t_eval=time_grid(1.0, 0.1))
    frame = r.to_frame()
    assert isinstance(frame, pd.DataFrame) and list(frame.columns) == list(r.header)
    np.testing.assert_array_equal(frame.to_numpy(), r.table())
    assert frame.attrs["units"]["q3"] == "m" and frame.attrs["units"]["T01x"] == "N·m"
    assert frame.attrs["units"]["qd3"] == "m/s" and frame.attrs["run"]["method"] == r.method


def test_qd0_defaults_to_rest():
    p = Params()
    arm, law, t = chapter_arm(p), chapter_controller(p), time_grid(1.0, 0.1)
    rest = rrt_pin.simulate(arm, law, p.q0, np.zeros(3), t)
    default = rrt_pin.simulate(arm, law, p.q0, t_eval=t)
    np.testing.assert_array_equal(default.table(), rest.table())
    with pytest.raises(InputError, match="t_eval"):
        rrt_pin.simulate(arm, law, p.q0)


def test_public_names():
    for name in ("time_grid", "simulate", "SimulationResult", "inverse_dynamics", "rest_to_rest"):
        assert name in rrt_pin.__all__ and getattr(rrt_pin, name) is not None
    for module in ("core.grid", "io.tables", "io.csvio", "io.files", "io.targets"):
        mod = __import__(f"rrt_pin.{module}", fromlist=["__all__"])
        for name in mod.__all__:
            assert hasattr(mod, name), f"rrt_pin.{module}.{name}"


def test_plot_of_a_long_run_is_thinned_evenly_with_both_ends(monkeypatch):
    monkeypatch.setattr(inverse_cmd, "PLOT_POINTS", 100)
    monkeypatch.setattr(rrt_pin.io.tables, "BLOCK_ROWS", 64)
    p = Params()
    arm = chapter_arm(p)
    motion = inverse_cmd.RestToRestMotion(arm, grid_size(10.0, 0.01), p.Tp)
    job = inverse_cmd.InverseJob(arm, motion, wrenches=False)
    job.run(None)
    t, tau = job.plot_samples()
    whole = whole_inverse(p, 0.01, tf=10.0)
    stride = 11  # ceil(1001 / 100)
    index = np.r_[np.arange(0, 1001, stride), 1000]
    np.testing.assert_array_equal(t, whole[index, 0])
    np.testing.assert_array_equal(tau, whole[index, 10:13])


def test_parquet_metadata_carries_the_error_estimate(tmp_path, capsys):
    import pyarrow.parquet as pq

    path, js = tmp_path / "s.parquet", tmp_path / "s.json"
    assert run(["simulate", "--tf", "2", "--csv", str(path), "--json", str(js)], capsys)[0] == 0
    run_meta = json.loads(pq.read_schema(path).metadata[b"rrt_pin.run"])
    assert run_meta["error_estimate"] == json.loads(js.read_text())["summary"]["error_estimate"]
    assert run_meta["error_estimate"]["accuracy"] == 1e-8
    # Skipped: recorded as not computed, everywhere.
    code, out, _ = run(["simulate", "--tf", "2", "--no-error-estimate", "--csv", str(path)], capsys)
    assert code == 0 and "estimated global error of q(t): not computed" in out
    assert json.loads(pq.read_schema(path).metadata[b"rrt_pin.run"])["error_estimate"] is None
