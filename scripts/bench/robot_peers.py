#!/usr/bin/env python
"""UR5 and Panda batches: rrt-pin's compiled lanes against ``mujoco.rollout``, per core, matched error.

The scene is :mod:`scripts.bench.robot_sim`'s: 15 s (--tf) under PD plus gravity
compensation, τ = −kd·q̇ − kp·(q − qf) + G(q), from q0 = qf + 0.3 rad (0.01 m for a
slider), outputs every 10 ms; the reference is rrt-pin's compiled DOP853 at rtol 1e-13.

rrt-pin runs the law alone (``effort_limits=False, position_limits=False,
losses=False``), and MuJoCo's model is the robot's URDF (``robots.urdf_path``) read by
MuJoCo's importer with what the law alone does not model switched off: visual and
collision elements removed (no meshes, no contacts: ``mjDSBL_CONTACT``), ``<mimic>``
removed (Pinocchio ignores it), the URDF's joint damping, friction and armature set to
0, joint limits off, the joints' actuator-force limits (MuJoCo's importer takes them
from ``effort``) off, and the constraint stage disabled (``mjDSBL_CONSTRAINT``: nothing
is constrained). The law is inside the model, so ``mujoco.rollout`` runs it without
Python per step: one position actuator a joint (gain kp, bias [0, −kp, −kd], ctrl = qf,
no ctrl or force limits) and ``gravcomp = 1`` on every body (MuJoCo adds G(q) as a
passive force). Printed checks: MuJoCo's mass matrix and bias forces against
``pin.crba`` and ``pin.rnea(q, v, 0)``, its actuator plus passive forces against
rrt-pin's law, at random states.

For each integrator (RK4; Euler and implicitfast to show) the largest step of the ladder
10 ms … 1 µs (each divides the 10 ms outputs) whose max |q error| meets --accuracy
(default 1e-9) over every output time, and separately at the final time only; first-order
integrators stop at --min-step and the step they would need is extrapolated (error ∝ step).
At 15 s the scene has settled (the final states are ~1e-15 from qf), so "final only" asks
little more of an integrator than stability; --tf 2 ends the runs before they settle.

Timed interleaved in one run (medians), one core each:

* rrt-pin   ``simulate_batch(..., backend="compiled", keep="final" | "metrics",
            threads=1, method=--method)`` of --batch variants (q0 spread by ±0.05 rad), at the loosest rtol
            of 1e-6 … 1e-13 in half-decades (--per-decade; atol = rtol/100) whose final
            state (final) or every output (metrics) meets --accuracy on the scene's run and
            three variants (MuJoCo's steps, 1-2-5 a decade, are chosen on the same runs);
* MuJoCo    ``mujoco.rollout`` with one MjData (one thread) of the first --mujoco-batch of
            those variants at each integrator's step (it records the full state at every
            step, in chunks of outputs so the memory stays small).

    .venv/bin/python -m scripts.bench.robot_peers [--robots ur5,panda] [--batch 200]
        [--mujoco-batch 20] [--repeat 3] [--accuracy 1e-9] [--tf 15] [--markdown]
        [--method DOP853-RKC]
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import re
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from scripts.bench.common import interleaved, verdict


def rtol_ladder(per_decade: int, loosest: int = 6) -> list[float]:
    """rrt-pin's tolerances 10^-loosest … 1e-13, loosest first, ``per_decade`` a decade."""
    return [10.0 ** (-k / per_decade) for k in range(loosest * per_decade, 13 * per_decade + 1)]


#: The default: half-decades (MuJoCo's steps below are 1-2-5 a decade, as fine or finer).
LADDER_RTOL = rtol_ladder(2)
# steps [s] dividing the 10 ms outputs, largest first
STEPS = [1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2.5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5, 5e-6, 2e-6, 1e-6]
# with --loose, for the final state only: steps beyond the outputs' 10 ms (dividing the 15 s)
LOOSE_STEPS = [5e-2, 3e-2, 2.5e-2, 2e-2, 1.5e-2]
DT_OUT = 0.01  # [s]
TARGET_RATIO = 50.0
CHUNK_BYTES = 32e6  # MuJoCo's recorded states held at once


