#!/usr/bin/env python
"""Inverse dynamics of the chapter's run (eq. 30, 15,001 samples): speed and agreement.

Times, in ONE run, interleaved round by round and then blocked (so machine noise hits all
sides alike), the medians of --repeat runs of:

* loop         a Python loop calling ``pin.rnea`` once per sample (the baseline);
* batched      ``rrt_pin.inverse_dynamics`` (``pin.rneaInParallel``, default threads);
* batched-1t   the same on one thread;
* symbolic     the generated numpy kernel ``rrt_pin.dynamics.kernel`` (if present);
* compiled     the numba kernel ``rrt_pin.compiled`` (if available; its first,
               compiling call is reported apart).

It prints times, speed-ups against the loop and the max relative difference of
each side from the loop (per effort, relative to that effort's peak |value|),
then the whole-process time of ``rrt-pin inverse --csv`` (interpreter start
included; median of --process-runs runs).

    .venv/bin/python -m scripts.bench.inverse [--repeat 7] [--process-runs 7] [--check]

Targets: batched ≥ 5× faster than the loop, same values to 1e-12 relative;
``rrt-pin inverse --csv`` < 1 s. ``--check`` exits 1 when one is missed.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pinocchio as pin

from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.inverse import default_num_threads, inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.model import rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from scripts.bench.compiled import inverse_verdict

TARGET_SPEEDUP = 5.0
TARGET_AGREEMENT = 1e-12
TARGET_PROCESS_S = 1.0


def rnea_loop(model: pin.Model, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """The baseline: one ``pin.rnea`` call per sample from Python."""
    data = model.createData()
    out = np.empty((q.shape[0], model.nv))
    for i in range(q.shape[0]):
        out[i] = pin.rnea(model, data, q[i], qd[i], qdd[i])
    return out


def rel_diff(a: np.ndarray, ref: np.ndarray) -> float:
    """max over efforts of max|a − ref| / max|ref|."""
    return float((np.abs(a - ref).max(axis=0) / np.abs(ref).max(axis=0)).max())


def sides(params: Params, model: pin.Model, traj) -> dict[str, Callable[[], np.ndarray]]:
    q, qd, qdd = traj.q, traj.qd, traj.qdd
    arm = chapter_arm(params)
    arm.model  # noqa: B018  (its Pinocchio model built before any timing)
    out: dict[str, Callable[[], np.ndarray]] = {
        "loop": lambda: rnea_loop(model, q, qd, qdd),
        f"batched ({default_num_threads()}t)": lambda: inverse_dynamics(arm, q, qd, qdd),
        "batched-1t": lambda: inverse_dynamics(arm, q, qd, qdd, num_threads=1),
    }
    try:
        import rrt_pin.dynamics.kernel  # noqa: F401

        out["symbolic"] = lambda: inverse_dynamics(arm, q, qd, qdd, backend="symbolic")
    except ImportError as e:
        print(f"symbolic kernel: not present ({e})")
    try:
        from rrt_pin import compiled

        if not getattr(compiled, "available", lambda: True)() or not hasattr(
            compiled, "inverse_dynamics"
        ):
            raise ImportError("rrt_pin.compiled.inverse_dynamics unavailable")
        start = time.perf_counter()
        inverse_dynamics(arm, q, qd, qdd, backend="compiled")
        print(
            f"compiled kernel: first call (JIT compile or cache load) {time.perf_counter() - start:.3f} s"
        )
        out["compiled"] = lambda: inverse_dynamics(arm, q, qd, qdd, backend="compiled")
    except ImportError as e:
        print(f"compiled kernel: not available ({e})")
    return out


# --- compiled backend: its targets ---------------------------------------------------------
# (section owned by the compiled backend; the verdict is defined in scripts/bench/compiled.py)
def compiled_targets(medians: dict[str, float], results: dict[str, np.ndarray]) -> dict[str, bool]:
    """The compiled side's targets: <= 1 ms, >= 50x the loop, same values to 1e-12."""
    if "compiled" not in medians:
        return {}

    return inverse_verdict(medians, results)


# --- end of the compiled backend's section -------------------------------------------------


