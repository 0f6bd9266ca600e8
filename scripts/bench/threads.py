#!/usr/bin/env python3
"""Batched Pinocchio inverse dynamics: the default thread choice against 1 and 2 threads,
on a quiet machine and with a CPU-bound process holding one core.

Times, interleaved, medians of --repeat rounds: a Python loop of ``pin.rnea`` (the
baseline), ``inverse_dynamics`` with ``num_threads=1``, ``=2`` and the default
(pools kept between calls, threads chosen by problem size and by the CPUs free now),
for the chapter's 15,001 samples and for UR5 and Panda along a rest-to-rest motion.
Prints each one's ratio to the loop and, under contention, the default's time over
the one-thread time (target ≤ 1.3). "raw 2" is ``pin.rneaInParallel`` itself on two
threads (pool and output made once, outside the timing): the ceiling of the wrapper.
Targets on 2 cores: ≥ 5.5× the loop for the chapter, ≥ 2.5× for UR5 and Panda.
The "batch" rows time ``simulate_batch`` (Pinocchio backend, --batch chapter variants,
no error estimate) on 1 thread, 2 and the default; its ratios are to the 1-thread run.

The "generated" table times ``inverse_dynamics(..., backend="compiled")`` on the RNEA
generated from each robot's Pinocchio model (:mod:`rrt_pin.compiled.rnea`; for the
chapter, its plain ``pin.Model``, as the arm's Robot runs the closed form), on one
thread and the default, in the same interleaved rounds as the loop: ns a sample, the
ratio to the loop, and the kernel's operations a sample (flops, sines and cosines).
Its compilation (or load from the disk cache) is paid before the timing.

A third table times the default against one thread on the chapter's arm for small
batches (--sizes): the thread count follows the problem size, so the default should
never be slower than one thread (default/1 ≤ 1, within noise).

    .venv/bin/python -m scripts.bench.threads [--repeat 15] [--sizes 64,256,512,1024,4096]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

import numpy as np
import pinocchio as pin

from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.robots import chapter_arm, get

BURNER = "import time\nend = time.time() + 600\nwhile time.time() < end: pass\n"


def _cases():
    arm = chapter_arm()
    d = arm.defaults
    yield "chapter", arm, rest_to_rest(d.q0, d.qf, 15.0, np.linspace(0, 15, 15_001))
    for name in ("ur5", "panda"):
        robot = get(name)
        n = robot.nv
        q0 = np.zeros(n)
        qf = np.linspace(0.2, 0.8, n)
        yield name, robot, rest_to_rest(q0, qf, 15.0, np.linspace(0, 15, 15_001))


def _loop(model, m) -> None:
    data = model.createData()
    for i in range(m.q.shape[0]):
        pin.rnea(model, data, m.q[i], m.qd[i], m.qdd[i])


def _sides(robot, m, generated: bool) -> dict:  # noqa: ANN001
    """The ways to compute the efforts of motion ``m``, by name."""
    model = robot.model
    pool = pin.ModelPool(model, 2)
    out = np.empty((model.nv, m.q.shape[0]), order="F")
    qT, qdT, qddT = (np.asfortranarray(robot.configuration(m.q).T), m.qd.T, m.qdd.T)
    gen = {}
    if generated:
        # The chapter's Robot runs its closed form: its plain model runs the generated RNEA.
        target = model if robot.is_chapter_arm else robot
        gen = {
            "gen 1": lambda: inverse_dynamics(
                target, m.q, m.qd, m.qdd, backend="compiled", num_threads=1
            ),
            "gen default": lambda: inverse_dynamics(target, m.q, m.qd, m.qdd, backend="compiled"),
        }
    return {
        **gen,
        "loop": lambda: _loop(model, m),
        "raw 2": lambda: pin.rneaInParallel(2, pool, qT, qdT, qddT, out),
        "1": lambda: inverse_dynamics(robot, m.q, m.qd, m.qdd, num_threads=1),
        "2": lambda: inverse_dynamics(robot, m.q, m.qd, m.qdd, num_threads=2),
        "default": lambda: inverse_dynamics(robot, m.q, m.qd, m.qdd),
    }


def _median_times(sides: dict, repeat: int, inner: int = 1) -> dict[str, float]:
    """Median [s] of each side over ``repeat`` interleaved rounds of ``inner`` calls."""
    times: dict[str, list[float]] = {k: [] for k in sides}
    for _ in range(repeat):
        for k, f in sides.items():
            f()  # not counted: warms this side's caches after the others ran
            start = time.perf_counter()
            for _ in range(inner):
                f()
            times[k].append((time.perf_counter() - start) / inner)
    return {k: statistics.median(v) for k, v in times.items()}


def _sizes(sizes: list[int], repeat: int) -> None:
    arm = chapter_arm()
    d = arm.defaults
    print(f"\n{'samples':>8} {'1 thread [us]':>14} {'default [us]':>13} {'default/1':>10}")
    for n in sizes:
        m = rest_to_rest(d.q0, d.qf, 15.0, np.linspace(0, 15, n))
        sides = {
            "1": lambda m=m: inverse_dynamics(arm, m.q, m.qd, m.qdd, num_threads=1),
            "default": lambda m=m: inverse_dynamics(arm, m.q, m.qd, m.qdd),
        }
        med = _median_times(sides, repeat, inner=max(1, 20_000 // n))
        print(f"{n:>8} {med['1'] * 1e6:>14.1f} {med['default'] * 1e6:>13.1f} "
              f"{med['default'] / med['1']:>10.2f}")  # fmt: skip


def _batch_sides(variants: int) -> dict:
    """``simulate_batch`` (Pinocchio backend) of ``variants`` chapter variants: 1 thread, default."""
    from rrt_pin.simulate import simulate_batch
    from rrt_pin.simulate.control import ChapterController, chapter_controller

    arm = chapter_arm()
    law = chapter_controller(arm.params)
    rng = np.random.default_rng(7)
    laws = [
        ChapterController(kp=np.asarray(law.kp) * g, kd=law.kd, qf=law.qf, params=law.params)
        for g in rng.uniform(0.8, 1.25, variants)
    ]
    q0s = arm.defaults.q0 + rng.uniform(-0.1, 0.1, (variants, 3))
    t = np.linspace(0.0, 15.0, 1501)

    def run(threads: int | None) -> None:
        simulate_batch(arm, laws, q0s, None, t, threads=threads, estimate_error=False)

    return {"1": lambda: run(1), "2": lambda: run(2), "default": lambda: run(None)}


def _generated_ready() -> dict[str, object]:
    """Each case's generated kernel, compiled (or loaded) now; {} without numba."""
    try:
        from rrt_pin.compiled import rnea
    except ImportError:
        return {}
    import importlib.util

    if importlib.util.find_spec("numba") is None:
        return {}
    kernels = {}
    for name, robot, _ in _cases():
        kernel = rnea.kernel_for(robot.model)
        print(f"generated RNEA of {name}: {kernel.origin} in {kernel.seconds:.2f} s")
        kernels[name] = kernel
    return kernels