def require() -> None:
    """Exit 2 with one line naming the extra when mujoco, numba or the robots are missing."""
    from rrt_pin.core.extras import install_hint

    wanted = (("mujoco", "bench"), ("numba", "fast"), ("example_robot_data", "robots"))
    missing = [(m, e) for m, e in wanted if importlib.util.find_spec(m) is None]
    if missing and missing != [("example_robot_data", "robots")]:  # its URDFs may be there
        extras = ",".join(dict.fromkeys(e for _, e in missing))
        names = ", ".join(m for m, _ in missing)
        print(
            f"scripts.bench.robot_peers: {names} not installed, install: {install_hint(extras)}",
            file=sys.stderr,
        )
        sys.exit(2)


# --------------------------------------------------------------------------------------------
# MuJoCo's model of a URDF robot, the law inside it
# --------------------------------------------------------------------------------------------
def urdf_for_mujoco(name: str) -> str:
    """The robot's URDF text without meshes or mimic joints, with MuJoCo's compiler options."""
    from rrt_pin.robot import robots

    text = robots.urdf_path(name).read_text(encoding="utf-8")
    text = re.sub(r"<visual\b.*?</visual>", "", text, flags=re.S)
    text = re.sub(r"<collision\b.*?</collision>", "", text, flags=re.S)
    text = re.sub(r"<mimic\b[^>]*/>", "", text)
    compiler = '<mujoco><compiler discardvisual="true" balanceinertia="false"/></mujoco>'
    return re.sub(r"(<robot\b[^>]*>)", r"\1" + compiler, text, count=1)


def mujoco_spec(name: str):
    """MuJoCo's spec of robot ``name`` (:func:`urdf_for_mujoco`) and its hinge and slide joints.

    The joints are in the order of the robot's coordinates (both depth first); the URDF's
    limits, damping, friction and effort limits are still as MuJoCo's importer read them.
    """
    import mujoco

    spec = mujoco.MjSpec.from_string(urdf_for_mujoco(name))
    kinds = (mujoco.mjtJoint.mjJNT_HINGE, mujoco.mjtJoint.mjJNT_SLIDE)
    return spec, [j for j in spec.joints if j.type in kinds]


def mujoco_compile(spec, dt: float, integrator: str, constraints: bool = False):
    """The compiled model: no contacts, the constraint stage on or off, the integrator and step."""
    import mujoco

    m = spec.compile()
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT
    if not constraints:
        m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    m.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    m.opt.timestep = dt
    return m


def mujoco_model(name: str, law=None, dt: float = 1e-3, integrator: str = "RK4"):
    """MuJoCo's model of robot ``name``, nothing beyond the law; with ``law`` (PD + gravity) inside."""
    import mujoco

    spec, joints = mujoco_spec(name)
    off = mujoco.mjtLimited.mjLIMITED_FALSE
    for j in joints:
        j.damping = np.zeros_like(np.asarray(j.damping, dtype=float))
        j.armature = 0.0
        j.frictionloss = 0.0
        j.limited = off
        j.actfrclimited = off
    if law is not None:
        for body in spec.bodies:
            body.gravcomp = 1.0
        for j, kp, kd in zip(joints, np.asarray(law.kp), np.asarray(law.kd), strict=True):
            act = spec.add_actuator()
            act.target = j.name
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            act.gaintype = mujoco.mjtGain.mjGAIN_FIXED  # force = kp·ctrl − kp·q − kd·q̇
            act.gainprm[0] = kp
            act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
            act.biasprm[:3] = (0.0, -kp, -kd)
            act.ctrllimited = off
            act.forcelimited = off
    return mujoco_compile(spec, dt, integrator)


def model_checks(name: str, robot, law, qf: np.ndarray, count: int = 5) -> dict[str, float]:
    """Max relative differences of MuJoCo's M, bias and law forces from Pinocchio's/rrt-pin's."""
    import mujoco
    import pinocchio as pin

    m = mujoco_model(name, law)
    d = mujoco.MjData(m)
    model = robot.model
    data = model.createData()
    rng = np.random.default_rng(7)
    worst = {"M": 0.0, "bias": 0.0, "law": 0.0, "gravity": 0.0}
    M = np.empty((m.nv, m.nv))
    for _ in range(count):
        q = qf + rng.uniform(-1.0, 1.0, m.nv) * np.where(np.abs(qf) < 0.1, 0.02, 1.0)
        v = rng.uniform(-1.0, 1.0, m.nv)
        d.qpos[:] = q
        d.qvel[:] = v
        d.ctrl[:] = qf
        mujoco.mj_forward(m, d)
        mujoco.mj_fullM(m, d, M)
        c = robot.configuration(q)
        Mp = pin.crba(model, data, c)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        b = pin.rnea(model, data, c, v, np.zeros(m.nv))
        g = pin.computeGeneralizedGravity(model, data, c)
        tau = np.asarray(law.efforts(0.0, q, v))
        for key, mine, theirs in (
            ("M", M, Mp),
            ("bias", d.qfrc_bias, b),
            ("gravity", d.qfrc_gravcomp, g),
            ("law", d.qfrc_actuator + d.qfrc_passive, tau),
        ):
            rel = float(np.abs(mine - theirs).max() / np.abs(theirs).max())
            worst[key] = max(worst[key], rel)
    return worst


