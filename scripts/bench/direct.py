#!/usr/bin/env python
"""Direct dynamics of the chapter's run: speed and accuracy against the plain baseline.

Baseline: ``scipy.integrate.solve_ivp(method="DOP853", rtol=1e-10, atol=1e-12)``
on a Python right-hand side calling ``pin.aba`` with eq. (31)'s efforts.
Accuracy: max |q error| over 0..15 s at the 1,501-point grid against the
reference of ``rrt_pin.simulate.reference.chapter_reference()`` (DOP853 and Radau at rtol
1e-13; their difference is printed).

Part 1 times single runs (medians of --repeat runs, both sides in this run);
part 2 times a batch of --batch chapter variants (other gains and initial states)
against the baseline run once per variant (estimated from --baseline-runs runs);
the target row returns states only, like the baseline; a second row adds the
applied efforts at every sample.

Rows are plain (label, callable) pairs: to add a backend, append rows in
``compiled_rows`` / ``compiled_batch_rows`` below.

    .venv/bin/python -m scripts.bench.direct [--all] [--repeat 7] [--batch 1000]
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp

from rrt_pin.dynamics.inverse import default_num_threads
from rrt_pin.robot.model import rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import simulate, simulate_batch
from rrt_pin.simulate.control import ChapterController, chapter_controller
from rrt_pin.simulate.methods import METHODS
from rrt_pin.simulate.reference import chapter_reference, reference_run
from scripts.bench.compiled import batch_rows, direct_rows

TARGET_ERROR = 1e-8  # max |q error| the defaults must reach [rad, m]
TARGET_SPEEDUP = 3.0  # single run, against the baseline
TARGET_BATCH_SPEEDUP = 20.0  # batch throughput, against the baseline run per variant


@dataclass
class Row:
    """One way of computing the chapter's run: ``run()`` returns (q at the grid, evaluations)."""

    label: str
    run: Callable[[], tuple[np.ndarray, int]]


def baseline(model: pin.Model, controller, q0, qd0, t: np.ndarray) -> tuple[np.ndarray, int]:
    """The plain baseline: solve_ivp DOP853 at rtol 1e-10, atol 1e-12, rhs calling pin.aba."""
    data = model.createData()

    def rhs(_t, y):
        q, v = y[:3], y[3:]
        return np.concatenate((v, pin.aba(model, data, q, v, controller(q, v))))

    sol = solve_ivp(
        rhs,
        (t[0], t[-1]),
        np.concatenate((q0, qd0)),
        method="DOP853",
        t_eval=t,
        rtol=1e-10,
        atol=1e-12,
    )
    return sol.y[:3].T, sol.nfev


def single_rows(model, controller, p: Params, t: np.ndarray, all_methods: bool) -> list[Row]:
    """The baseline, rrt_pin's defaults and (with --all) every method at its defaults."""
    arm = chapter_arm(p)  # built once: the runs time simulate, not the Robot's construction
    arm.model  # noqa: B018  (its Pinocchio model built before any timing)
    rows = [
        Row("baseline solve_ivp DOP853 1e-10", lambda: baseline(model, controller, p.q0, p.qd0, t)),
        Row("rrt_pin simulate() defaults", lambda: _sim(arm, controller, p, t)),
    ]
    if all_methods:
        for method in METHODS[1:]:
            rows.append(
                Row(f"  simulate {method}", lambda m=method: _sim(arm, controller, p, t, m))
            )
        for method in ("Radau", "BDF"):
            rows.append(
                Row(
                    f"  simulate {method} finite-diff jac",
                    lambda m=method: _sim(arm, controller, p, t, m, "finite-difference"),
                )
            )
    return rows


def _sim(arm, controller, p, t, method=None, jacobian="analytic"):
    kwargs = {"method": method} if method else {}
    r = simulate(arm, controller, p.q0, p.qd0, t, jacobian=jacobian, **kwargs)
    return r.q, r.n_evals


