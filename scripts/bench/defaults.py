#!/usr/bin/env python3
"""Defaults against what a user would write: ``simulate`` and ``inverse_dynamics`` as called plainly.

**Simulations.** For the chapter's run (eq. (31), 15 s) and UR5 and Panda (5 s under PD +
gravity from 0.3 rad off, the scene of ``scripts/bench/robot_sim.py``; the loop applies
the URDF's damping, friction and effort limits, as rrt-pin does by default; position
limits are off on both sides, as a finger of Panda touches its stop): the default
``simulate`` (accuracy 1e-8, its error estimate included) on the Pinocchio backend and
on the default backend (``auto``: compiled once its code is loaded), against a SciPy
DOP853 + ``pin.aba`` loop at the loosest rtol (a ladder of half decades) that keeps max
|q error| ≤ 1e-8 against a reference (compiled DOP853 at rtol 1e-13). Interleaved
medians; ratios are the loop's time over each.

**Inverse dynamics**, in a fresh process per robot (the compiled code built beforehand,
ahead of time where it can be): the default ``inverse_dynamics`` of 15,001 samples (its
first call, the module's load included, and the median of the next calls) against a
``pin.rnea`` loop over the same samples in the same process. Calls are timed back to
back, the first of each round not counted (as :func:`scripts.bench.common.interleaved`
does): a sub-millisecond call right after the loop or a pause runs 2–4× slower
(caches, the CPU's clock), which would measure the machine, not the kernel.

**Bounds** (``--bounds``): what a default could reach at best on each scene. Every side
runs at the loosest rtol of the ladder that meets 1e-8 on that very scene (a tolerance
only an oracle knows beforehand: the defaults must meet the accuracy on every problem of
the catalogue) and with no estimate at all; the ratios are the ceilings of the defaults'
targets on each backend.

    .venv/bin/python -m scripts.bench.defaults [--repeat 7] [--markdown] [--bounds]
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np
import pinocchio as pin

import rrt_pin
from rrt_pin.robot import robots
from rrt_pin.simulate.control import chapter_controller
from scripts.bench.common import interleaved, verdict
from scripts.bench.robot_sim import scene

ACCURACY = 1e-8
LADDER = [10.0 ** (-k / 2) for k in range(6, 27)]  # 1e-3 … 1e-13
#: Targets of the default (its estimate included) over the matched SciPy loop.
TARGETS = {"pinocchio": 3.0, "default": 60.0, "robot": 8.0}


def _arm_scene() -> tuple:
    arm = robots.chapter_arm()
    p = arm.params
    return arm, chapter_controller(p), np.array([p.q10, p.q20, p.q30])


def _arm_loop(robot, law, q0, t, rtol):
    from scipy.integrate import solve_ivp

    model, data = robot.model, robot.model.createData()

    def f(tt, y):
        q, v = y[:3], y[3:]
        return np.concatenate([v, pin.aba(model, data, q, v, law.efforts(tt, q, v))])

    y0 = np.concatenate([q0, np.zeros(3)])
    s = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", t_eval=t, rtol=rtol, atol=rtol / 100)
    return s.y[:3].T


def robot_loop(robot, law, q0, t, rtol):
    """PD + gravity with the URDF's damping, friction and effort limits, as rrt-pin's default."""
    from scipy.integrate import solve_ivp

    model, data = robot.model, robot.model.createData()
    kp, kd, qf = np.array(law.kp), np.array(law.kd), np.array(law.qf)
    damping, friction = np.array(model.damping), np.array(model.friction)
    limit = np.where(np.array(model.effortLimit) > 0, np.array(model.effortLimit), np.inf)
    nv = robot.nv

    def f(_t, y):
        q, v = y[:nv], y[nv:]
        c = robot.configuration(q)
        tau = -kd * v - kp * (q - qf) + pin.computeGeneralizedGravity(model, data, c)
        tau = np.clip(tau, -limit, limit) - damping * v - friction * np.tanh(v / 1e-3)
        return np.concatenate([v, pin.aba(model, data, c, v, tau)])

    y0 = np.concatenate([q0, np.zeros(nv)])
    s = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", t_eval=t, rtol=rtol, atol=rtol / 100)
    return s.y[:nv].T


def _loosest(side, reference):
    for rtol in LADDER:
        err = float(np.abs(side(rtol) - reference).max())
        if err <= ACCURACY:
            return rtol, err
    return LADDER[-1], err


def simulations(repeat: int) -> list[dict]:
    return [_scene_row(name, repeat) for name in ("chapter", "ur5", "panda")]


def _scene(name: str) -> tuple:
    """(robot, law, q0, output times, the SciPy loop, the reference q) of a scene.

    The compiled code is loaded (compiled once if needed) here, before any timing.
    Panda's finger touches its stop: the loop has no compliant limits, so neither side
    does (``position_limits=False`` for the reference and every rrt-pin side).
    """
    if name == "chapter":
        robot, law, q0 = _arm_scene()
        t, loop = rrt_pin.time_grid(15.0, 0.01), _arm_loop
    else:
        robot, law, q0, _ = scene(name)
        t, loop = rrt_pin.time_grid(5.0, 0.01), robot_loop
    rrt_pin.simulate(robot, law, q0, None, t[:3], backend="compiled", estimate_error=False)
    reference = rrt_pin.simulate(robot, law, q0, None, t, backend="compiled", method="DOP853",
                                 rtol=1e-13, atol=1e-15, estimate_error=False,
                                 position_limits=False).q  # fmt: skip
    return robot, law, q0, t, loop, reference


def _scene_row(name: str, repeat: int) -> dict:
    robot, law, q0, t, loop, reference = _scene(name)
    kw = {"position_limits": False}  # as the reference (see _scene)
    rtol, loop_err = _loosest(lambda r: loop(robot, law, q0, t, r), reference)
    runs = {
        "loop": lambda: loop(robot, law, q0, t, rtol),
        "pinocchio": lambda: rrt_pin.simulate(robot, law, q0, None, t, backend="pinocchio", **kw),
        "default": lambda: rrt_pin.simulate(robot, law, q0, None, t, **kw),
        "default, no estimate": lambda: rrt_pin.simulate(
            robot, law, q0, None, t, estimate_error=False, **kw
        ),
    }
    default = runs["default"]()
    pin_run = runs["pinocchio"]()
    med = interleaved(runs, repeat, inner=1)
    return {
        "scene": name, "loop_rtol": rtol, "loop_err": loop_err,
        "backend": default.backend, "method": default.method,
        "err_default": float(np.abs(default.q - reference).max()),
        "err_pinocchio": float(np.abs(pin_run.q - reference).max()),
        "estimate": float(default.error_estimate),
        **{f"t_{k}": v for k, v in med.items()},
    }  # fmt: skip


_INVERSE = """
import json, logging, sys, time
import numpy as np
import pinocchio as pin
from rrt_pin.robot import robots
from rrt_pin.dynamics.inverse import inverse_dynamics
chose = []
class Seen(logging.Handler):
    def emit(self, record):
        chose.append(record.getMessage())
