#!/usr/bin/env python
"""The compiled backend against its baselines, side by side in one run.

Sections (medians over --repeat rounds; each round runs every side a few times
back to back, see :func:`interleaved`):

1. compile: numba's import and the compilation or cache load, apart from run times;
2. direct: the chapter's run (0..15 s, 1,501 outputs) — baseline ``solve_ivp(DOP853,
   rtol=1e-10, atol=1e-12)`` on a Python right-hand side calling ``pin.aba`` — against
   ``simulate(..., backend="compiled")``; error = max |q − reference| with the
   reference of ``rrt_pin.simulate.reference.chapter_reference`` (DOP853 at rtol 1e-13,
   cross-checked with Radau). Targets: error <= 1e-8, <= 0.5 ms, >= 40x;
3. inverse: the chapter's 15,001 samples — a Python loop over ``pin.rnea`` against
   ``rrt_pin.compiled.inverse_dynamics``. Targets: <= 1 ms, >= 50x, same values to 1e-12;
4. batch: --batch chapter variants (gains, q0 and masses varied) with
   ``simulate_batch_compiled``, keeping full trajectories, final states only
   (``keep="final"``) or metrics (``keep="metrics"``), on 1 and 2 threads, interleaved.
   Targets: >= 2,000 simulations per second on one core (full trajectories);
   >= 15,000 simulations/s/core keeping final states or metrics at max |q err| <= 1e-9
   (--lean-rtol, --lean-atol; the metrics' error is that of the samples they are
   computed from: every output time of the lean trajectories); parallel efficiency
   rate(2) / (2 rate(1)) >= 90 % (the median over rounds of each round's 1- and
   2-thread runs, side by side); with a CPU-bound process holding one core ("1 busy"),
   the default thread count at most 1.3x slower than one thread;
5. physics: the compiled M, c + G, G, RNEA and ABA against Pinocchio at 1,000
   seeded random states (target <= 1e-12 relative), and the compiled trajectories
   against the Pinocchio backend's with the same method and tolerance;
6. process: whole-process ``rrt-pin inverse --csv`` with ``--backend pinocchio`` and
   ``--backend compiled``, and ``import numba`` alone (budget 1 s);
7. lanes: the batch of section 4 (final states and metrics, one thread) with each
   count of variants integrated side by side (``rrt_pin.compiled._jit_batch.LANES``).

``scripts/bench/direct.py`` and ``scripts/bench/inverse.py`` import
:func:`direct_rows`, :func:`batch_rows` and :func:`inverse_verdict` from here for
their compiled rows.

    .venv/bin/python -m scripts.bench.compiled [--repeat 21] [--batch 2000] [--check]
        [--only direct,batch,busy,inverse,physics,process,lanes] [--lanes 16]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np

from rrt_pin.robot.robots import chapter_arm
from scripts.bench.common import interleaved, verdict

TARGET_ERROR = 1e-8  # [rad, m]
TARGET_DIRECT_S = 0.5e-3
TARGET_DIRECT_SPEEDUP = 40.0
TARGET_DIRECT_SPEEDUP_16 = 100.0  # the lean direct run's target
TARGET_INVERSE_S = 1e-3
TARGET_INVERSE_SPEEDUP = 50.0
TARGET_BATCH_RATE = 2000.0  # simulations per second
TARGET_LEAN_RATE = 15000.0  # simulations per second per core, final states or metrics kept
TARGET_LEAN_ERROR = 1e-9  # [rad, m]
TARGET_EFFICIENCY = 0.9  # rate(2 threads) / (2 rate(1 thread))
TARGET_BUSY_RATIO = 1.3  # default threads / 1 thread, another process holding one core
TARGET_AGREEMENT = 1e-12
TARGET_PROCESS_S = 1.0

Run = Callable[[], tuple[np.ndarray, int]]


# --------------------------------------------------------------------------------------------
# Pieces used by scripts/bench/direct.py and scripts/bench/inverse.py
# --------------------------------------------------------------------------------------------


def compile_line() -> str:
    """Compile (or load) the backend and describe what it cost."""
    from rrt_pin import compiled

    cached = compiled.is_compiled()
    report = compiled.ensure_compiled()
    return f"{report.describe()}; is_compiled() before: {cached}"


def direct_rows(model, controller, p, t: np.ndarray) -> list[tuple[str, Run]]:
    """(label, run) rows of the compiled backend on the chapter's run; ``run()`` -> (q, evals)."""
    from rrt_pin.simulate import simulate

    print(f"compiled: {compile_line()}")
    arm = chapter_arm(p)

    def sim(method: str, **kw) -> Run:
        def run():
            r = simulate(
                arm, controller, p.q0, p.qd0, t, method=method, backend="compiled",
                **kw,
            )  # fmt: skip
            return r.q, r.n_evals

        return run

    return [
        ("compiled DOP853 (simulate defaults)", sim("DOP853")),
        ("compiled DOP853 1e-10 (baseline tol)", sim("DOP853", rtol=1e-10, atol=1e-12)),
        ("compiled RK45 1e-10", sim("RK45", rtol=1e-10, atol=1e-12)),
        ("compiled rk4 step 10 ms", sim("rk4", step=0.01)),
        ("compiled verlet step 10 ms", sim("verlet", step=0.01)),
    ]