# --- compiled backend: its single-run rows here -----------------------------
# (section owned by the compiled backend; the rows are defined in scripts/bench/compiled.py)
def compiled_rows(model, controller, p: Params, t: np.ndarray) -> list[Row]:
    """Rows of the numba backend (``simulate(..., backend="compiled")``), if numba imports."""
    from rrt_pin import compiled

    if not compiled.available():
        print("compiled backend: numba not available, no rows")
        return []

    return [Row(label, run) for label, run in direct_rows(model, controller, p, t)]


# --- compiled backend: its batch rows here ----------------------------------
# (section owned by the compiled backend; the rows are defined in scripts/bench/compiled.py)
def compiled_batch_rows(model, controllers, q0s, qd0s, t: np.ndarray) -> list[Row]:
    """Batch rows of the numba backend; ``run()`` returns q of shape (B, N, 3)."""
    from rrt_pin import compiled

    if not compiled.available():
        return []

    return [Row(label, run) for label, run in batch_rows(model, controllers, q0s, qd0s, t)]


def interleaved_runs(
    rows: list[Row], repeat: int
) -> dict[str, tuple[list[float], np.ndarray, int]]:
    """Run every row once per round, ``repeat`` rounds: a changing machine load hits all
    rows alike. Returns, per label, the wall times [s] and the last output."""
    out: dict[str, tuple[list[float], np.ndarray, int]] = {}
    for _ in range(repeat):
        for row in rows:
            start = time.perf_counter()
            q, n_evals = row.run()
            elapsed = time.perf_counter() - start
            out.setdefault(row.label, ([], q, n_evals))[0].append(elapsed)
    return out


