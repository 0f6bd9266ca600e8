"""The benchmark's building blocks, and one quick end-to-end run."""

from __future__ import annotations

import io
import math

import numpy as np
import pytest

from rrt_pin.cli.bench_measure import BenchRow, Progress, median_time, pareto_front, write_rows
from rrt_pin.cli.bench_report import _on_front


def test_pareto_front_by_brute_force(rng):
    times = rng.random(200)
    errors = rng.random(200)
    mask = pareto_front(times, errors)
    for i in range(200):
        dominated = any(
            times[j] <= times[i]
            and errors[j] <= errors[i]
            and (times[j] < times[i] or errors[j] < errors[i])
            for j in range(200)
        )
        assert mask[i] == (not dominated)
    assert 1 <= mask.sum() < 200


def test_pareto_front_small_cases():
    assert pareto_front([1, 2, 3], [3, 2, 1]).tolist() == [True, True, True]
    assert pareto_front([1, 2, 3], [1, 2, 3]).tolist() == [True, False, False]
    assert pareto_front([1, 1], [2, 2]).tolist() == [True, True]  # ties dominate neither


def test_default_is_not_pushed_off_the_front_by_its_own_twin():
    twin = BenchRow("p", "m", "rtol=1e-09", 0.0010, 500, 1e-10)
    default = BenchRow("p", "m", "default", 0.0011, 500, 1e-10)
    slower = BenchRow("p", "x", "rtol=1e-09", 0.0009, 700, 1e-11)
    assert _on_front(default, [twin, default])
    assert not _on_front(default, [twin, default, slower])


def test_median_time_repeats_until_min_total():
    calls = []
    t, result = median_time(lambda: calls.append(1) or len(calls), repeats=3, min_total=0.0)
    assert len(calls) == 3 and result == 3 and t >= 0.0
    calls.clear()
    median_time(lambda: calls.append(1), repeats=1, min_total=1e9, max_repeats=17)
    assert len(calls) == 17


def test_progress_counts_on_a_pipe():
    out = io.StringIO()
    p = Progress(2, stream=out)
    p.step("a")
    p.step("b")
    assert out.getvalue() == "[1/2] a\n[2/2] b\n"


def test_rows_csv(tmp_path):
    path = write_rows(
        tmp_path / "r.csv", [BenchRow("compiled", "DOP853", "rtol=1e-09", 2.5e-4, 740, 8e-10)]
    )
    assert path.read_text() == (
        "backend,method,setting,time_s,n_evals,max_error\ncompiled,DOP853,rtol=1e-09,0.00025,740,8e-10\n"
    )


def test_mpmath_reference_agrees_with_pinocchio(seed_model, seed_params, rng):
    pytest.importorskip("mpmath")
    import pinocchio as pin

    from rrt_pin.cli.bench_measure import mpmath_inverse_reference
    from tests.support import random_states

    q, qd, qdd = random_states(rng, 20)
    ref = mpmath_inverse_reference(q, qd, qdd, seed_params)
    data = seed_model.createData()
    tau = np.array(
        [pin.rnea(seed_model, data, a, b, c) for a, b, c in zip(q, qd, qdd, strict=True)]
    )
    np.testing.assert_allclose(tau, ref, rtol=1e-11, atol=1e-9)


@pytest.mark.slow
def test_bench_quick_end_to_end(tmp_path, capsys):
    from rrt_pin.cli.app import main

    assert main(["bench", "--quick", "--out", str(tmp_path)]) == 0
    out, err = capsys.readouterr()
    assert "Pareto front" in out and "[" in err
    header = (tmp_path / "work_precision.csv").read_text().splitlines()[0]
    assert header == "backend,method,setting,time_s,n_evals,max_error"
    rows = (tmp_path / "work_precision.csv").read_text().splitlines()[1:]
    assert len(rows) >= 5 * 2
    # every configuration planned runs (the arm's compiled kernel gets only its own methods)
    assert all(math.isfinite(float(r.split(",")[-1])) for r in rows), rows
    assert not {r.split(",")[1] for r in rows if r.startswith("compiled,")} & {"adams", "BDF"}
    for name in ("work_precision.png", "inverse.csv", "energy_drift.csv"):
        assert (tmp_path / name).stat().st_size > 0
    kernels = (tmp_path / "kernels.csv").read_text().splitlines()
    assert kernels[0] == "kernel,ns_per_sample,flops,gflops,fma_gflops,fraction"
    by_name = {line.split(",")[0]: line.split(",") for line in kernels[1:]}
    compiled = by_name["compiled inverse"]
    assert 0 < float(compiled[5]) <= 1  # a fraction of the machine's limit
    # the RNEA generated for another robot (UR5 in --quick), its flops counted in its source
    from rrt_pin.compiled.rnea import kernel_for
    from rrt_pin.robot.robots import get

    generated = by_name["compiled inverse generated for ur5"]
    assert int(generated[2]) == kernel_for(get("ur5").model).all_flops > 0
    assert float(generated[3]) == pytest.approx(int(generated[2]) / float(generated[1]), rel=1e-4)
    assert 0 < float(generated[5]) <= 1
    assert "of the FMA limit" in out