def batch_rows(model, controllers, q0s, qd0s, t: np.ndarray) -> list[tuple[str, Run]]:
    """(label, run) batch rows of the compiled backend; ``run()`` -> (q (B, N, 3), evals)."""
    from rrt_pin import compiled

    compiled.ensure_compiled()
    p = controllers[0].params

    def run(method: str, efforts: bool) -> Run:
        def go():
            r = compiled.simulate_batch_compiled(
                p, controllers, q0s, qd0s, t, method=method, efforts=efforts
            )
            return r.q, r.n_evals

        return go

    return [
        ("compiled batch DOP853, states only", run("DOP853", False)),
        ("compiled batch DOP853 + efforts", run("DOP853", True)),
    ]


def inverse_verdict(medians: dict[str, float], results: dict[str, np.ndarray]) -> dict[str, bool]:
    """The compiled inverse-dynamics targets from bench_inverse's medians and results."""
    if "compiled" not in medians:
        return {}
    base, mine = medians["loop"], medians["compiled"]
    ref = results["loop"]
    rel = float((np.abs(results["compiled"] - ref).max(axis=0) / np.abs(ref).max(axis=0)).max())
    return {
        f"compiled <= {TARGET_INVERSE_S * 1e3:g} ms ({mine * 1e3:.3f} ms)": mine
        <= TARGET_INVERSE_S,
        f"compiled >= {TARGET_INVERSE_SPEEDUP:g}x the loop ({base / mine:.0f}x)": base / mine
        >= TARGET_INVERSE_SPEEDUP,
        f"compiled agrees to {TARGET_AGREEMENT:g} ({rel:.1e})": rel <= TARGET_AGREEMENT,
    }


# --------------------------------------------------------------------------------------------
# The standalone benchmark
# --------------------------------------------------------------------------------------------
def baseline_direct(
    model, controller, q0, qd0, t, rtol: float = 1e-10, atol: float = 1e-12
) -> tuple[np.ndarray, int]:
    """solve_ivp DOP853 (rtol 1e-10, atol 1e-12 by default) on a Python rhs calling pin.aba."""
    import pinocchio as pin
    from scipy.integrate import solve_ivp

    data = model.createData()

    def rhs(_t, y):
        q, v = y[:3], y[3:]
        return np.concatenate((v, pin.aba(model, data, q, v, controller(q, v))))

    sol = solve_ivp(
        rhs, (t[0], t[-1]), np.concatenate((q0, qd0)), method="DOP853", t_eval=t, rtol=rtol,
        atol=atol,
    )  # fmt: skip
    return sol.y[:3].T, sol.nfev