def _generated_table(load: str, rows: list) -> None:
    """ns a sample and ratio to the loop of the generated kernels (1 thread, default)."""
    if not rows:
        return
    print(f"\n{'generated':<9} {'load':<8} {'loop ns':>8} {'1 thread ns':>12} {'ratio':>7} "
          f"{'default ns':>11} {'ratio':>7} {'flops':>6} {'sin/cos':>8}")  # fmt: skip
    for name, n, med, kernel in rows:
        ns = {k: med[k] / n * 1e9 for k in ("loop", "gen 1", "gen default")}
        print(f"{name:<9} {load:<8} {ns['loop']:>8.0f} {ns['gen 1']:>12.1f} "
              f"{ns['loop'] / ns['gen 1']:>6.2f}x {ns['gen default']:>11.1f} "
              f"{ns['loop'] / ns['gen default']:>6.2f}x {kernel.flops:>6} "
              f"{kernel.transcendentals:>8}")  # fmt: skip
    print()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--sizes", default="64,256,512,1024,2048,4096")
    parser.add_argument("--batch", type=int, default=200, help="variants of simulate_batch")
    args = parser.parse_args()
    repeat = args.repeat
    generated = _generated_ready()
    print(f"{'robot':<8} {'load':<8} {'loop [ms]':>10} {'raw 2':>7} {'1 thread':>9} "
          f"{'2 threads':>10} {'default':>8} {'default/1':>10}")  # fmt: skip
    for load in ("quiet", "1 busy"):
        burner = None
        if load != "quiet":
            burner = subprocess.Popen([sys.executable, "-c", BURNER])
            time.sleep(1.0)
        rows = []
        try:
            for name, robot, m in _cases():
                med = _median_times(_sides(robot, m, bool(generated)), repeat)
                base = med["loop"]
                if generated:
                    rows.append((name, m.q.shape[0], med, generated[name]))
                print(f"{name:<8} {load:<8} {base * 1e3:>10.2f} {base / med['raw 2']:>6.2f}x "
                      f"{base / med['1']:>8.2f}x "
                      f"{base / med['2']:>9.2f}x {base / med['default']:>7.2f}x "
                      f"{med['default'] / med['1']:>10.2f}")  # fmt: skip
            if args.batch:
                med = _median_times(_batch_sides(args.batch), max(3, repeat // 3))
                print(f"{'batch':<8} {load:<8} {med['1'] * 1e3:>10.2f} {'':>7} {'(1 t ms)':>9} "
                      f"{med['1'] / med['2']:>9.2f}x {med['1'] / med['default']:>7.2f}x "
                      f"{med['default'] / med['1']:>10.2f}")  # fmt: skip
        finally:
            if burner is not None:
                burner.kill()
                burner.wait()
        _generated_table(load, rows)
    if args.sizes:
        _sizes([int(x) for x in args.sizes.split(",")], repeat)


if __name__ == "__main__":
    main()