def _fake_measurements(monkeypatch):
    """run_bench with its measurements replaced by three rows (the outputs are what is tested)."""
    from rrt_pin.cli import bench_report as bench

    row = BenchRow("pinocchio", "odepack", "rtol=1e-09", 0.002, 500, 6e-11)
    monkeypatch.setattr(bench, "direct_work_precision", lambda **k: ([row], [row], 0.0))
    monkeypatch.setattr(bench, "inverse_backends", lambda **k: [row])
    monkeypatch.setattr(bench, "energy_drift", lambda **k: [row])
    monkeypatch.setattr(bench, "kernel_table", lambda *a, **k: [])


def test_bench_out_on_a_read_only_disk_is_refused_before_any_work(tiny_fs, monkeypatch, capsys):
    import subprocess

    from rrt_pin.cli import bench_report as bench
    from rrt_pin.cli.app import main

    if subprocess.run(["mount", "-o", "remount,ro", str(tiny_fs)], capture_output=True).returncode:
        pytest.skip("cannot remount read-only")
    ran = []
    monkeypatch.setattr(bench, "direct_work_precision", lambda **k: ran.append(1))
    for out in (tiny_fs / "b", tiny_fs):
        assert main(["bench", "--quick", "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert err.count("\n") == 1 and "read-only file system" in err.lower(), err
    assert ran == [] and list(tiny_fs.iterdir()) == []


def test_bench_out_on_a_full_disk_leaves_nothing(tiny_fs, monkeypatch, capsys):
    from rrt_pin.cli import bench_report as bench
    from rrt_pin.cli.app import main

    _fake_measurements(monkeypatch)
    (tiny_fs / "filler").write_bytes(b"x" * (64 * 1024 - 8192))  # leave too little for a PNG
    assert main(["bench", "--quick", "--out", str(tiny_fs / "b")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no space left" in err.lower(), err
    assert sorted(p.name for p in tiny_fs.iterdir()) == ["filler"]  # no folder, no partial file
    # With room, all five files are written together.
    (tiny_fs / "filler").unlink()
    report = bench.run_bench(tiny_fs / "b", quick=True)
    assert sorted(p.name for p in (tiny_fs / "b").iterdir()) == sorted(
        ["work_precision.csv", "work_precision.png", "inverse.csv", "energy_drift.csv",
         "kernels.csv"]
    )  # fmt: skip
    assert len(report.files) == 5


def test_kernel_rows_put_each_kernel_against_the_fma_limit():
    from rrt_pin.cli import flops
    from rrt_pin.dynamics import kernel

    counts = flops.kernel_flops()
    rows = flops.kernel_rows({"symbolic inverse": 50.0, "pinocchio rnea loop": 1000.0}, 2.5e9)
    sym, loop = rows
    assert sym.flops == counts["symbolic inverse"] == kernel.INVERSE_FLOPS
    assert sym.gflops == pytest.approx(kernel.INVERSE_FLOPS / 50.0)
    assert sym.fma_gflops == pytest.approx(5.0) and sym.fraction == pytest.approx(sym.gflops / 5)
    assert loop.flops == 0 and np.isnan(loop.gflops) and np.isnan(loop.fraction)


def test_flop_counts_are_those_of_the_generated_source():
    pytest.importorskip("numba")
    from rrt_pin.cli import flops
    from rrt_pin.dynamics.symbolic import codegen

    shared = sum(codegen.flop_count(src) for _, src in codegen.SHARED_LINES)
    inverse = sum(codegen.flop_count(src) for _, src in codegen.INVERSE_LINES)
    counts = flops.kernel_flops()
    from rrt_pin.compiled import _jit_dynamics as jd

    assert counts["compiled inverse"] == shared + inverse + jd.SINCOS_FLOPS


def test_the_fma_rate_is_a_plausible_core_rate():
    pytest.importorskip("numba")
    from rrt_pin.cli.flops import fma_rate

    rate = fma_rate(0.05)
    assert 1e8 < rate < 2e11  # between a slow core and 4x today's widest vector unit


def test_rows_csv_quotes_a_name_with_a_comma():
    """A kernel or setting named with a comma stays one column (read back by the csv module)."""
    import csv

    from rrt_pin.cli.bench_measure import rows_csv
    from rrt_pin.cli.flops import KernelRow

    text = rows_csv([KernelRow("a, b", 1.5, 3, 2.0, 50.0, 0.04)], KernelRow)
    header, row = list(csv.reader(text.splitlines()))
    assert header == KernelRow.header() and row == ["a, b", "1.5", "3", "2", "50", "0.04"]