def section_direct(repeat: int) -> dict[str, bool]:
    from rrt_pin import compiled
    from rrt_pin.robot.model import rrt_model
    from rrt_pin.robot.params import Params
    from rrt_pin.simulate.control import chapter_controller
    from rrt_pin.simulate.reference import chapter_reference

    p = Params()
    model, ctrl = rrt_model(p), chapter_controller(p)
    ref = chapter_reference()
    t = ref.t
    print(
        f"\n2. direct dynamics, the chapter's run: {t.size} outputs over {t[0]:g}..{t[-1]:g} s; "
        f"reference {ref.methods[0]} vs {ref.methods[1]} at rtol {ref.rtol:g} differ by "
        f"{ref.difference_q:.1e}"
    )
    rows: dict[str, Run] = {"baseline solve_ivp DOP853 + pin.aba": lambda: baseline_direct(
        model, ctrl, p.q0, p.qd0, t
    )}  # fmt: skip
    rows.update(direct_rows(model, ctrl, p, t))
    lean = "compiled DOP853, estimate_error=False"
    arm = chapter_arm(p)
    rows[lean] = lambda: _lean(arm, ctrl, p, t)
    rows["compiled.simulate_compiled (no simulate())"] = lambda: _raw(compiled, p, ctrl, t)
    t15 = np.linspace(0.0, 15.0, 15001)
    rows["compiled DOP853, 15,001 outputs"] = lambda: _raw(compiled, p, ctrl, t15)
    out = {name: run() for name, run in rows.items()}  # warm
    medians = interleaved(rows, repeat)
    base = medians["baseline solve_ivp DOP853 + pin.aba"]
    print(f"{'side':<44} {'time [ms]':>10} {'evals':>6} {'max|q err|':>11} {'speed-up':>9}")
    for name, (q, evals) in out.items():
        err = np.abs(q - ref.q).max() if q.shape == ref.q.shape else np.nan
        print(
            f"{name:<44} {medians[name] * 1e3:>10.3f} {evals:>6d} {err:>11.2e} "
            f"{base / medians[name]:>8.1f}x"
        )
    name = "compiled DOP853 (simulate defaults)"
    err = np.abs(out[name][0] - ref.q).max()
    lean_err = np.abs(out[lean][0] - ref.q).max()
    return {
        f"direct error <= {TARGET_ERROR:g} ({err:.1e})": err <= TARGET_ERROR,
        f"direct <= {TARGET_DIRECT_S * 1e3:g} ms ({medians[name] * 1e3:.3f} ms)": medians[name]
        <= TARGET_DIRECT_S,
        f"direct >= {TARGET_DIRECT_SPEEDUP:g}x the baseline ({base / medians[name]:.0f}x)": (
            base / medians[name] >= TARGET_DIRECT_SPEEDUP
        ),
        f"direct >= {TARGET_DIRECT_SPEEDUP_16:g}x the baseline (lean direct run: no error "
        f"estimate, {medians[lean] * 1e3:.3f} ms, error {lean_err:.1e}) "
        f"({base / medians[lean]:.0f}x)": base / medians[lean] >= TARGET_DIRECT_SPEEDUP_16
        and lean_err <= TARGET_ERROR,
    }


def _lean(arm, ctrl, p, t):
    from rrt_pin.simulate import simulate

    r = simulate(arm, ctrl, p.q0, p.qd0, t, backend="compiled", estimate_error=False)
    return r.q, r.n_evals


def _raw(compiled, p, ctrl, t):
    r = compiled.simulate_compiled(p, ctrl, p.q0, p.qd0, t)
    return r.q, r.n_evals


