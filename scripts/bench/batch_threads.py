#!/usr/bin/env python
"""Compiled batches on one thread, two, and the default: does a second thread pay?

``simulate_batch(..., backend="compiled")`` of the chapter's arm (its closed-form
integrators, under eq. (31), q0 spread by ±0.05 rad or m) and of UR5 (the generated
lanes, PD plus gravity with kp = 100·M_kk(qf), kd = 20·M_kk(qf), q0 = qf ± 0.3 rad,
rtol 1e-9), 15 s with outputs every 10 ms, no error estimate, ``keep="final"`` and
``"metrics"``, batches of --sizes variants. ``threads=1``, ``threads=2`` and the default
(the CPUs free at the call, none with fewer than a few variants) are timed interleaved
in one process (medians of --repeat rounds); the ratios are one thread's time over
each. With ``--busy`` a CPU-bound process holds one core meanwhile: the default must
then not be slower than one thread (ratio ≥ 1 within noise).

    .venv/bin/python -m scripts.bench.batch_threads [--sizes 1000,10000] [--repeat 5]
        [--robots arm,ur5] [--busy]
"""

from __future__ import annotations

import argparse
import subprocess
import sys

import numpy as np

from scripts.bench.common import interleaved


def _scene(name: str, count: int):  # noqa: ANN202
    """(robot, laws, q0s, qd0s, options) of a batch of ``count`` variants."""
    from rrt_pin.robot.params import Params
    from rrt_pin.robot.robots import chapter_arm, get
    from rrt_pin.simulate.control import pd_gravity_controller, seed_controller

    rng = np.random.default_rng(2)
    if name == "arm":
        p = Params()
        q0s = p.q0 + rng.uniform(-0.05, 0.05, (count, 3))
        return chapter_arm(p), [seed_controller(p)] * count, q0s, np.tile(p.qd0, (count, 1)), {}
    import pinocchio as pin

    robot = get(name)
    qf = np.array([0.3, -1.0, 1.0, 0.3, 0.5, 0.1])[: robot.nv]
    m = np.diag(pin.crba(robot.model, robot.model.createData(), qf))
    law = pd_gravity_controller(robot, kp=100 * m, kd=20 * m, qf=qf)
    q0s = qf + rng.uniform(-0.3, 0.3, (count, robot.nv))
    return robot, [law] * count, q0s, None, {"rtol": 1e-9, "atol": 1e-11}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="1000,10000", help="batch sizes, comma-separated")
    parser.add_argument("--robots", default="arm,ur5", help="arm and/or example-robot-data names")
    parser.add_argument("--repeat", type=int, default=5, help="interleaved rounds (medians)")
    parser.add_argument("--busy", action="store_true", help="a CPU-bound process holds a core")
    args = parser.parse_args()
    import rrt_pin

    t = np.linspace(0.0, 15.0, 1501)
    spinner = None
    if args.busy:
        spinner = subprocess.Popen([sys.executable, "-c", "while True: pass"])
    try:
        rows = []
        for name in args.robots.split(","):
            for count in (int(s) for s in args.sizes.split(",")):
                robot, laws, q0s, qd0s, options = _scene(name, count)
                for keep in ("final", "metrics"):

                    def run(threads, robot=robot, laws=laws, q0s=q0s, qd0s=qd0s, keep=keep,
                            options=options):  # fmt: skip
                        return lambda: rrt_pin.simulate_batch(
                            robot, laws, q0s, qd0s, t, backend="compiled", keep=keep,
                            threads=threads, estimate_error=False, **options,
                        )  # fmt: skip

                    run(1)()  # compiled (or loaded) before the timing
                    sides = {"1": run(1), "2": run(2), "default": run(None)}
                    m = interleaved(sides, args.repeat, inner=1)
                    rows.append((name, count, keep, m["1"], m["2"], m["default"]))
                    print(
                        f"{name:4s} {count:6d} {keep:7s} 1 thread {m['1'] * 1e3:8.1f} ms, "
                        f"2 threads {m['2'] * 1e3:8.1f} ms ({m['1'] / m['2']:.2f}x), default "
                        f"{m['default'] * 1e3:8.1f} ms ({m['1'] / m['default']:.2f}x)",
                        flush=True,
                    )
    finally:
        if spinner is not None:
            spinner.kill()
    print(
        "\n| robot | variants | keep | 1 thread | 2 threads | default |"
        + (" (busy core)" if args.busy else "")
    )
    print("| --- | ---: | --- | ---: | ---: | ---: |")
    for name, count, keep, one, two, default in rows:
        print(f"| {name} | {count:,} | {keep} | {one * 1e3:.1f} ms | {one / two:.2f}× | "
              f"{one / default:.2f}× |")  # fmt: skip


if __name__ == "__main__":
    main()