def variants(p: Params, count: int, seed: int = 7) -> tuple[list[ChapterController], np.ndarray]:
    """``count`` chapter variants: gains scaled by 0.8..1.25, q0 moved by up to ±0.1 rad/m."""
    rng = np.random.default_rng(seed)
    base = chapter_controller(p)
    controllers = [
        ChapterController(
            kp=tuple(np.array(base.kp) * rng.uniform(0.8, 1.25, 3)),
            kd=tuple(np.array(base.kd) * rng.uniform(0.8, 1.25, 3)),
            qf=base.qf,
            params=p,
        )
        for _ in range(count)
    ]
    q0s = np.array(p.q0) + rng.uniform(-0.1, 0.1, (count, 3))
    return controllers, q0s


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="runs per single-run row (median)")
    ap.add_argument("--all", action="store_true", help="also time every method of METHODS")
    ap.add_argument("--batch", type=int, default=1000, help="variants in the batch (0: skip)")
    ap.add_argument("--baseline-runs", type=int, default=20, help="baseline runs for the estimate")
    ap.add_argument("--batch-repeat", type=int, default=3, help="rounds of the batch (median)")
    ap.add_argument(
        "--threads",
        type=int,
        default=None,
        help="threads of pin.abaInParallel (default: simulate_batch's, the CPUs available)",
    )
    args = ap.parse_args()

    p = Params()
    model = rrt_model(p)
    arm = chapter_arm(p)
    controller = chapter_controller(p)
    start = time.perf_counter()
    ref = chapter_reference()
    t = ref.t
    print(
        f"reference: {ref.methods[0]} vs {ref.methods[1]} at rtol {ref.rtol:g}, atol {ref.atol:g}: "
        f"max |q difference| = {ref.difference_q:.2e}, |qd| {ref.difference_qd:.2e} "
        f"({time.perf_counter() - start:.2f} s incl. cache)"
    )
    print(
        f"grid: {t.size} points, {t[0]:g}..{t[-1]:g} s; medians of {args.repeat} interleaved "
        "rounds (each row once per round)\n"
    )

    rows = single_rows(model, controller, p, t, args.all) + compiled_rows(model, controller, p, t)
    print(f"{'single run':<38} {'time [ms]':>10} {'evals':>7} {'max|q err|':>11} {'speed-up':>9}")
    results = interleaved_runs(rows, args.repeat)
    base_time = statistics.median(results[rows[0].label][0])
    for row in rows:
        times, q, n_evals = results[row.label]
        median = statistics.median(times)
        err = np.abs(q - ref.q).max()
        print(
            f"{row.label:<38} {median * 1e3:>10.2f} {n_evals:>7d} {err:>11.2e} {base_time / median:>8.2f}x"
        )
        if row.label.startswith("rrt_pin simulate() defaults"):
            default = (median, err)
    ok = default[1] <= TARGET_ERROR and base_time / default[0] >= TARGET_SPEEDUP
    print(
        f"defaults: error {default[1]:.2e} (target <= {TARGET_ERROR:g}), speed-up "
        f"{base_time / default[0]:.2f}x (target >= {TARGET_SPEEDUP:g}x): {'OK' if ok else 'MISSED'}"
    )

    if args.batch <= 0:
        return 0
    B = args.batch
    controllers, q0s = variants(p, B)
    qd0s = np.zeros((B, 3))
    rounds = max(1, args.batch_repeat)
    per_round = -(-max(1, min(args.baseline_runs, B)) // rounds)
    print(
        f"\nbatch of {B} chapter variants (gains x0.8..1.25, q0 +-0.1), "
        f"threads={args.threads or default_num_threads()}; "
        f"{rounds} rounds, each: the baseline on {per_round} variants, then each batch row once"
    )
    batch_rows = [
        Row(
            "simulate_batch() defaults, states only",
            lambda: _batch(arm, controllers, q0s, qd0s, t, args.threads, False),
        ),
        Row(
            "simulate_batch() defaults + efforts",
            lambda: _batch(arm, controllers, q0s, qd0s, t, args.threads, True),
        ),
    ]
    batch_rows.append(
        Row(
            "simulate_batch() states, threads=1",
            lambda: _batch(arm, controllers, q0s, qd0s, t, 1, False),
        )
    )
    batch_rows += compiled_batch_rows(model, controllers, q0s, qd0s, t)
    base_times: list[float] = []
    results = {}
    for k in range(rounds):
        for i in range(k * per_round, (k + 1) * per_round):
            start = time.perf_counter()
            baseline(model, controllers[i % B], q0s[i % B], qd0s[i % B], t)
            base_times.append(time.perf_counter() - start)
        for label, value in interleaved_runs(batch_rows, 1).items():
            times, _, _ = results.setdefault(label, ([], *value[1:]))
            times += value[0]
            results[label] = (times, *value[1:])
    per_run = statistics.median(base_times)
    print(
        f"baseline: median {per_run * 1e3:.2f} ms per variant over {len(base_times)} runs "
        f"-> {B} variants ~ {per_run * B:.2f} s"
    )
    checked = sorted({0, B // 2, B - 1})
    refs = {i: reference_run(model, controllers[i], q0s[i], qd0s[i], t).q for i in checked}
    print(f"accuracy judged on variants {checked} against their own DOP853/Radau references")
    print(f"{'batch':<38} {'time [s]':>10} {'evals':>7} {'max|q err|':>11} {'throughput':>11}")
    for row in batch_rows:
        times, Q, n_evals = results[row.label]
        median = statistics.median(times)
        err = max(np.abs(Q[i] - refs[i]).max() for i in checked)
        ratio = per_run * B / median
        print(f"{row.label:<38} {median:>10.3f} {n_evals:>7d} {err:>11.2e} {ratio:>10.1f}x")
        if row.label.startswith("simulate_batch() defaults, states only"):
            ok_b = err <= TARGET_ERROR and ratio >= TARGET_BATCH_SPEEDUP
            print(
                f"batch: error {err:.2e} (target <= {TARGET_ERROR:g}), throughput {ratio:.1f}x "
                f"(target >= {TARGET_BATCH_SPEEDUP:g}x): {'OK' if ok_b else 'MISSED'}"
            )
    return 0


def _batch(arm, controllers, q0s, qd0s, t, threads, efforts):
    r = simulate_batch(arm, controllers, q0s, qd0s, t, threads=threads, efforts=efforts)
    return r.q, r.n_evals


if __name__ == "__main__":
    sys.exit(main())