def time_sides(
    funcs: dict[str, Callable[[], np.ndarray]], repeat: int, interleaved: bool = True
) -> tuple[dict[str, float], dict[str, np.ndarray]]:
    """Median time of each side [s] and its last result.

    Interleaved: round by round, each side once per round (machine drift hits all
    sides alike, but each call starts with caches the previous side filled).
    Blocked: each side's runs back to back after one warm-up call (warm caches,
    as ``timeit`` measures).
    """
    times: dict[str, list[float]] = {k: [] for k in funcs}
    results: dict[str, np.ndarray] = {}
    if interleaved:
        for _ in range(repeat):
            for name, f in funcs.items():
                start = time.perf_counter()
                results[name] = f()
                times[name].append(time.perf_counter() - start)
    else:
        for name, f in funcs.items():
            f()
            for _ in range(repeat):
                start = time.perf_counter()
                results[name] = f()
                times[name].append(time.perf_counter() - start)
    return {k: statistics.median(v) for k, v in times.items()}, results


def process_time(runs: int) -> tuple[float, list[float]]:
    cmd = [sys.executable, "-m", "rrt_pin", "inverse", "--csv"]
    times = []
    with tempfile.TemporaryDirectory() as tmp:
        out = str(Path(tmp) / "out.csv")
        for _ in range(runs):
            start = time.perf_counter()
            subprocess.run([*cmd, out], check=True, capture_output=True)
            times.append(time.perf_counter() - start)
        rows = Path(out).read_text().count("\n") - 1
    if rows != 15001:
        raise SystemExit(f"rrt-pin inverse --csv wrote {rows} rows, not 15001")
    return statistics.median(times), times


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="timed runs per side (median)")
    ap.add_argument("--process-runs", type=int, default=7, help="whole-process runs (median)")
    ap.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    args = ap.parse_args()

    params = Params()
    model = rrt_model(params)
    traj = rest_to_rest(params.q0, params.qf, params.Tp, time_grid(params.Tp, 0.001))
    print(
        f"chapter's run: {len(traj)} samples; pinocchio {pin.__version__}; numpy {np.__version__}; "
        f"{default_num_threads()} CPUs available"
    )
    funcs = sides(params, model, traj)
    protocols = {}
    for interleaved in (True, False):
        medians, results = time_sides(funcs, args.repeat, interleaved)
        protocols["interleaved" if interleaved else "blocked"] = (medians, results)
        base = medians["loop"]
        ref = results["loop"]
        how = "interleaved round by round" if interleaved else "blocked, each side warm"
        print(f"\nmedian of {args.repeat} runs, {how}")
        print(f"{'side':<16} {'time [ms]':>10} {'speed-up':>9} {'max rel diff':>13}")
        for name, t in medians.items():
            print(
                f"{name:<16} {1e3 * t:>10.2f} {base / t:>8.1f}x "
                f"{rel_diff(results[name], ref):>13.2e}"
            )

    proc, runs = process_time(args.process_runs)
    print(
        f"\nrrt-pin inverse --csv (whole process): median {proc:.3f} s of {len(runs)} runs "
        f"(min {min(runs):.3f}, max {max(runs):.3f})"
    )

    ok: dict[str, bool] = {}
    for protocol, (medians, results) in protocols.items():
        base, ref = medians["loop"], results["loop"]
        batched = next(k for k in medians if k.startswith("batched ("))
        speedup = base / medians[batched]
        agreement = rel_diff(results[batched], ref)
        ok[f"batched ≥ {TARGET_SPEEDUP:g}x the loop ({protocol}, {speedup:.1f}x)"] = (
            speedup >= TARGET_SPEEDUP
        )
        ok[f"batched agrees to {TARGET_AGREEMENT:g} ({protocol})"] = agreement <= TARGET_AGREEMENT
        for label, good in compiled_targets(medians, results).items():
            ok[f"{label} ({protocol})"] = good
    ok[f"whole process < {TARGET_PROCESS_S:g} s"] = proc < TARGET_PROCESS_S
    print()
    for label, good in ok.items():
        print(f"target {label}: {'met' if good else 'MISSED'}")
    return 1 if args.check and not all(ok.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