def section_inverse(repeat: int) -> dict[str, bool]:
    import pinocchio as pin

    from rrt_pin import compiled
    from rrt_pin.core.grid import time_grid
    from rrt_pin.dynamics.trajectory import rest_to_rest
    from rrt_pin.robot.model import rrt_model
    from rrt_pin.robot.params import Params

    p = Params()
    model = rrt_model(p)
    traj = rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, 0.001))
    q, qd, qdd = traj.q, traj.qd, traj.qdd
    data = model.createData()

    def loop():
        out = np.empty((q.shape[0], 3))
        for i in range(q.shape[0]):
            out[i] = pin.rnea(model, data, q[i], qd[i], qdd[i])
        return out

    funcs = {"loop": loop, "compiled": lambda: compiled.inverse_dynamics(q, qd, qdd, p)}
    results = {k: f() for k, f in funcs.items()}
    medians = interleaved(funcs, max(3, repeat // 3), inner=2)
    print(f"\n3. inverse dynamics, the chapter's {q.shape[0]} samples")
    for k, v in medians.items():
        print(f"{k:<44} {v * 1e3:>10.3f} ms {medians['loop'] / v:>8.1f}x")
    return inverse_verdict(medians, results)


def seed_variants(count: int, seed: int = 7):
    """``count`` chapter variants: gains x0.8..1.25, q0 +-0.1, masses x0.8..1.25 (own Params each)."""
    from rrt_pin.robot.params import Params
    from rrt_pin.simulate.control import ChapterController

    rng = np.random.default_rng(seed)
    base = Params()
    plants, controllers = [], []
    for _ in range(count):
        m = np.array([base.m1, base.m2, base.m3]) * rng.uniform(0.8, 1.25, 3)
        plant = base.with_overrides({"m1": m[0], "m2": m[1], "m3": m[2]})
        plants.append(plant)
        controllers.append(
            ChapterController(
                kp=tuple(np.array(base.kp) * rng.uniform(0.8, 1.25, 3)),
                kd=tuple(np.array(base.kd) * rng.uniform(0.8, 1.25, 3)),
                qf=base.qf,
                params=plant,
            )
        )
    q0s = np.array(base.q0) + rng.uniform(-0.1, 0.1, (count, 3))
    return plants, controllers, q0s, np.zeros((count, 3))


def vector_reference_funcs(seconds: float = 0.02) -> dict[int, Callable[[], object]]:
    """Pure vector arithmetic on 1 and on 2 threads (the same work): the machine's reference.

    A multiply-add over three arrays that stay in each core's L1 cache, compiled
    with numba (GIL released), each thread on arrays of its own: no memory traffic
    and nothing shared, so its 2-thread efficiency is what the CPUs give two threads
    that fill their vector units at that moment (a VM's two vCPUs may share a
    physical core's units): a reference for the batches' efficiency, measured in the
    same rounds.
    """
    import numba

    @numba.njit(nogil=True, fastmath=True, cache=False)
    def multiply_add(a, b, c, reps):
        for _ in range(reps):
            for i in range(a.shape[0]):
                a[i] = a[i] * b[i] + c[i]  # b, c < 0.5: a stays bounded

    rng = np.random.default_rng(0)
    arrays = [tuple(rng.uniform(0.0, 0.5, 2048) for _ in range(3)) for _ in range(2)]
    multiply_add(*arrays[0], 1)
    start = time.perf_counter()
    multiply_add(*arrays[0], 1000)
    reps = max(2, int(seconds / max(time.perf_counter() - start, 1e-9) * 1000)) // 2 * 2
    pool = ThreadPoolExecutor(1)

    def one() -> None:
        multiply_add(*arrays[0], reps)

    def two() -> None:
        helper = pool.submit(multiply_add, *arrays[1], reps // 2)
        multiply_add(*arrays[0], reps // 2)
        helper.result()

    return {1: one, 2: two}


def section_batch(count: int, repeat: int, lean_rtol: float, lean_atol: float) -> dict[str, bool]:
    from rrt_pin import compiled
    from rrt_pin.robot.model import rrt_model
    from rrt_pin.simulate.metrics import GROUPS, batch_metrics
    from rrt_pin.simulate.reference import reference_run

    plants, controllers, q0s, qd0s = seed_variants(count)
    t = np.linspace(0.0, 15.0, 1501)

    def batch(keep: str, threads: int | None, rtol: float | None = None):
        return compiled.simulate_batch_compiled(
            plants, controllers, q0s, qd0s, t, rtol=rtol, atol=None if rtol is None else lean_atol,
            keep=keep, threads=threads,
        )  # fmt: skip

    lean = f"rtol {lean_rtol:g}, atol {lean_atol:g}"
    sides = {"full trajectories (defaults, rtol 1e-10)": ("trajectories", None)}
    sides[f"full trajectories, {lean}"] = ("trajectories", lean_rtol)
    sides[f"final states, {lean}"] = ("final", lean_rtol)
    sides[f"metrics, {lean}"] = ("metrics", lean_rtol)
    funcs = {}
    for label, (keep, rtol) in sides.items():
        for threads in (1, 2):
            funcs[(label, threads)] = lambda keep=keep, rtol=rtol, threads=threads: batch(
                keep, threads, rtol
            )
    results = {k: f() for k, f in funcs.items()}
    vector_label = "pure vector arithmetic (the machine's reference)"
    for threads, f in vector_reference_funcs().items():
        funcs[(vector_label, threads)] = f
    from rrt_pin.core import cpus

    busy_before, load_before = cpus.busy(), os.getloadavg()[0]
    cpu_start, wall_start = time.process_time(), time.perf_counter()
    samples: dict = {}
    medians = interleaved(funcs, max(3, repeat // 5), inner=1, rounds=samples)
    cores = (time.process_time() - cpu_start) / (time.perf_counter() - wall_start)
    two = {k: f for k, f in funcs.items() if k[1] == 2}
    cpu_start, wall_start = time.process_time(), time.perf_counter()
    for f in two.values():
        f()
    cores2 = (time.process_time() - cpu_start) / (time.perf_counter() - wall_start)
    checked = sorted({*range(0, count, max(1, count // 6)), count - 1})
    refs = {i: reference_run(rrt_model(plants[i]), controllers[i], q0s[i], qd0s[i], t)
            for i in checked}  # fmt: skip
    print(
        f"\n4. batch: {count} chapter variants (gains, q0, masses), 0..15 s, 1,501 output "
        f"times, DOP853; error = max |q - vector_label| over variants {checked} "
        f"(at every output time for trajectories and metrics, at 15 s for final states)"
    )
    print(
        f"{'kept':<44} {'1 thread [s]':>12} {'sims/s':>8} {'2 threads [s]':>13} "
        f"{'sims/s/core':>11} {'efficiency':>10} {'error':>8}"
    )
    rates, errors, efficiency = {}, {}, {}
    for label, (keep, _) in sides.items():
        one, two = medians[(label, 1)], medians[(label, 2)]
        r = results[(label, 1)]
        assert np.array_equal(r.q, results[(label, 2)].q), "threads changed the numbers"
        if keep == "metrics":  # the samples they are computed from: the lean trajectories'
            r = results[(f"full trajectories, {lean}", 1)]
        if keep != "final":
            err = max(np.abs(r.q[i] - refs[i].q).max() for i in checked)
        else:
            err = max(np.abs(r.q[i, -1] - refs[i].q[-1]).max() for i in checked)
        rates[label] = (count / one, count / two / 2)
        # Each round's 1- and 2-thread runs side by side (the machine's speed drifts
        # by tens of percent from one second to the next, a round takes a second).
        pairs = zip(samples[(label, 1)], samples[(label, 2)], strict=True)
        efficiency[label] = statistics.median(a / (2 * b) for a, b in pairs)
        errors[label] = err
        print(
            f"{label:<44} {one:>12.3f} {count / one:>8,.0f} {two:>13.3f} "
            f"{count / two / 2:>11,.0f} {efficiency[label]:>9.0%} {err:>8.1e}"
        )
    pairs = zip(samples[(vector_label, 1)], samples[(vector_label, 2)], strict=True)
    machine = statistics.median(a / (2 * b) for a, b in pairs)
    print(
        f"   {vector_label}: {machine:.0%} efficiency in the same rounds (a multiply-add in each "
        f"core's L1 cache, nothing shared: what the CPUs give two threads that fill their "
        f"vector units now)"
    )
    print(
        f"   machine: {cpus.available()} CPUs; other processes' running tasks at the start "
        f"{busy_before}, load average {load_before:.2f}; this process used {cores:.2f} "
        f"CPUs on average over the timed rounds, {cores2:.2f} during 2-thread runs alone "
        f"(below 2: the threads waited for CPUs other work held)"
    )
    metrics_label = f"metrics, {lean}"
    got = results[(metrics_label, 1)].metrics
    ref_q = np.array([refs[i].q for i in checked])
    ref_qd = np.array([refs[i].qd for i in checked])
    ref_tau = np.array([controllers[i].efforts(refs[i].q, refs[i].qd) for i in checked])
    qf = np.array([controllers[i].qf for i in checked])
    want = batch_metrics(GROUPS, t, ref_q, ref_qd, ref_tau, qf, ("q1", "q2", "q3"),
                         ("T01x", "T12y", "F23z"))  # fmt: skip
    worst = max(
        float(np.nanmax(np.abs(got[k][checked] - v))) for k, v in want.items()
        if not k.startswith("settling_time") and not k.startswith("peak_effort_time")
    )  # fmt: skip
    same_times = all(
        np.array_equal(got[k][checked], v, equal_nan=True) for k, v in want.items()
        if k.startswith(("settling_time", "peak_effort_time"))
    )  # fmt: skip
    print(
        f"   metrics against batch_metrics of the reference runs: max |difference| {worst:.1e} "
        f"(rad, m, N·m, N, J); settling and peak times {'equal' if same_times else 'DIFFER'}"
    )
    full = "full trajectories (defaults, rtol 1e-10)"
    ok = {
        f"batch (full trajectories, 1 thread) >= {TARGET_BATCH_RATE:,.0f} simulations/s "
        f"({rates[full][0]:,.0f})": rates[full][0] >= TARGET_BATCH_RATE,
        f"batch error <= {TARGET_ERROR:g} ({errors[full]:.1e})": errors[full] <= TARGET_ERROR,
    }
    for label in (f"final states, {lean}", metrics_label):
        slow = min(rates[label])
        ok[
            f"{label}: >= {TARGET_LEAN_RATE:,.0f} sims/s/core at 1 and 2 threads "
            f"({rates[label][0]:,.0f}, {rates[label][1]:,.0f})"
        ] = slow >= TARGET_LEAN_RATE
        ok[f"{label}: error <= {TARGET_LEAN_ERROR:g} ({errors[label]:.1e})"] = (
            errors[label] <= TARGET_LEAN_ERROR
        )
    for label in sides:
        ok[
            f"{label}: parallel efficiency >= {TARGET_EFFICIENCY:.0%} ({efficiency[label]:.0%}; "
            f"pure vector arithmetic {machine:.0%})"
        ] = efficiency[label] >= TARGET_EFFICIENCY
    return ok


def section_busy(count: int, repeat: int, lean_rtol: float, lean_atol: float) -> dict[str, bool]:
    """Default threads against one thread while a CPU-bound process holds one core."""
    from rrt_pin import compiled
    from rrt_pin.core import cpus

    plants, controllers, q0s, qd0s = seed_variants(count)
    t = np.linspace(0.0, 15.0, 1501)

    def batch(threads: int | None):
        return compiled.simulate_batch_compiled(
            plants, controllers, q0s, qd0s, t, rtol=lean_rtol, atol=lean_atol,
            keep="final", threads=threads,
        )  # fmt: skip

    hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        time.sleep(1.0)
        free = cpus.free()
        used = batch(None).threads
        medians = interleaved(
            {
                "default": lambda: batch(None),
                "1 thread": lambda: batch(1),
                "2 threads": lambda: batch(2),
            },
            max(3, repeat // 5),
            inner=1,
        )
    finally:
        hog.kill()
        hog.wait()
    ratio = medians["default"] / medians["1 thread"]
    print(
        f"\n4b. 1 busy: a CPU-bound process on one of {cpus.available()} CPUs; cpus.free() = "
        f"{free}, default threads used: {used}; keep='final', {count} variants: default "
        f"{medians['default']:.3f} s, 1 thread {medians['1 thread']:.3f} s, ratio {ratio:.2f} "
        f"(2 threads forced: {medians['2 threads']:.3f} s)"
    )
    return {
        f"1 busy: default threads <= {TARGET_BUSY_RATIO:g}x one thread ({ratio:.2f}x)": ratio
        <= TARGET_BUSY_RATIO
    }


def section_physics() -> dict[str, bool]:
    import pinocchio as pin

    from rrt_pin import compiled
    from rrt_pin.robot.model import rrt_model
    from rrt_pin.robot.params import Params
    from rrt_pin.simulate import simulate
    from rrt_pin.simulate.control import chapter_controller

    p = Params(I1z=0.3, I2z=0.2)  # every term of the kernel non-zero
    model = rrt_model(p)
    data = model.createData()
    rng = np.random.default_rng(20261122)
    n = 1000
    q = np.column_stack(
        [rng.uniform(-np.pi, np.pi, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.5, 1.0, n)]
    )
    qd, qdd, tau = rng.normal(0, 2, (n, 3)), rng.normal(0, 5, (n, 3)), rng.normal(0, 200, (n, 3))
    ref = {k: [] for k in ("M", "nle", "G", "rnea", "aba")}
    for i in range(n):
        M = pin.crba(model, data, q[i])
        ref["M"].append(np.triu(M) + np.triu(M, 1).T)
        ref["nle"].append(pin.nonLinearEffects(model, data, q[i], qd[i]).copy())
        ref["G"].append(pin.computeGeneralizedGravity(model, data, q[i]).copy())
        ref["rnea"].append(pin.rnea(model, data, q[i], qd[i], qdd[i]).copy())
        ref["aba"].append(pin.aba(model, data, q[i], qd[i], tau[i]).copy())
    got = {
        "M": compiled.mass_matrix(q, p),
        "nle": compiled.nonlinear_effects(q, qd, p),
        "G": compiled.gravity(q, p),
        "rnea": compiled.inverse_dynamics(q, qd, qdd, p),
        "aba": compiled.forward_dynamics(q, qd, tau, p),
    }
    worst = {}
    for k, v in got.items():
        r = np.array(ref[k])
        axes = tuple(range(1, r.ndim))
        worst[k] = float((np.abs(v - r).max(axis=axes) / np.abs(r).max(axis=axes)).max())
    print(
        f"\n5. physics at {n} random states, max relative difference from Pinocchio: "
        + ", ".join(f"{k} {v:.1e}" for k, v in worst.items())
    )
    ok = {f"physics agrees to {TARGET_AGREEMENT:g} ({max(worst.values()):.1e})": max(
        worst.values()
    ) <= TARGET_AGREEMENT}  # fmt: skip
    seed = Params()
    ctrl, arm = chapter_controller(seed), chapter_arm(seed)
    t = np.linspace(0.0, 15.0, 1501)
    for method, tol in (("DOP853", 1e-10), ("RK45", 1e-10), ("rk4", 1e-12), ("verlet", 1e-12)):
        a = simulate(arm, ctrl, seed.q0, seed.qd0, t, method=method)
        b = simulate(arm, ctrl, seed.q0, seed.qd0, t, method=method, backend="compiled")
        diff = np.abs(a.q - b.q).max()
        print(
            f"   {method:<7} compiled vs pinocchio backend: max |dq| {diff:.1e}, evaluations "
            f"{b.n_evals} vs {a.n_evals}"
        )
        ok[f"{method} trajectories agree ({diff:.0e} <= {tol:g})"] = diff <= tol
    return ok


def process_time(argv: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(argv, check=True, capture_output=True)
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def section_process(runs: int) -> dict[str, bool]:
    print(f"\n6. whole processes (median of {runs})")
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        csv = str(Path(tmp) / "out.csv")
        for backend in ("pinocchio", "compiled"):
            argv = [sys.executable, "-m", "rrt_pin", "inverse", "--csv", csv, "--backend", backend]
            seconds = process_time(argv, runs)
            print(f"   rrt-pin inverse --csv --backend {backend:<10} {seconds:.3f} s")
            out[backend] = seconds
    numba = process_time([sys.executable, "-c", "import numba"], runs)
    bare = process_time([sys.executable, "-c", "pass"], runs)
    print(f"   python -c 'import numba'{'':<18} {numba:.3f} s (bare interpreter {bare:.3f} s)")
    return {
        f"inverse --csv, pinocchio < {TARGET_PROCESS_S:g} s ({out['pinocchio']:.2f} s)": out[
            "pinocchio"
        ]
        < TARGET_PROCESS_S,
        f"inverse --csv, compiled < {TARGET_PROCESS_S:g} s ({out['compiled']:.2f} s)": out[
            "compiled"
        ]
        < TARGET_PROCESS_S,
    }


def section_lanes(count: int, repeat: int, lean_rtol: float, lean_atol: float) -> dict[str, bool]:
    """The lean batches on one thread with 1, 4, 8, 16 and 32 lanes, interleaved."""
    from rrt_pin import compiled
    from rrt_pin.compiled import _jit_batch

    plants, controllers, q0s, qd0s = seed_variants(count)
    t = np.linspace(0.0, 15.0, 1501)
    default = _jit_batch.LANES
    counts = (1, 4, 8, 16, 32)

    def batch(keep: str, lanes: int):
        def go():
            _jit_batch.LANES = lanes
            try:
                return compiled.simulate_batch_compiled(
                    plants, controllers, q0s, qd0s, t, rtol=lean_rtol, atol=lean_atol,
                    keep=keep, threads=1,
                )  # fmt: skip
            finally:
                _jit_batch.LANES = default

        return go

    funcs = {(keep, n): batch(keep, n) for keep in ("final", "metrics") for n in counts}
    results = {k: f() for k, f in funcs.items()}
    for keep in ("final", "metrics"):
        for n in counts:
            assert np.array_equal(results[(keep, n)].q, results[(keep, 1)].q), "lanes changed bits"
    medians = interleaved(funcs, max(3, repeat // 5), inner=1)
    print(
        f"\n7. lanes: {count} chapter variants, one thread, rtol {lean_rtol:g}, atol "
        f"{lean_atol:g}; sims/s by variants integrated side by side (default {default}; "
        "the same bits at every count)"
    )
    print(f"{'kept':<10}" + "".join(f"{n:>10}" for n in counts))
    for keep in ("final", "metrics"):
        print(f"{keep:<10}" + "".join(f"{count / medians[(keep, n)]:>10,.0f}" for n in counts))
    best = min(counts, key=lambda n: medians[("metrics", n)] + medians[("final", n)])
    return {
        f"the default lanes ({default}) within 10 % of the fastest ({best})": (
            medians[("metrics", default)] + medians[("final", default)]
            <= 1.1 * (medians[("metrics", best)] + medians[("final", best)])
        )
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=21, help="timed rounds per section (median)")
    ap.add_argument("--batch", type=int, default=2000, help="variants in the batch")
    ap.add_argument("--process-runs", type=int, default=5, help="whole-process runs (median)")
    ap.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    ap.add_argument("--lean-rtol", type=float, default=1e-9, help="rtol of the lean batches")
    ap.add_argument(
        "--lean-atol",
        type=float,
        default=1e-11,
        help="atol of the lean batches [rad, m, rad/s, m/s] (1e-11: every sample of 21 "
        "variants within 5.6e-10 of the reference; 5e-11 takes 13 %% fewer steps but "
        "reached 9.9e-10, at the 1e-9 line)",
    )
    ap.add_argument(
        "--only",
        default="direct,inverse,batch,busy,physics,process",
        help="comma-separated sections to run (also: lanes)",
    )
    ap.add_argument(
        "--lanes",
        type=int,
        default=None,
        help="variants a thread integrates side by side in adaptive batches (default 16)",
    )
    args = ap.parse_args()
    only = set(args.only.split(","))
    if args.lanes is not None:
        if args.lanes < 1:
            ap.error(f"--lanes={args.lanes} must be >= 1")
        from rrt_pin.compiled import _jit_batch

        _jit_batch.LANES = args.lanes

    start = time.perf_counter()
    print(f"1. {compile_line()} ({time.perf_counter() - start:.2f} s in all)")
    ok: dict[str, bool] = {}
    if "direct" in only:
        ok |= section_direct(args.repeat)
    if "inverse" in only:
        ok |= section_inverse(args.repeat)
    if "batch" in only:
        ok |= section_batch(args.batch, args.repeat, args.lean_rtol, args.lean_atol)
    if "busy" in only:
        ok |= section_busy(args.batch, args.repeat, args.lean_rtol, args.lean_atol)
    if "physics" in only:
        ok |= section_physics()
    if "process" in only:
        ok |= section_process(args.process_runs)
    if "lanes" in only:
        ok |= section_lanes(args.batch, args.repeat, args.lean_rtol, args.lean_atol)
    print()
    for label, good in ok.items():
        print(f"target {label}: {verdict(good)}")
    return 1 if args.check and not all(ok.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