def initial_states(m, q0s: np.ndarray) -> np.ndarray:
    """MuJoCo's full physics states (B, nstate) at q0s, at rest."""
    import mujoco

    d = mujoco.MjData(m)
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    x = np.empty((len(q0s), mujoco.mj_stateSize(m, kind)))
    for i, q in enumerate(q0s):
        d.qpos[:] = q
        d.qvel[:] = 0.0
        mujoco.mj_getState(m, d, x[i], kind)
    return x


def final_runner(m, q0s: np.ndarray, qf: np.ndarray, tf: float):
    """A call of ``mujoco.rollout`` (one thread) over the run, q at ``tf`` [s] only (B, 1, nv)."""
    import mujoco
    from mujoco import rollout

    nstep = round(tf / m.opt.timestep)
    x0 = initial_states(m, q0s)
    B, nstate = x0.shape
    state = np.empty((B, nstep, nstate))
    control = np.ascontiguousarray(np.broadcast_to(qf, (B, nstep, m.nu)), dtype=float)
    models, datas = [m] * B, [mujoco.MjData(m)]
    ctrl_spec = int(mujoco.mjtState.mjSTATE_CTRL)

    def run() -> np.ndarray:
        rollout.rollout(models, datas, x0, control, control_spec=ctrl_spec, nstep=nstep,
                        state=state, skip_checks=True)  # fmt: skip
        return state[:, -1:, 1 : 1 + m.nv].copy()

    return run


