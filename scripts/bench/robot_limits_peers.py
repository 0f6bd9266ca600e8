#!/usr/bin/env python
"""Passive UR5 and Panda at their joint limits: rrt-pin against MuJoCo with the URDF's limits.

Scenes: no controller (zero efforts, no gravity compensation), released at rest,
outputs every 1 ms:

* ur5   q0 = (0, −1, 1, 0.3, 0.5, 0) rad for 1.5 s (``--tf``): wrist 1 reaches its −2π
        limit at ~1.12 s, the elbow its +π at ~1.23 s;
* panda q0 = (0, 0.5, 0, −1.5, 0, 1.5, 0.7, 0.02, 0.02) for 1.5 s: joint 2 reaches its
        +1.7628 rad limit at ~0.34 s, then the fingers and other joints theirs;
* and each "before any limit" (ur5 1.1 s, panda 0.3 s): there the two models are the same
  equations (Panda's joints damped, 0.003 N·m·s/rad and 0.3 N·s/m on its fingers; UR5's
  URDF states no damping), so the runs must agree to the integrators' accuracy.

MuJoCo's model is :func:`scripts.bench.robot_peers.mujoco_spec` (the URDF without meshes
or mimic), then per joint the URDF's values as rrt-pin reads them
(:func:`rrt_pin.robot.limits.physical_model`): ``limited`` with ``range`` = [lower, upper]
(none for a continuous joint or a zero range), ``damping``, ``frictionloss`` = the URDF's
friction (0 in both URDFs: rrt-pin's regularised Coulomb friction and MuJoCo's
frictionloss then both vanish), armature 0, ``actfrclimited`` with ``actfrcrange`` =
±effort (the importer's default; no actuator acts in a passive run, on either side);
contacts off, the constraint stage on; RK4.

The limit models differ. rrt-pin's is a spring–damper that only pushes back, τ =
k·(lower − q) − b·q̇ with k = m·ω², b = 2·m·ω, ω = 200 rad/s, m = 1/(M⁻¹)_kk(q0)
(:mod:`rrt_pin.robot.limits`), added to the joint's other efforts. MuJoCo's is a soft
constraint whose limited joint accelerates as a₁ = (1 − d)·a₀ − d·(b·ṙ + k·r) with b =
2/(dmax·timeconst), k = d/(dmax²·timeconst²·dampratio²). "MuJoCo matched" sets solref =
(1/ω, 1) = (5 ms, critically damped) and solimp = (0.9999, 0.9999, 0.001, 0.5, 2): the
impedance d at its maximum everywhere, so a₁ ≈ −ω²·r − 2ω·ṙ, the same reference as
rrt-pin's per unit of effective inertia. What still differs: MuJoCo's acts through
1/(M⁻¹)_kk at the current state and replaces the free acceleration a₀ (gravity's push is
cancelled but for 1e-4 of it), rrt-pin's acts through 1/(M⁻¹)_kk at q0 and adds to a₀ (gravity
keeps a steady penetration a₀/ω²). "MuJoCo default" keeps the importer's solref (0.02,
1) and solimp (0.9, 0.95, 0.001, 0.5, 2), what a MuJoCo user gets.

Accuracy: the reference is rrt-pin's Pinocchio backend with DOP853 at rtol 1e-12 (atol
1e-14; neither side's default method); the rrt-pin sides run
``rrt_pin.simulate.simulate(robot, None, …)`` at their defaults (accuracy 1e-8: odepack on
Pinocchio, DOP853 compiled; no error estimate, which would double the cost). MuJoCo's RK4
gets two steps: the largest of 1 ms … 10 µs (dividing the 1 ms outputs) whose run before
any limit is within --accuracy (1e-8) of the reference, and --limit-step (0.1 ms) for the
runs at the limits, where RK4 falls to first order (the constraint switches on inside a
step: its crossings are printed against a step four times shorter).

Reported: the URDF's values against MuJoCo's importer; max |Δq| before any limit; then, per
side, the position limits crossed (first crossing, linearly interpolated between the 1 ms
samples; deepest penetration; crossings), and max |Δq| from rrt-pin's Pinocchio run up to
the first crossing and over the run (a passive arm is chaotic: after the first impact the
runs part). Timed interleaved in one run (medians, one core each): the rrt-pin sides and
MuJoCo matched at both steps, whole limit runs; ratios MuJoCo ÷ rrt-pin.

    .venv/bin/python -m scripts.bench.robot_limits_peers [--robots ur5,panda] [--repeat 5]
        [--tf 1.5] [--accuracy 1e-8] [--markdown]
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from dataclasses import dataclass

import numpy as np

from scripts.bench.common import interleaved, verdict
from scripts.bench.robot_peers import mujoco_compile, mujoco_spec, require, rollout_runner

DT_OUT = 1e-3  # [s]
# RK4 steps [s] dividing the 1 ms outputs, largest first
STEPS = [1e-3, 5e-4, 2.5e-4, 2e-4, 1e-4, 5e-5, 2.5e-5, 2e-5, 1e-5]
SCENES = {
    "ur5": (np.array([0.0, -1.0, 1.0, 0.3, 0.5, 0.0]), 1.1),
    "panda": (np.array([0.0, 0.5, 0.0, -1.5, 0.0, 1.5, 0.7, 0.02, 0.02]), 0.3),
}  # q0 [rad, m], end of the run before any limit [s]
#: MuJoCo's impedance at its maximum everywhere (dmin = dmax < 1, MuJoCo's ceiling 0.9999)
SOLIMP_MATCHED = (0.9999, 0.9999, 0.001, 0.5, 2.0)


@dataclass(frozen=True)
class Crossing:
    """A coordinate past one of its position limits at some output samples."""

    joint: str
    side: str  # "lower" or "upper"
    limit: float  # [rad or m]
    first: float  # first crossing [s], interpolated between samples
    depth: float  # deepest penetration [rad or m]
    count: int  # separate crossings


def crossings(t: np.ndarray, q: np.ndarray, lower, upper, names) -> list[Crossing]:
    """The position limits ``q`` (T, nv) crossed, by first crossing."""
    found = []
    for k, name in enumerate(names):
        for side, limit, past in (("lower", lower[k], lower[k] - q[:, k]),
                                  ("upper", upper[k], q[:, k] - upper[k])):  # fmt: skip
            over = past > 0.0
            if not np.isfinite(limit) or not over.any():
                continue
            i = int(np.argmax(over))
            first = t[i] if i == 0 else t[i - 1] + (t[i] - t[i - 1]) * -past[i - 1] / (
                past[i] - past[i - 1])  # fmt: skip
            count = int(over[0]) + int(np.count_nonzero(over[1:] & ~over[:-1]))
            found.append(Crossing(name, side, float(limit), float(first), float(past.max()), count))
    return sorted(found, key=lambda c: c.first)


# --------------------------------------------------------------------------------------------
# the two models
# --------------------------------------------------------------------------------------------
def mujoco_limits_model(name: str, stated, dt: float, solref=None, solimp=None):
    """MuJoCo's model of robot ``name`` with the URDF's limits, damping, friction (``stated``).

    ``solref``, ``solimp``: the position limits' (None: the importer's).
    Returns the model and the importer's values (range, damping, frictionloss, actfrcrange).
    """
    import mujoco

    spec, joints = mujoco_spec(name)
    imported = {
        "lower": np.array([j.range[0] if j.limited != mujoco.mjtLimited.mjLIMITED_FALSE
                           else -np.inf for j in joints]),
        "upper": np.array([j.range[1] if j.limited != mujoco.mjtLimited.mjLIMITED_FALSE
                           else np.inf for j in joints]),
        "damping": np.array([np.asarray(j.damping, dtype=float)[0] for j in joints]),
        "friction": np.array([j.frictionloss for j in joints]),
        "effort": np.array([j.actfrcrange[1] for j in joints]),
    }  # fmt: skip
    on, off = mujoco.mjtLimited.mjLIMITED_TRUE, mujoco.mjtLimited.mjLIMITED_FALSE
    for k, j in enumerate(joints):
        lo, hi = stated.lower[k], stated.upper[k]
        if np.isfinite(lo) or np.isfinite(hi):
            j.limited = on
            j.range = [lo if np.isfinite(lo) else -1e10, hi if np.isfinite(hi) else 1e10]
        else:
            j.limited = off
        damping = np.zeros_like(np.asarray(j.damping, dtype=float))
        damping[0] = stated.damping[k]
        j.damping = damping
        j.frictionloss = float(stated.friction[k])
        j.armature = 0.0
        if np.isfinite(stated.effort[k]):
            j.actfrclimited = on
            j.actfrcrange = [-stated.effort[k], stated.effort[k]]
        else:
            j.actfrclimited = off
        if solref is not None:
            j.solref_limit = list(solref)
        if solimp is not None:
            j.solimp_limit = list(solimp)
    return mujoco_compile(spec, dt, "RK4", constraints=True), imported


def mujoco_run(m, q0: np.ndarray, n_out: int):
    """A call running MuJoCo from rest at ``q0``: q at every 1 ms output (n_out, nv)."""
    run = rollout_runner(m, q0[None], np.zeros(m.nu), n_out, dt_out=DT_OUT)
    return lambda: run()[0]


def rrt_run(robot, q0: np.ndarray, t: np.ndarray, backend: str, **kw):
    """A call of ``rrt_pin.simulate`` (passive, no estimate): q at ``t`` (T, nv)."""
    from rrt_pin.simulate import simulate

    def run() -> np.ndarray:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return simulate(robot, None, q0, None, t, backend=backend, estimate_error=False,
                            **kw).q  # fmt: skip

    return run


def milliseconds(s: float) -> str:
    """A duration [s] in ms, three significant digits, no exponent."""
    ms = s * 1e3
    return f"{ms:,.0f} ms" if ms >= 100 else f"{ms:.3g} ms"


def stiffer(robot, q0: np.ndarray, t: np.ndarray, q: np.ndarray, found: list[Crossing]) -> str:
    """How much stiffer rrt-pin's limit is than MuJoCo matched's at each first crossing.

    rrt-pin's spring (k = m·ω², b = 2·m·ω, m = 1/(M⁻¹)_kk(q0)) on the joint's effective
    inertia 1/(M⁻¹)_kk(q) has the natural frequency ω·√f and the damping ratio √f,
    f = (M⁻¹)_kk(q) / (M⁻¹)_kk(q0).
    """
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    m0 = 1.0 / np.diag(pin.computeMinverse(model, data, robot.configuration(q0))).copy()
    parts = []
    for c in found:
        k = robot.joints[[j.name for j in robot.joints].index(c.joint)].idx_v
        i = int(np.searchsorted(t, c.first))
        minv = pin.computeMinverse(model, data, robot.configuration(q[i]))
        f = m0[k] * float(minv[k, k])
        parts.append(f"{c.joint} sqrt(f) = {np.sqrt(f):.2f}")
    return (
        "rrt-pin's limit against MuJoCo matched's at each first crossing, frequency and "
        "damping ratio × sqrt((M⁻¹)_kk(q) / (M⁻¹)_kk(q0)): " + ", ".join(parts)
    )


# --------------------------------------------------------------------------------------------
# one robot
# --------------------------------------------------------------------------------------------
def bench(name: str, args: argparse.Namespace) -> tuple[list[str], list[str], list[str]]:
    """One robot's checks, crossings and timings; its Markdown rows (no limit, limits, times)."""
    from rrt_pin.robot import robots
    from rrt_pin.robot.limits import LIMIT_OMEGA, joint_names, physical_model

    robot = robots.get(name)
    stated = physical_model(robot)
    names = joint_names(robot)
    units = {n: u for n, u in zip(names, robot.coordinate_units, strict=True)}
    q0, t_free = SCENES[name]
    t = np.arange(0.0, args.tf + 1e-9, DT_OUT)
    tb = t[t <= t_free + 1e-9]
    solref = (1.0 / LIMIT_OMEGA, 1.0)

    def mujoco(h: float, matched: bool = True):
        kw = {"solref": solref, "solimp": SOLIMP_MATCHED} if matched else {}
        m, _ = mujoco_limits_model(name, stated, h, **kw)
        return lambda tt: mujoco_run(m, q0, tt.size)

    # the URDF's values, as rrt-pin reads them and as MuJoCo's importer does
    _, imported = mujoco_limits_model(name, stated, 1e-3)
    diffs = []
    for key in ("lower", "upper", "damping", "friction", "effort"):
        mine = np.asarray(getattr(stated, key), dtype=float)
        same = np.isclose(mine, imported[key], rtol=1e-12, atol=0.0) | (mine == imported[key])
        if not same.all():
            diffs.append(f"{key} {mine[~same]} vs {imported[key][~same]}")
    print(f"\n{name}: nv={robot.nv}, q0 = {np.array2string(q0, separator=', ')}; URDF as read by "
          f"rrt-pin and by MuJoCo's importer: {'the same' if not diffs else '; '.join(diffs)} "
          f"(lower, upper, damping, friction, effort)")  # fmt: skip
    print(f"  damping {stated.damping.tolist()}, friction {stated.friction.tolist()}")

    # the reference: Pinocchio backend, DOP853 (neither side's default method)
    def ref_run(tt: np.ndarray):
        return rrt_run(robot, q0, tt, "pinocchio", method="DOP853", rtol=1e-12, atol=1e-14)

    ref_free, ref = ref_run(tb)(), ref_run(t)()
    found_ref = crossings(t, ref, stated.lower, stated.upper, names)
    first_ref = found_ref[0].first if found_ref else np.inf
    print(f"  reference: rrt-pin pinocchio DOP853 rtol 1e-12; first limit crossed at "
          f"{first_ref:.4f} s; the run before any limit ends at {t_free:g} s")  # fmt: skip

    # MuJoCo's steps: before any limit (accuracy) and at the limits (converged crossings)
    dt = STEPS[-1]
    for h in STEPS:
        e = float(np.abs(mujoco(h)(tb)() - ref_free).max())
        print(f"  MuJoCo RK4 {h * 1e3:g} ms, before any limit: max |q - q_ref| {e:.1e}")
        if e <= args.accuracy:
            dt = h
            break
    dl = args.limit_step
    qa, qb = mujoco(dl)(t)(), mujoco(dl / 4)(t)()
    window = t < first_ref + 0.1
    print(f"  MuJoCo RK4 at the limits, {dl * 1e3:g} ms against {dl * 250:g} ms: max |Δq| "
          f"{float(np.abs(qa - qb)[window].max()):.1e} up to 0.1 s past the first crossing, "
          f"{float(np.abs(qa - qb).max()):.1e} over the run (first order past a limit: the "
          f"constraint switches on inside a step)")  # fmt: skip

    sides = {
        "rrt-pin pinocchio": lambda tt: rrt_run(robot, q0, tt, "pinocchio"),
        "rrt-pin compiled": lambda tt: rrt_run(robot, q0, tt, "compiled"),
        "MuJoCo matched": mujoco(dl),
        "MuJoCo default": mujoco(dl, matched=False),
    }
    setting = {
        "rrt-pin pinocchio": "simulate(), odepack, accuracy 1e-8",
        "rrt-pin compiled": 'simulate(backend="compiled"), DOP853, accuracy 1e-8',
        "MuJoCo matched": f"RK4 {dl * 1e3:g} ms, solref ({solref[0]:g}, 1), solimp 0.9999",
        "MuJoCo default": f"RK4 {dl * 1e3:g} ms, solref (0.02, 1), solimp (0.9, 0.95)",
    }
    sides["rrt-pin compiled"](tb)()  # compiles or loads the kernels
    free = {side: float(np.abs(make(tb)() - ref_free).max()) for side, make in sides.items()}
    free[f"MuJoCo matched, {dt * 1e3:g} ms"] = float(np.abs(mujoco(dt)(tb)() - ref_free).max())
    print(
        f"  before any limit (0 … {t_free:g} s), max |q - q_ref|: "
        + ", ".join(f"{s} {e:.1e}" for s, e in free.items())
        + f"; every side ≤ {args.accuracy:.0e}: {verdict(max(free.values()) <= args.accuracy)}"
    )
    rows_free = [f"| {name} | 0 … {t_free:g} s | " + " | ".join(f"{e:.0e}" for e in free.values())
                 + " |"]  # fmt: skip

    # at the limits
    runs = {side: make(t) for side, make in sides.items()}
    found = {}
    for side, run in runs.items():
        q = run()
        found[side] = {(c.joint, c.side): c for c in crossings(t, q, stated.lower, stated.upper,
                                                               names)}  # fmt: skip
        first = min((c.first for c in found[side].values()), default=t[-1])
        print(f"  {side:<18} ({setting[side]}): max |q - q_ref| "
              f"{float(np.abs(q - ref)[t < first].max()):.1e} before its first crossing, "
              f"{float(np.abs(q - ref).max()):.2g} over the run")  # fmt: skip
        for c in found[side].values():
            unit = units[c.joint]
            print(f"    {c.joint:<20} {c.side} {c.limit:+.4f} {unit}: first at {c.first:.4f} s, "
                  f"deepest {c.depth:.2e} {unit}, {c.count} crossing(s)")  # fmt: skip
    print("  " + stiffer(robot, q0, t, ref, found_ref))
    keys = sorted({k for f in found.values() for k in f},
                  key=lambda k: min(f[k].first for f in found.values() if k in f))  # fmt: skip
    rows = []
    for joint, side in keys:
        limit = next(f[(joint, side)].limit for f in found.values() if (joint, side) in f)
        cells = [f"{f[(joint, side)].first:.3f} s, {f[(joint, side)].depth:.2g}"
                 if (joint, side) in f else "—" for f in found.values()]  # fmt: skip
        rows.append(f"| {name} | {joint} {side} {limit:+.4g} {units[joint]} | "
                    + " | ".join(cells) + " |")  # fmt: skip

    # timings: whole limit runs, interleaved
    timed = {
        "rrt-pin pinocchio": runs["rrt-pin pinocchio"],
        "rrt-pin compiled": runs["rrt-pin compiled"],
        f"MuJoCo RK4 {dl * 1e3:g} ms": runs["MuJoCo matched"],
        f"MuJoCo RK4 {dt * 1e3:g} ms": mujoco(dt)(t),
    }
    start = time.perf_counter()
    med = interleaved(timed, args.repeat, inner=1)
    print(f"  timed {args.repeat} interleaved rounds in {time.perf_counter() - start:.0f} s "
          f"(0 … {args.tf:g} s, {t.size} outputs, medians):")  # fmt: skip
    for side, s in med.items():
        ratios = ", ".join(f"{s / med[r]:.2g}× {r}" for r in ("rrt-pin pinocchio",
                                                             "rrt-pin compiled"))  # fmt: skip
        print(f"    {side:<20} {s * 1e3:8.2f} ms ({ratios})")
    cells = [milliseconds(s) + (f" ({side[7:]})" if side.startswith("MuJoCo") else "")
             for side, s in med.items()]  # fmt: skip
    ratio = [f"{med[m] / med[r]:.2g}×" for m in list(med)[2:] for r in list(med)[:2]]
    rows_time = [f"| {name} | " + " | ".join(cells + ratio) + " |"]
    return rows_free, rows, rows_time


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", default="ur5,panda")
    ap.add_argument("--repeat", type=int, default=5, help="interleaved rounds (5)")
    ap.add_argument("--tf", type=float, default=1.5, help="end of the limit runs [s] (1.5)")
    ap.add_argument("--accuracy", type=float, default=1e-8,
                    help="max |q - q_ref| before any limit [rad, m] (1e-8)")  # fmt: skip
    ap.add_argument("--limit-step", type=float, default=1e-4,
                    help="MuJoCo's RK4 step for the runs at the limits [s] (1e-4)")  # fmt: skip
    ap.add_argument("--markdown", action="store_true", help="print the tables as Markdown")
    args = ap.parse_args(argv)
    require()
    import mujoco

    import rrt_pin

    print(f"MuJoCo {mujoco.__version__}, rrt-pin {rrt_pin.__version__}")
    free, rows, times = [], [], []
    for name in args.robots.split(","):
        f, r, s = bench(name, args)
        free, rows, times = free + f, rows + r, times + s
    if args.markdown:
        print("\n| robot | before any limit | rrt-pin pinocchio | rrt-pin compiled | MuJoCo matched "
              f"{args.limit_step * 1e3:g} ms | MuJoCo default | MuJoCo matched, its step for "
              f"{args.accuracy:.0e} |")  # fmt: skip
        print("| --- | --- | ---: | ---: | ---: | ---: | ---: |")
        print("\n".join(free))
        print("\n| robot | limit crossed | rrt-pin pinocchio | rrt-pin compiled | MuJoCo matched "
              "| MuJoCo default |")  # fmt: skip
        print("| --- | --- | ---: | ---: | ---: | ---: |")
        print("\n".join(rows))
        print("\n| robot | rrt-pin pinocchio | rrt-pin compiled | MuJoCo matched, step at the "
              "limits | MuJoCo matched, step before them | ÷ pinocchio | ÷ compiled "
              "| ÷ pinocchio | ÷ compiled |")  # fmt: skip
        print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
        print("\n".join(times))
    return 0


if __name__ == "__main__":
    sys.exit(main())
