#!/usr/bin/env python3
"""Batched Pinocchio inverse dynamics: the default thread choice against 1 and 2 threads,
on a quiet machine and with a CPU-bound process holding one core.

Times, interleaved, medians of --repeat rounds: a Python loop of ``pin.rnea`` (the
baseline), ``inverse_dynamics`` with ``num_threads=1``, ``=2`` and the default
(pools kept between calls, threads chosen by problem size and by the CPUs free now),
for the chapter's 15,001 samples and for UR5 and Panda along a rest-to-rest motion.
Prints each one's ratio to the loop and, under contention, the default's time over
the one-thread time (target ≤ 1.3).

    .venv/bin/python scripts/bench_threads.py [--repeat 15]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

import numpy as np
import pinocchio as pin

from rrt_pin.inverse import inverse_dynamics
from rrt_pin.robots import chapter_arm, get
from rrt_pin.trajectory import rest_to_rest

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


def _sides(robot, m) -> dict:  # noqa: ANN001
    """The four ways to compute the efforts of motion ``m``, by name."""
    model = robot.model
    return {
        "loop": lambda: _loop(model, m),
        "1": lambda: inverse_dynamics(robot, m.q, m.qd, m.qdd, num_threads=1),
        "2": lambda: inverse_dynamics(robot, m.q, m.qd, m.qdd, num_threads=2),
        "default": lambda: inverse_dynamics(robot, m.q, m.qd, m.qdd),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    repeat = parser.parse_args().repeat
    print(f"{'robot':<8} {'load':<8} {'loop [ms]':>10} {'1 thread':>9} {'2 threads':>10} "
          f"{'default':>8} {'default/1':>10}")  # fmt: skip
    for load in ("quiet", "1 busy"):
        burner = None
        if load != "quiet":
            burner = subprocess.Popen([sys.executable, "-c", BURNER])
            time.sleep(1.0)
        try:
            for name, robot, m in _cases():
                sides = _sides(robot, m)
                times: dict[str, list[float]] = {k: [] for k in sides}
                for _ in range(repeat):
                    for k, f in sides.items():
                        start = time.perf_counter()
                        f()
                        times[k].append(time.perf_counter() - start)
                med = {k: statistics.median(v) for k, v in times.items()}
                base = med["loop"]
                print(f"{name:<8} {load:<8} {base * 1e3:>10.2f} {base / med['1']:>8.2f}x "
                      f"{base / med['2']:>9.2f}x {base / med['default']:>7.2f}x "
                      f"{med['default'] / med['1']:>10.2f}")  # fmt: skip
        finally:
            if burner is not None:
                burner.kill()
                burner.wait()


if __name__ == "__main__":
    main()