log = logging.getLogger("rrt_pin"); log.setLevel(logging.INFO); log.addHandler(Seen())
robot = robots.get(sys.argv[1])
model, data = robot.model, robot.model.createData()
rng = np.random.default_rng(0)
q, qd, qdd = (rng.uniform(-1.0, 1.0, (15001, robot.nv)) for _ in range(3))
x = robot.configuration(q)
start = time.perf_counter(); tau = inverse_dynamics(robot, q, qd, qdd)
first = time.perf_counter() - start
calls, loops = [], []
for _ in range(int(sys.argv[2])):
    for k in range(3):  # back to back, the first not counted (common.interleaved's rule)
        start = time.perf_counter(); inverse_dynamics(robot, q, qd, qdd)
        if k:
            calls.append(time.perf_counter() - start)
    start = time.perf_counter()
    ref = np.array([pin.rnea(model, data, x[i], qd[i], qdd[i]) for i in range(len(q))])
    loops.append(time.perf_counter() - start)
print(json.dumps({
    "first": first, "call": float(np.median(calls)), "loop": float(np.median(loops)),
    "worst": float(np.max(np.abs(tau - ref) / (1.0 + np.abs(ref)))),
    "chose": [m for m in chose if "chose" in m], "numba": "numba" in sys.modules,
}))
"""


def inverses(repeat: int) -> list[dict]:
    rows = []
    env = {k: v for k, v in os.environ.items() if k != "RRT_PIN_BACKEND"}
    for name in ("rrt", "ur5", "panda"):
        robot = robots.get(name)
        z = np.zeros((4, robot.nv))
        rrt_pin.inverse_dynamics(robot, z, z, z, backend="compiled")  # built (ahead of time)
        out = subprocess.run(
            [sys.executable, "-c", _INVERSE, name, str(repeat)],
            capture_output=True, text=True, env=env, check=True,
        ).stdout  # fmt: skip
        rows.append({"robot": name, **json.loads(out.strip().splitlines()[-1])})
    return rows


def bounds(repeat: int) -> None:
    """Each backend's method at its loosest rtol meeting 1e-8 on the scene, no estimate."""
    print("| scene | side | loosest rtol meeting 1e-8 (error) | time | SciPy loop ÷ side |")
    print("| --- | --- | --- | ---: | ---: |")
    for name in ("chapter", "ur5", "panda"):
        for line in _bound_rows(name, repeat):
            print(line)


