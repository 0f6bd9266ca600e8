#!/usr/bin/env python
"""The physical model's cost on a run that hits no limit: with it against without it.

The scene is :mod:`scripts.bench.robot_sim`'s (targets, gains critically damped at
10 rad/s): 15 s under PD plus gravity compensation from an offset, q0 = qf + 0.3 rad
for UR5 and 0.1 rad for Panda (a slider a thirtieth of that in metres; from 0.3 rad
Panda's arm flings its fingers past their limits), outputs every 10 ms, DOP853 at
rtol 1e-10 (atol rtol/100), no error estimate. Each run is timed with and without
the model, interleaved in ONE process (medians of --repeat rounds, each of as many
calls as take ~0.2 s):

* with     the URDF's physical model, the default (effort limits, compliant position
           limits, damping and friction);
* without  ``effort_limits=False, position_limits=False, losses=False``.

Both sides measure what the run crossed against the stated limits (that is not the
feature's cost). Per robot and backend (``pinocchio``, ``compiled``): one run, and a
``simulate_batch`` of --batch variants (q0 spread by ±a sixth of the offset: ±0.05 rad
for UR5; ``threads=--threads``).
Every run is checked to cross no limit. A URDF's damping changes the motion (Panda's
fingers: 0.3 N·s/m), so the evaluation counts are printed too, and the ratio per
right-hand-side evaluation beside the ratio of times.

    .venv/bin/python -m scripts.bench.physical_cost [--robots ur5,panda] [--repeat 7]
        [--batch 64] [--threads 1] [--backends pinocchio,compiled]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np

import rrt_pin
from scripts.bench.common import interleaved, verdict
from scripts.bench.robot_sim import scene

TF = 15.0
RTOL = 1e-10
#: The cost target: a run that hits no limit takes at most this times its time without.
TARGET = 1.2
OFF = {"effort_limits": False, "position_limits": False, "losses": False}
#: The start's offset from the target per robot [rad] (a slider's: a thirtieth [m]).
OFFSET = {"ur5": 0.3, "panda": 0.1}


def single(robot, law, q0, t, backend: str, on: bool):
    switches = {} if on else OFF
    return rrt_pin.simulate(robot, law, q0, None, t, backend=backend, method="DOP853",
                            rtol=RTOL, atol=RTOL / 100, estimate_error=False,
                            **switches)  # fmt: skip


def batch(robot, law, q0s, t, backend: str, on: bool, threads: int):
    switches = {} if on else OFF
    return rrt_pin.simulate_batch(robot, law, q0s, None, t, backend=backend, method="DOP853",
                                  rtol=RTOL, atol=RTOL / 100, estimate_error=False,
                                  threads=threads, **switches)  # fmt: skip


def crossed(result) -> list:
    """The limit events of a run or a batch (each variant's, flattened)."""
    events = result.limits or ()
    if events and isinstance(events[0], tuple):
        return [e for variant in events for e in variant]
    return list(events)


def bench(name: str, args: argparse.Namespace, t: np.ndarray) -> list[tuple]:
    """One robot's rows: (robot, backend, kind, evals with, evals without, ratio, per eval)."""
    robot, law, _, qf = scene(name)
    offset = np.array([1 / 30 if u == "m" else 1.0 for u in robot.coordinate_units])
    offset *= OFFSET.get(name, 0.3)
    q0 = qf + offset
    rng = np.random.default_rng(1)
    q0s = q0 + offset * rng.uniform(-1 / 6, 1 / 6, (args.batch, robot.nv))
    rows = []
    for backend in args.backends:
        for kind in ("single", f"batch {args.batch}"):
            if kind == "single":

                def side(on: bool, backend=backend):
                    return single(robot, law, q0, t, backend, on)
            else:

                def side(on: bool, backend=backend):
                    return batch(robot, law, q0s, t, backend, on, args.threads)

            runs = {on: side(on) for on in (True, False)}  # warm-up, compilation, checks
            for on, r in runs.items():
                if crossed(r):
                    first = crossed(r)[0]
                    print(f"  {name} {backend} {kind} ({'with' if on else 'without'}): crossed "
                          f"{first.kind} of {first.joint} at {first.first_time:g} s: not a run "
                          "that hits no limit", file=sys.stderr)  # fmt: skip
            diff = float(np.abs(runs[True].q - runs[False].q).max())
            began = time.perf_counter()
            side(False)
            inner = max(1, min(20, int(0.2 / (time.perf_counter() - began))))  # ~0.2 s a round
            times = interleaved({"with": lambda: side(True), "without": lambda: side(False)},
                                repeat=args.repeat, inner=inner)  # fmt: skip
            ev_on, ev_off = runs[True].n_evals, runs[False].n_evals
            ratio = times["with"] / times["without"]
            per_eval = ratio * ev_off / ev_on
            rows.append((name, backend, kind, times["with"], times["without"], ev_on, ev_off,
                         ratio, per_eval, diff))  # fmt: skip
            print(f"  {name:<6} {backend:<10} {kind:<9} with {times['with'] * 1e3:8.1f} ms "
                  f"({ev_on} evals), without {times['without'] * 1e3:8.1f} ms ({ev_off} evals): "
                  f"{ratio:.2f}x, {per_eval:.2f}x a evaluation; max |q with - q without| "
                  f"{diff:.1e}", flush=True)  # fmt: skip
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robots", default="ur5,panda", help="comma-separated robots")
    parser.add_argument("--backends", default="pinocchio,compiled", help="comma-separated")
    parser.add_argument("--repeat", type=int, default=7, help="interleaved rounds (medians)")
    parser.add_argument("--batch", type=int, default=64, help="variants of the batch runs")
    parser.add_argument("--threads", type=int, default=1, help="threads of the batch runs")
    args = parser.parse_args(argv)
    args.backends = args.backends.split(",")
    t = rrt_pin.time_grid(TF, 0.01)
    print(f"physical model on a run that hits no limit: {TF:g} s, DOP853 rtol {RTOL:g}, "
          f"{args.repeat} interleaved rounds, batches of {args.batch} on {args.threads} "
          "thread(s)")  # fmt: skip
    rows = []
    for name in args.robots.split(","):
        rows += bench(name, args, t)
    print(f"\n| robot | backend | run | with / without | a evaluation | ≤ {TARGET}× |")
    print("|---|---|---|---:|---:|---|")
    for name, backend, kind, *_, ratio, per_eval, _diff in rows:
        print(f"| {name} | {backend} | {kind} | {ratio:.2f}× | {per_eval:.2f}× | "
              f"{verdict(ratio <= TARGET)} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