def rollout_runner(m, q0s: np.ndarray, qf: np.ndarray, n_out: int, dt_out: float = DT_OUT):
    """A call of ``mujoco.rollout`` (one thread) over the run: q at every output (B, n_out, nv).

    Outputs every ``dt_out`` [s] (a multiple of the model's step); ``qf``: the controls (nu,).
    """
    import mujoco
    from mujoco import rollout

    sub = round(dt_out / m.opt.timestep)
    x0 = initial_states(m, q0s)
    B, nstate = x0.shape
    nv = m.nv
    per_output = B * sub * (nstate + m.nu) * 8
    k = int(max(1, min(n_out - 1, CHUNK_BYTES // per_output)))
    state = np.empty((B, k * sub, nstate))
    control = np.ascontiguousarray(np.broadcast_to(qf, (B, k * sub, m.nu)), dtype=float)
    models, datas = [m] * B, [mujoco.MjData(m)]  # skip_checks: one model a variant, a list
    ctrl_spec = int(mujoco.mjtState.mjSTATE_CTRL)

    def run() -> np.ndarray:
        q = np.empty((B, n_out, nv))
        q[:, 0] = q0s
        x = x0
        i = 1
        while i < n_out:
            n = min(k, n_out - i)
            st = state if n == k else np.empty((B, n * sub, nstate))
            ctrl = control if n == k else np.ascontiguousarray(control[:, : n * sub])
            rollout.rollout(models, datas, x, ctrl, control_spec=ctrl_spec, nstep=n * sub, state=st,
                            skip_checks=True)  # fmt: skip
            q[:, i : i + n] = st[:, sub - 1 :: sub, 1 : 1 + nv]
            x = np.ascontiguousarray(st[:, -1])
            i += n
        return q

    return run


# --------------------------------------------------------------------------------------------
# matched accuracy
# --------------------------------------------------------------------------------------------
@dataclass
class Step:
    """An integrator's largest step meeting the target, over every output and at the end."""

    integrator: str
    tried: list[tuple[float, float, float]]  # step [s], max error every output, final
    every: tuple[float, float] | None = None  # step [s], error
    final: tuple[float, float] | None = None
    loose: list[tuple[float, float]] = field(default_factory=list)  # step [s], final error

    def need(self, accuracy: float) -> float:
        """The step an order-1 method would need for the target over every output [s]."""
        dt, err, _ = self.tried[-1]
        return dt * accuracy / err


def find_step(name, law, q0s, qf, refs, integrator, accuracy, min_step, loose=False) -> Step:
    """The largest step of STEPS meeting ``accuracy`` on every run of ``q0s`` (refs: (R, N, nv)).

    ``loose``: first LOOSE_STEPS, beyond the outputs, for the final state alone.
    """
    found = Step(integrator, [])
    tf = (refs.shape[1] - 1) * DT_OUT
    for dt in LOOSE_STEPS if loose else []:
        q = final_runner(mujoco_model(name, law, dt, integrator), q0s, qf, tf)()
        e = np.abs(q[:, -1] - refs[:, -1])
        final = float(e.max()) if np.isfinite(e).all() else float("inf")
        if found.final is None and final <= accuracy:
            found.final = (dt, final)
        found.loose.append((dt, final))
    for dt in STEPS:
        if dt < min_step:
            break
        m = mujoco_model(name, law, dt, integrator)
        q = rollout_runner(m, q0s, qf, refs.shape[1])()
        with np.errstate(invalid="ignore"):
            e = np.abs(q - refs)
        every = float(e.max()) if np.isfinite(e).all() else float("inf")
        final = float(e[:, -1].max()) if np.isfinite(e[:, -1]).all() else float("inf")
        found.tried.append((dt, every, final))
        if found.final is None and final <= accuracy:
            found.final = (dt, final)
        if every <= accuracy:
            found.every = (dt, every)
            break
    return found


def loosest_rtol(side, refs, rows, accuracy, ladder=None) -> tuple[float, tuple[float, float]]:
    """The loosest rtol of ``ladder`` (LADDER_RTOL) meeting ``accuracy`` at ``rows``; its errors."""
    for rtol in LADDER_RTOL if ladder is None else ladder:
        e = np.abs(side(rtol) - refs)
        if float(e[:, rows].max()) <= accuracy:
            break
    return rtol, (float(e[:, -1].max()), float(e.max()))


# --------------------------------------------------------------------------------------------
# one robot
# --------------------------------------------------------------------------------------------
def bench(name: str, args: argparse.Namespace, t: np.ndarray) -> list[str]:
    """One robot's checks, steps and timings; returns its rows of the Markdown table."""
    import rrt_pin
    from scripts.bench.robot_sim import PHYSICS, scene

    robot, law, q0, qf = scene(name)

    def rrt(q0_, rtol, keep="trajectories", **kw):
        # the law alone, as MuJoCo's model (no limits, losses or saturation)
        r = rrt_pin.simulate_batch(robot, law, np.atleast_2d(q0_), None, t, backend="compiled",
                                   keep=keep, threads=1, rtol=rtol, atol=rtol / 100,
                                   estimate_error=False, **PHYSICS, **kw)  # fmt: skip
        return r

    rrt(q0, 1e-6)  # compiles or loads the kernels
    B, Bm = args.batch, min(args.mujoco_batch, args.batch)
    rng = np.random.default_rng(1)
    q0s = q0 + rng.uniform(-0.05, 0.05, (B, robot.nv))
    # both sides' settings are chosen on the scene's run and three of the batch's variants
    checked = sorted({0, Bm // 2, Bm - 1})
    q0c = np.vstack([q0, q0s[checked]])
    refs = rrt(q0c, 1e-13, method="DOP853").q
    checks = model_checks(name, robot, law, qf)
    print(f"\n{name}: nv={robot.nv}, {t[-1]:g} s, {t.size} outputs; references compiled DOP853 "
          f"rtol 1e-13 (the scene's run and variants {checked}); their final states are "
          f"{np.abs(refs[:, -1] - qf).max():.1e} from qf")  # fmt: skip
    print("  MuJoCo's model, max relative difference at 5 random states: "
          f"M vs pin.crba {checks['M']:.1e}, qfrc_bias vs pin.rnea(q, v, 0) {checks['bias']:.1e}, "
          f"qfrc_gravcomp vs G(q) {checks['gravity']:.1e}, qfrc_actuator + qfrc_passive vs "
          f"rrt-pin's law {checks['law']:.1e}")  # fmt: skip

    # MuJoCo's steps
    steps: dict[str, Step] = {}
    for integrator in args.integrators.split(","):
        min_step = 0.0 if integrator.upper() == "RK4" else args.min_step
        s = find_step(name, law, q0c, qf, refs, integrator, args.accuracy, min_step, args.loose)
        steps[integrator] = s
        tried = ", ".join(f"{dt * 1e3:g} ms: {a:.1e}/{f:.1e}" for dt, a, f in s.tried)
        if s.loose:
            tried = ", ".join(f"{dt * 1e3:g} ms: final {f:.1e}" for dt, f in s.loose) + "; " + tried
        print(f"  MuJoCo {integrator:<12} max |q error| every output/final: {tried}")
        if s.every is None:
            print(f"  {'':<19} misses {args.accuracy:.0e} over the run down to "
                  f"{s.tried[-1][0] * 1e3:g} ms; error ∝ step would need ≈ "
                  f"{s.need(args.accuracy):.0e} s")  # fmt: skip
    rk4 = steps.get("RK4") or steps.get("rk4")
    if rk4 is not None and len(rk4.tried) >= 2:
        (h1, e1, _), (h2, e2, _) = rk4.tried[-2:]
        if e1 > 0 and e2 > 0:
            print(f"  law check: RK4's error falls as step^{np.log(e1 / e2) / np.log(h1 / h2):.1f} "
                  f"({h1 * 1e3:g} → {h2 * 1e3:g} ms): the model's law is rrt-pin's")  # fmt: skip

    # rrt-pin's tolerances (as robot_sim picks them)
    rtols, errors, evals = {}, {}, {}  # evals: dynamics evaluations a simulation
    for keep, rows in (("final", slice(-1, None)), ("metrics", slice(None))):
        side = f"rrt-pin {keep}"
        ladder = rtol_ladder(args.per_decade, 3 if args.loose and keep == "final" else 6)
        rtols[keep], errors[side] = loosest_rtol(lambda r: rrt(q0c, r, method=args.method).q, refs,
                                                 rows, args.accuracy, ladder)  # fmt: skip
        print(f"  rrt-pin {keep:<8} {args.method} rtol {rtols[keep]:.2g}: max |q error| final "
              f"{errors[side][0]:.1e}, every output {errors[side][1]:.1e}")  # fmt: skip

    # the timed sides
    funcs = {}
    setting = {}
    for keep in ("final", "metrics"):
        side = f"rrt-pin {keep}"
        funcs[side] = lambda keep=keep: rrt(q0s, rtols[keep], keep=keep, method=args.method)
        setting[side] = (f'rrt-pin simulate_batch(keep="{keep}"), {B} variants, {args.method} '
                         f"rtol {rtols[keep]:.2g}", B)  # fmt: skip
        result = funcs[side]()
        out = result.q[checked, -1]  # the batch's own final rows against the references
        evals[side] = float(np.mean(result.evaluations)) if result.evaluations is not None else 0
        print(f"  rrt-pin {keep:<8} batch's final rows of variants {checked}: max |q error| "
              f"{np.abs(out - refs[1:, -1]).max():.1e}")  # fmt: skip
    for integrator, s in steps.items():
        for what, found in (("every output", s.every), ("final", s.final)):
            if found is None:
                continue
            dt = found[0]
            key = f"MuJoCo {integrator} {dt * 1e3:g} ms"
            if key not in funcs:
                m = mujoco_model(name, law, dt, integrator)
                beyond = dt > DT_OUT * (1 + 1e-9)  # a loose step: the final state only
                funcs[key] = (final_runner(m, q0s[:Bm], qf, t[-1]) if beyond
                              else rollout_runner(m, q0s[:Bm], qf, t.size))  # fmt: skip
                setting[key] = (f"mujoco.rollout, 1 thread, {Bm} variants, {integrator}, "
                                f"step {dt * 1e3:g} ms", Bm)  # fmt: skip
                errors[key] = (next((f, math.nan) for h, f in s.loose if h == dt) if beyond else
                               next((f, a) for h, a, f in s.tried if h == dt))  # fmt: skip
                evals[key] = (4 if integrator.upper() == "RK4" else 1) * round(t[-1] / dt)
            setting.setdefault(f"{key} meets", []).append(what)

    start = time.perf_counter()
    med = interleaved(funcs, args.repeat, inner=1)
    rate = {side: setting[side][1] / med[side] for side in funcs}
    print(f"  timed {args.repeat} interleaved rounds in {time.perf_counter() - start:.0f} s "
          f"(errors: the scene's run and variants {checked}, final / every output):")  # fmt: skip
    lines = []
    for side in funcs:
        label, count = setting[side]
        fin, every = errors[side]
        meets = ", ".join(setting.get(f"{side} meets", [])) or (
            "final" if side.endswith("final") else "every output"
        )
        err = f"{fin:.1e} / {every:.1e}"
        base = "rrt-pin final" if "final" in meets and "every" not in meets else "rrt-pin metrics"
        ratio = rate[base] / rate[side]
        print(f"  {side:<26} {rate[side]:10.1f} simulations/s/core ({count} variants), "
              f"{evals[side]:,.0f} evaluations a simulation, error {err}; target met: {meets}; "
              f"{base} is {ratio:,.1f}x")  # fmt: skip
        lines.append(f"| {name} | {label} | {meets} | {err} | {evals[side]:,.0f} | "
                     f"{rate[side]:,.1f} | "
                     f"{'—' if side.startswith('rrt-pin') else f'{ratio:,.1f}×'} |")  # fmt: skip
    for keep, what in (("final", "final"), ("metrics", "every output")):
        mj = [s for s in funcs if s.startswith("MuJoCo") and what in setting.get(f"{s} meets", [])]
        if not mj:
            print(f"  rrt-pin {keep}: no MuJoCo integrator met {args.accuracy:.0e} ({what})")
            continue
        best = max(mj, key=lambda s: rate[s])
        r = rate[f"rrt-pin {keep}"] / rate[best]
        print(f"  rrt-pin {keep}: {r:,.1f}x the fastest MuJoCo at matched error ({best}): "
              f"target {TARGET_RATIO:g}x {verdict(r >= TARGET_RATIO)}")  # fmt: skip
    return lines


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", default="ur5,panda")
    ap.add_argument("--batch", type=int, default=200, help="rrt-pin's variants (200)")
    ap.add_argument("--mujoco-batch", type=int, default=20, help="MuJoCo's variants (20)")
    ap.add_argument("--repeat", type=int, default=3, help="interleaved rounds (3)")
    ap.add_argument("--accuracy", type=float, default=1e-9, help="max |q error| [rad, m]")
    ap.add_argument("--tf", type=float, default=15.0, help="end of the run [s] (15)")
    ap.add_argument("--integrators", default="RK4,Euler,implicitfast")
    ap.add_argument("--min-step", type=float, default=1e-5,
                    help="smallest step tried for first-order integrators [s] (1e-5)")  # fmt: skip
    ap.add_argument("--per-decade", type=int, default=2, choices=(1, 2),
                    help="rrt-pin's tolerances a decade of 1e-6 … 1e-13 (2: half-decades, as "
                    "fine as MuJoCo's 1-2-5 steps; 1: decades, as before)")  # fmt: skip
    ap.add_argument("--loose", action="store_true",
                    help="for the final state, both ladders further: rrt-pin's tolerances from "
                    "1e-3, MuJoCo's steps up to 50 ms (beyond the outputs)")  # fmt: skip
    ap.add_argument("--method", default="DOP853", choices=("DOP853", "DOP853-RKC"),
                    help="rrt-pin's method (DOP853; DOP853-RKC hands the settled tail to "
                    "Runge–Kutta–Chebyshev)")  # fmt: skip
    ap.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    args = ap.parse_args(argv)
    require()
    import mujoco

    import rrt_pin

    print(f"MuJoCo {mujoco.__version__}, rrt-pin {rrt_pin.__version__}")
    t = np.arange(0.0, args.tf + 1e-9, DT_OUT)
    lines = []
    for name in args.robots.split(","):
        lines += bench(name, args, t)
    if args.markdown:
        print("\n| robot | side | meets the target over | max \\|q error\\| (final / every output) "
              "| evaluations a simulation | simulations/s/core | rrt-pin ÷ side |")  # fmt: skip
        print("| --- | --- | --- | ---: | ---: | ---: | ---: |")
        for line in lines:
            print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
