#!/usr/bin/env python
"""Simulations of UR5 and Panda: compiled (generated) against rrt-pin's Pinocchio backend and SciPy.

The scene: 15 s under PD plus gravity compensation from an offset, q0 = qf + 0.3 rad
(0.01 m for a slider), outputs every 10 ms, gains critically damped at 10 rad/s on
the diagonal of M(qf): kp_k = 100·M_kk, kd_k = 20·M_kk (an engineer's scaling: every
joint answers alike, however light its link).

Every side solves the same problem, the law alone (rrt-pin's runs with
``effort_limits=False, position_limits=False, losses=False``, as the SciPy loop);
``--physical`` gives rrt-pin's sides the robot's limits and losses instead (its
default), and the SciPy loop then solves another problem (its ratio is not at matched
accuracy: Panda's wrists saturate).

The reference is the compiled DOP853 at rtol 1e-13 (checked against SciPy's DOP853
with ``pin.aba`` at the same tolerance). Each side then runs at the loosest rtol of
1e-6 … 1e-13 in half decades (atol = rtol/100) whose max |q error| over the run is at
most the target (--accuracy, default 1e-8), and the sides are timed interleaved in ONE
run (medians):

* compiled        ``rrt_pin.simulate(robot, ..., backend="compiled")``, DOP853, no estimate;
* adams           the same with ``method="adams"`` (Shampine and Gordon's variable-order
                  Adams, outputs interpolated);
* bdf             the same with ``method="BDF"`` (SciPy's BDF step for step, the loop's
                  generated Jacobian: implicit, for the stiff tail of the scene);
* dop853-rkc      the same with ``method="DOP853-RKC"`` (DOP853 handing over to
                  Runge–Kutta–Chebyshev in the stiff tail);
* pinocchio       the same on rrt-pin's Pinocchio backend (odepack, its default method);
* scipy loop      a hand-written ``solve_ivp(DOP853)`` over ``pin.aba`` and
                  ``pin.computeGeneralizedGravity`` (what a user writes without rrt-pin);
* batch final     ``simulate_batch(..., keep="final", threads=1)`` of --batch variants (q0
                  spread by ±0.05 rad) at the rtol meeting a tenth of the accuracy on the
                  scene's run and three of the variants, as simulations a second on one core;
* batch metrics   the same with ``keep="metrics"``;
* the two batches again with DOP853-RKC (at its own loosest rtol meeting the same);
* bare            DOP853-RKC's and BDF's compiled runs alone (``robot_runs.run_one`` with
                  the output times t0 and tf only, at the same rtol, the law alone): no
                  front door, no outputs, the ceiling of a single run's ratio.

    .venv/bin/python -m scripts.bench.robot_sim [--robots ur5,panda] [--repeat 5] [--batch 200]
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
import pinocchio as pin

import rrt_pin
from rrt_pin.robot import robots
from rrt_pin.simulate.control import pd_gravity_controller
from scripts.bench.common import interleaved, verdict

#: The compiled single runs also timed bare (``robot_runs.run_one`` from t0 to tf only).
BARE = {"dop853-rkc": "DOP853-RKC", "bdf": "BDF"}
LADDER = [10.0 ** (-k / 2) for k in range(12, 27)]  # 1e-6 … 1e-13 in half decades
TF = 15.0


def scene(name: str):
    robot = robots.get(name)
    model = robot.model
    qf = np.zeros(robot.nv)
    if name == "ur5":
        qf = np.array([0.0, -1.2, 1.2, -1.0, -1.2, 0.0])
    elif name == "panda":
        qf = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.8, 0.02, 0.02])
    M = pin.crba(model, model.createData(), robot.configuration(qf))
    diag = np.diag(M)
    law = pd_gravity_controller(robot, kp=100.0 * diag, kd=20.0 * diag, qf=qf)
    q0 = qf + np.array([0.01 if u == "m" else 0.3 for u in robot.coordinate_units])
    return robot, law, q0, qf


def scipy_loop(robot, law, q0, t, rtol):
    from scipy.integrate import solve_ivp

    model, data = robot.model, robot.model.createData()
    kp, kd, qf = np.array(law.kp), np.array(law.kd), np.array(law.qf)
    nv = robot.nv
    config = robot.configuration

    def f(_t, y):
        q, v = y[:nv], y[nv:]
        c = config(q)
        tau = -kd * v - kp * (q - qf) + pin.computeGeneralizedGravity(model, data, c)
        return np.concatenate([v, pin.aba(model, data, c, v, tau)])

    y0 = np.concatenate([q0, np.zeros(nv)])
    s = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", t_eval=t, rtol=rtol, atol=rtol / 100)
    return s.y[:nv].T


#: rrt-pin's runs: the law alone (as the SciPy loop), unless --physical.
LAW_ONLY = {"effort_limits": False, "position_limits": False, "losses": False}
PHYSICS = dict(LAW_ONLY)


def run(robot, law, q0, t, backend, rtol, method=None):
    return rrt_pin.simulate(robot, law, q0, None, t, backend=backend, method=method, rtol=rtol,
                            atol=rtol / 100, estimate_error=False, **PHYSICS)  # fmt: skip


def loosest(side, reference, accuracy):
    for rtol in LADDER:
        err = np.abs(side(rtol) - reference).max()
        if err <= accuracy:
            return rtol, err
    return LADDER[-1], err


def bench(name: str, args: argparse.Namespace, t: np.ndarray) -> None:
    """One robot's table."""
    robot, law, q0, qf = scene(name)
    rrt_pin.simulate(robot, law, q0, None, t[:3], backend="compiled", estimate_error=False,
                     **PHYSICS)  # fmt: skip
    reference = run(robot, law, q0, t, "compiled", 1e-13, "DOP853").q
    check = scipy_loop(robot, law, q0, t, 1e-13)
    print(f"\n{name}: nv={robot.nv}, 15 s, reference compiled DOP853 rtol 1e-13; "
          f"SciPy's at 1e-13 differs by {np.abs(check - reference).max():.1e}")  # fmt: skip
    sides = {
        "compiled": lambda r: run(robot, law, q0, t, "compiled", r, "DOP853").q,
        "adams": lambda r: run(robot, law, q0, t, "compiled", r, "adams").q,
        "bdf": lambda r: run(robot, law, q0, t, "compiled", r, "BDF").q,
        "dop853-rkc": lambda r: run(robot, law, q0, t, "compiled", r, "DOP853-RKC").q,
        "pinocchio": lambda r: run(robot, law, q0, t, "pinocchio", r).q,
        "scipy loop": lambda r: scipy_loop(robot, law, q0, t, r),
    }
    chosen = {}
    evals = {"compiled": "DOP853", "adams": "adams", "bdf": "BDF", "dop853-rkc": "DOP853-RKC",
             "pinocchio": None}  # fmt: skip
    for side, f in sides.items():
        rtol, err = loosest(f, reference, args.accuracy)
        chosen[side] = rtol
        if side in evals:
            backend = "pinocchio" if side == "pinocchio" else "compiled"
            evals[side] = (
                f", {run(robot, law, q0, t, backend, rtol, evals[side]).n_evals} evaluations"
            )
        print(f"  {side:<12} rtol {rtol:.2g}: max |q error| {err:.1e}{evals.get(side, '')}")
    B = args.batch
    rng = np.random.default_rng(1)
    q0s = q0 + rng.uniform(-0.05, 0.05, (B, robot.nv))
    batch_accuracy = args.accuracy / 10
    # the batch's rtol meets the accuracy on the scene's run and three of its variants
    checked = np.vstack([q0, q0s[[0, B // 2, B - 1]]])

    def rows_of(rtol, method):
        return rrt_pin.simulate_batch(
            robot, law, checked, None, t, backend="compiled", method=method, rtol=rtol,
            atol=rtol / 100, estimate_error=False, threads=1, **PHYSICS,
        ).q  # fmt: skip

    references = rows_of(1e-13, "DOP853")
    final = {}
    for method in ("DOP853", "DOP853-RKC"):
        for keep, rows in (("final", slice(-1, None)), ("metrics", slice(None))):
            r, err = loosest(
                lambda r, rows=rows, method=method: rows_of(r, method)[:, rows],
                references[:, rows], batch_accuracy,
            )  # fmt: skip
            final[keep, method] = r
            print(f"  batch {keep:<8}{method:<11} rtol {r:.2g}: max |q error| {err:.1e} "
                  f"({'the final state' if keep == 'final' else 'every output time'} of the "
                  f"scene and 3 variants, target {batch_accuracy:.0e})")  # fmt: skip

    def batch(keep, method="DOP853"):
        r = final[keep, method]
        return lambda: rrt_pin.simulate_batch(
            robot, law, q0s, None, t, backend="compiled", keep=keep, threads=1, method=method,
            rtol=r, atol=r / 100, estimate_error=False, **PHYSICS,
        )  # fmt: skip

    timed = {s: (lambda s=s: sides[s](chosen[s])) for s in sides}
    ends = t[[0, -1]]

    def bare(side: str, method: str):
        """The compiled run alone: two output times, no front door (the law alone)."""
        from rrt_pin.compiled import robot_runs
        from rrt_pin.simulate.options import resolve

        r = chosen[side]
        options = resolve(ends, backend="compiled", method=method, rtol=r, atol=r / 100)
        return lambda: robot_runs.run_one(robot, law, q0, np.zeros(robot.nv), ends, options)

    for side, method in BARE.items():
        timed[f"bare {side}"] = bare(side, method)
    timed["batch final"] = batch("final")
    timed["batch metrics"] = batch("metrics")
    timed["batch final rkc"] = batch("final", "DOP853-RKC")
    timed["batch metrics rkc"] = batch("metrics", "DOP853-RKC")
    start = time.perf_counter()
    med = interleaved(
        timed, args.repeat, inner=3
    )  # steady state: the side before leaves caches cold
    for side in sides:
        print(f"  {side:<12} {med[side] * 1e3:9.2f} ms")
    for keep in ("final", "metrics"):
        for suffix, method in (("", "DOP853"), (" rkc", "DOP853-RKC")):
            rate = B / med[f"batch {keep}{suffix}"]
            print(f"  batch {keep:<7} {method:<11} {rate:9.0f} simulations/s on one core "
                  f"({B} variants)")  # fmt: skip
    for single in ("compiled", "adams", "bdf", "dop853-rkc"):
        fast = med[single]
        r_pin, r_scipy = med["pinocchio"] / fast, med["scipy loop"] / fast
        print(f"  {single}: {r_pin:.1f}x rrt-pin's Pinocchio backend (target 25x: "
              f"{verdict(r_pin >= 25)}), {r_scipy:.1f}x the SciPy loop (target 100x: "
              f"{verdict(r_scipy >= 100)})")  # fmt: skip
    for side in BARE:
        r_pin = med["pinocchio"] / med[f"bare {side}"]
        print(f"  bare {side}: {med[f'bare {side}'] * 1e3:.2f} ms, {r_pin:.1f}x rrt-pin's Pinocchio "
              "backend: the integration alone (two output times, no front door), a single "
              "run's ceiling")  # fmt: skip
    target = 3000 if name == "ur5" else 1500
    for suffix, method in (("", "DOP853"), (" rkc", "DOP853-RKC")):
        rate = min(B / med[f"batch metrics{suffix}"], B / med[f"batch final{suffix}"])
        print(f"  batch {method}: {rate:.0f}/s/core, the slower of final and metrics "
              f"(target {target}: {verdict(rate >= target)})")  # fmt: skip
    print(f"  timed in {time.perf_counter() - start:.0f} s")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", default="ur5,panda")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--batch", type=int, default=200)
    ap.add_argument("--accuracy", type=float, default=1e-8)
    ap.add_argument("--physical", action="store_true", help="rrt-pin's runs with the limits")
    args = ap.parse_args(argv)
    if args.physical:
        PHYSICS.clear()
    t = np.arange(0.0, TF + 1e-9, 0.01)
    for name in args.robots.split(","):
        bench(name, args, t)
    return 0


if __name__ == "__main__":
    sys.exit(main())
