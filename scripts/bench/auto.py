#!/usr/bin/env python3
"""The costs the default backend (``auto``) compares, measured here next to the registry's values.

For ``pinocchio`` and ``compiled`` (:data:`rrt_pin.core.backends.BACKENDS`):

* start-up per process [s]: a fresh interpreter that imports Pinocchio, or that loads
  the compiled code (numba's JIT cache; the module built ahead of time) and makes one
  call, minus the same interpreter without it;
* the chapter's arm: inverse dynamics [ns/sample] and the default ``simulate`` (its
  method, tolerances for the default accuracy, the error estimate) [ms per simulated s];
* other robots (UR5 and Panda, the larger per coordinate): inverse dynamics [ns per
  sample and coordinate] and the default ``simulate`` under PD + gravity from 0.3 rad
  off [ms per simulated s and coordinate].

Both backends are timed interleaved in one run; medians of ``--repeat``. The compiled
code must be built first (``rrt-pin inverse --backend compiled`` for the arm, the same
with ``--robot ur5`` / ``panda``, and one compiled simulate of each).

    .venv/bin/python -m scripts.bench.auto [--repeat 7]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import time

import numpy as np

from rrt_pin import compiled
from rrt_pin.core import backends
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot import robots
from rrt_pin.robot.params import Params
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import chapter_controller
from scripts.bench.robot_sim import scene

NAMES = ("pinocchio", "compiled")
ROBOTS = ("ur5", "panda")

_ARM_CALL = (
    "import numpy as np; from rrt_pin.robot.robots import chapter_arm; "
    "from rrt_pin.dynamics.inverse import inverse_dynamics; a = chapter_arm(); "
    "z = np.zeros((1, 3)); "
)


def _process_seconds(code: str) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True)
    return time.perf_counter() - start


def _startups(times: dict) -> None:
    floor = _process_seconds(_ARM_CALL + "inverse_dynamics(a, z, z, z, backend='symbolic')")
    pin = _process_seconds(_ARM_CALL + "import pinocchio")
    aot = _process_seconds(_ARM_CALL + "inverse_dynamics(a, z, z, z, backend='compiled')")
    jit = _process_seconds(_ARM_CALL + "from rrt_pin import compiled; compiled.ensure_compiled()")
    times.setdefault(("pinocchio", "startup"), []).append(pin - floor)
    times.setdefault(("compiled", "startup"), []).append(jit - floor)
    times.setdefault(("compiled", "aot_startup"), []).append(aot - floor)


def _robot_problem(name: str) -> tuple:
    """(robot, law, q0): the scene of ``scripts/bench/robot_sim.py``."""
    robot, law, q0, _ = scene(name)
    return robot, law, q0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    repeat = parser.parse_args().repeat
    compiled.ensure_compiled()
    p = Params()
    arm = robots.chapter_arm(p)
    arm.model  # noqa: B018  (its Pinocchio model built before any timing)
    law = chapter_controller(p)
    q0 = (p.q10, p.q20, p.q30)
    motion = rest_to_rest(q0, (p.q1f, p.q2f, p.q3f), p.Tp, np.linspace(0.0, p.Tp, 150_001))
    tf = 15.0
    out = np.linspace(0.0, tf, 1501)
    others = {name: _robot_problem(name) for name in ROBOTS}
    rng = np.random.default_rng(0)
    states = {
        name: tuple(rng.uniform(-1.0, 1.0, (150_001, r.nv)) for _ in range(3))
        for name, (r, _, _) in others.items()
    }
    t5 = np.linspace(0.0, 5.0, 501)
    for name, (robot, rlaw, rq0) in others.items():  # load (or compile) outside the timing
        inverse_dynamics(robot, *(s[:10] for s in states[name]), backend="compiled")
        simulate(robot, rlaw, rq0, None, t5[:3], backend="compiled")
    times: dict[tuple[str, str], list[float]] = {}
    for _ in range(repeat):  # interleaved: every backend in every round
        _startups(times)
        for name in NAMES:
            start = time.perf_counter()
            inverse_dynamics(arm, motion.q, motion.qd, motion.qdd, backend=name)
            times.setdefault((name, "inverse"), []).append(
                (time.perf_counter() - start) / motion.t.size
            )
            start = time.perf_counter()
            simulate(arm, law, q0, None, out, backend=name)
            times.setdefault((name, "simulate"), []).append((time.perf_counter() - start) / tf)
            for rname, (robot, rlaw, rq0) in others.items():
                q, qd, qdd = states[rname]
                start = time.perf_counter()
                inverse_dynamics(robot, q, qd, qdd, backend=name)
                per = (time.perf_counter() - start) / q.shape[0] / robot.nv
                times.setdefault((name, f"robot_inverse {rname}"), []).append(per)
                start = time.perf_counter()
                simulate(robot, rlaw, rq0, None, t5, backend=name)
                per = (time.perf_counter() - start) / 5.0 / robot.nv
                times.setdefault((name, f"robot_simulate {rname}"), []).append(per)
    for rname in ROBOTS:  # the registry keeps the larger per coordinate
        for name in NAMES:
            for kind in ("robot_inverse", "robot_simulate"):
                times.setdefault((name, kind), [0.0])
                worst = statistics.median(times[(name, f"{kind} {rname}")])
                times[(name, kind)] = [max(times[(name, kind)][0], worst)]
    fields = {
        "startup": ("startup", 1.0, "start-up [s]"),
        "aot_startup": ("aot_startup", 1.0, "start-up, ahead of time [s]"),
        "inverse": ("inverse_cost", 1e9, "arm inverse [ns/sample]"),
        "simulate": ("simulate_cost", 1e3, "arm simulate [ms/simulated s]"),
        "robot_inverse": ("robot_inverse_cost", 1e9, "robot inverse [ns/sample/coord]"),
        "robot_simulate": ("robot_simulate_cost", 1e3, "robot simulate [ms/sim s/coord]"),
    }
    print(f"{'backend':<10} {'cost':<34} {'measured':>10} {'registry':>10} {'ratio':>6}")
    for name in NAMES:
        backend = backends.get(name)
        for kind, (field, scale, label) in fields.items():
            if (name, kind) not in times:
                continue
            measured = statistics.median(times[(name, kind)]) * scale
            registered = (getattr(backend, field) or 0.0) * scale
            ratio = measured / registered if registered else float("nan")
            print(f"{name:<10} {label:<34} {measured:>10.3g} {registered:>10.3g} {ratio:>6.2f}")
    for rname in ROBOTS:
        for kind in ("robot_inverse", "robot_simulate"):
            scale = 1e9 if kind == "robot_inverse" else 1e3
            row = [statistics.median(times[(n, f"{kind} {rname}")]) * scale for n in NAMES]
            print(f"  {rname:<6} {kind:<15} pinocchio {row[0]:.3g}  compiled {row[1]:.3g}")


if __name__ == "__main__":
    main()
