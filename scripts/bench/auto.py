#!/usr/bin/env python3
"""The costs ``--backend auto`` compares, measured here next to the registry's values.

For each backend of :data:`rrt_pin.core.backends.BACKENDS` with costs: its start-up per
process [s] (numba's import and the cache load, in a fresh interpreter, minus the
same interpreter without it), inverse dynamics of the chapter's arm [ns/sample],
and the chapter's direct run with the backend's default method [ms per simulated
second]. Both backends are timed interleaved in one run; medians of --repeat.

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
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import chapter_controller

NAMES = ("pinocchio", "compiled")


def _process_seconds(code: str) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", code], check=True)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7)
    repeat = parser.parse_args().repeat
    compiled.ensure_compiled()
    p = Params()
    arm = chapter_arm(p)
    arm.model  # noqa: B018  (its Pinocchio model built before any timing)
    law = chapter_controller(p)
    q0 = (p.q10, p.q20, p.q30)
    motion = rest_to_rest(q0, (p.q1f, p.q2f, p.q3f), p.Tp, np.linspace(0.0, p.Tp, 150_001))
    tf = 150.0
    out = np.linspace(0.0, tf, 1501)
    times: dict[tuple[str, str], list[float]] = {}
    for _ in range(repeat):  # interleaved: every backend in every round
        with_numba = _process_seconds("from rrt_pin import compiled; compiled.ensure_compiled()")
        without = _process_seconds("import rrt_pin.compiled")
        times.setdefault(("compiled", "startup"), []).append(with_numba - without)
        times.setdefault(("pinocchio", "startup"), []).append(0.0)
        for name in NAMES:
            start = time.perf_counter()
            inverse_dynamics(arm, motion.q, motion.qd, motion.qdd, backend=name)
            times.setdefault((name, "inverse"), []).append(
                (time.perf_counter() - start) / motion.t.size
            )
            method = backends.get(name).default_method
            start = time.perf_counter()
            simulate(arm, law, q0, None, out, backend=name, method=method)
            times.setdefault((name, "simulate"), []).append((time.perf_counter() - start) / tf)
    print(f"{'backend':<10} {'cost':<28} {'measured':>10} {'registry':>10} {'ratio':>6}")
    fields = {
        "startup": ("startup", 1.0, "start-up [s]"),
        "inverse": ("inverse_cost", 1e9, "inverse [ns/sample]"),
        "simulate": ("simulate_cost", 1e3, "simulate [ms/simulated s]"),
    }
    for name in NAMES:
        backend = backends.get(name)
        for kind, (field, scale, label) in fields.items():
            measured = statistics.median(times[(name, kind)]) * scale
            registered = (getattr(backend, field) or 0.0) * scale
            ratio = measured / registered if registered else float("nan")
            print(f"{name:<10} {label:<28} {measured:>10.3g} {registered:>10.3g} {ratio:>6.2f}")


if __name__ == "__main__":
    main()