def _bound_rows(name: str, repeat: int) -> list[str]:
    robot, law, q0, t, loop, reference = _scene(name)
    kw = {"position_limits": False, "estimate_error": False}  # as the reference

    def side(backend, method):
        return lambda r: rrt_pin.simulate(robot, law, q0, None, t, backend=backend,
                                          method=method, rtol=r, atol=r / 100, **kw).q  # fmt: skip

    sides = {
        "SciPy DOP853 loop": lambda r: loop(robot, law, q0, t, r),
        "Pinocchio backend, odepack": side("pinocchio", "odepack"),
        "compiled backend, DOP853": side("compiled", "DOP853"),
    }
    chosen = {k: _loosest(f, reference) for k, f in sides.items()}
    med = interleaved({k: (lambda k=k: sides[k](chosen[k][0])) for k in sides}, repeat, inner=1)
    base = med["SciPy DOP853 loop"]
    return [f"| {name} | {k} | {chosen[k][0]:.2g} ({chosen[k][1]:.1e}) | {med[k] * 1e3:.3f} ms | "
            f"{base / med[k]:.1f}× |" for k in sides]  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=7, help="interleaved rounds (medians)")
    ap.add_argument("--markdown", action="store_true", help="print the tables as markdown")
    ap.add_argument("--bounds", action="store_true",
                    help="only the ceilings: each side at the scene's own loosest rtol, no estimate")  # fmt: skip
    args = ap.parse_args(argv)
    os.environ.pop("RRT_PIN_BACKEND", None)
    start = time.perf_counter()
    if args.bounds:
        bounds(args.repeat)
        print(f"\ntimed in {time.perf_counter() - start:.0f} s")
        return 0
    sims = simulations(args.repeat)
    inv = inverses(max(5, args.repeat))
    print(
        "| scene | matched SciPy loop (rtol, error) | default: backend, method | default "
        "error (estimate) | loop | Pinocchio default | × loop | default | × loop | "
        "default without its estimate |"
    )
    print("| --- | --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |")
    for r in sims:
        ratio_pin = r["t_loop"] / r["t_pinocchio"]
        ratio_def = r["t_loop"] / r["t_default"]
        target = TARGETS["default"] if r["scene"] == "chapter" else TARGETS["robot"]
        print(f"| {r['scene']} | {r['loop_rtol']:.1e}, {r['loop_err']:.1e} | {r['backend']}, "
              f"{r['method']} | {r['err_default']:.1e} ({r['estimate']:.1e}) | "
              f"{r['t_loop'] * 1e3:.2f} ms | {r['t_pinocchio'] * 1e3:.2f} ms | {ratio_pin:.1f}× | "
              f"{r['t_default'] * 1e3:.3f} ms | **{ratio_def:.1f}×** "
              f"({verdict(ratio_def >= target)} {target:g}×) | "
              f"{r['t_loop'] / r['t_default, no estimate']:.1f}× |")  # fmt: skip
    print()
    print(
        "| robot | default chose | first call | later calls | `pin.rnea` loop | × loop "
        "(later) | × loop (first) | worst relative difference | numba imported |"
    )
    print("| --- | --- | ---: | ---: | ---: | ---: | ---: | ---: | --- |")
    for r in inv:
        target = 50.0 if r["robot"] == "rrt" else 10.0
        ratio = r["loop"] / r["call"]
        chose = r["chose"][0].split("chose ")[-1] if r["chose"] else "?"
        print(f"| {r['robot']} | {chose} | {r['first'] * 1e3:.2f} ms | {r['call'] * 1e3:.3f} ms | "
              f"{r['loop'] * 1e3:.1f} ms | **{ratio:.0f}×** ({verdict(ratio >= target)} "
              f"{target:g}×) | {r['loop'] / r['first']:.1f}× | {r['worst']:.0e} | "
              f"{'yes' if r['numba'] else 'no'} |")  # fmt: skip
    print(f"\ntimed in {time.perf_counter() - start:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
