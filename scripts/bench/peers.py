#!/usr/bin/env python
"""rrt-pin against its peers — MuJoCo, Drake, scipy — at matched accuracy, in one run.

Needs the ``bench`` extra (``pip install -e '.[bench,fast]'``: mujoco, drake; numba for
the compiled backend). Every side computes the chapter's arm and is timed in the same
run, interleaved (:func:`bench_compiled.interleaved`, medians); ratios compare sides of
this run only.

1. inverse dynamics on the chapter's 15,001 samples of eq. (30)'s motion: ns/sample
   and speed against a Python loop of ``pin.rnea``; each side's max relative difference
   (per joint, against the joint's largest effort) from rrt-pin's Pinocchio efforts.
2. direct dynamics, the chapter's run (eq. 31, 0..15 s, 1,501 outputs): every side at
   its cheapest setting that reaches max |q − q_ref| <= 1e-8 against
   ``rrt_pin.simulate.reference.chapter_reference`` ("matched accuracy": tolerances tightened
   tenfold, fixed steps halved, until the run reaches it; that search is not timed).
3. batch: --batch chapter variants (gains, q0, masses) per second on one core:
   ``simulate_batch(..., backend="compiled")`` against ``mujoco.rollout`` with one thread.

MuJoCo refuses the rods' zero axial moments (I1z = I2z = 0): its model is the URDF of
``rrt_pin.robot.urdf.urdf_xml(min_inertia=1e-6)``, a slightly different arm (the difference is
printed, and the same model with the moments set back to 0 after compilation shows that
it is the whole difference). Drake takes the chapter's URDF as it is.

    /work/peers-venv/bin/python -m scripts.bench.peers [--repeat 5] [--quick]
        [--batch 1000] [--markdown] [--csv PATH]
"""

from __future__ import annotations

import argparse
import csv
import importlib.util
import math
import os
import platform
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from scripts.bench.common import interleaved
from scripts.bench.compiled import baseline_direct, seed_variants

TARGET_ERROR = 1e-8  # max |q − q_ref| of "matched accuracy" [rad, m]
MIN_INERTIA = 1e-6  # [kg·m²] the rods' axial moments in MuJoCo's model
N_INVERSE = 15001
Run = Callable[[], tuple[np.ndarray, int]]


def require_peers() -> None:
    """Exit 2 with one line naming the extra when a peer (or numba) is not installed."""
    from rrt_pin.core.extras import install_hint

    wanted = (
        ("mujoco", "mujoco", "bench"),
        ("pydrake", "drake", "bench"),
        ("numba", "numba", "fast"),
    )
    missing = [
        (name, extra) for module, name, extra in wanted if importlib.util.find_spec(module) is None
    ]
    if missing:
        extras = list(dict.fromkeys(extra for _, extra in missing))
        which = " and ".join(f"'{e}'" for e in extras) + (
            " extras" if len(extras) > 1 else " extra"
        )
        print(
            f"scripts.bench.peers: {', '.join(name for name, _ in missing)} not installed, "
            f"install the {which}: {install_hint(','.join(extras))}",
            file=sys.stderr,
        )
        sys.exit(2)


@dataclass
class Row:
    """One line of the table."""

    task: str
    side: str
    setting: str
    seconds: float  # median wall time of one call
    cost: float  # in ``unit``
    unit: str
    ratio: float  # speed against the task's baseline (> 1: faster)
    evaluations: int | None
    error: float
    error_kind: str
    reached: bool = True
    note: str = ""


@dataclass
class Side:
    """A side of the direct-dynamics race: settings from cheapest to tightest."""

    name: str
    knobs: list[tuple[str, Run]]
    chosen: tuple[str, Run, np.ndarray, int, float] | None = None
    tried: list[tuple[str, float, float]] = field(default_factory=list)  # label, err, seconds
    reached: bool = False

    def calibrate(self, ref_q: np.ndarray) -> None:
        """Run the settings in order until one reaches TARGET_ERROR (untimed, beyond one call)."""
        for label, run in self.knobs:
            start = time.perf_counter()
            q, evals = run()
            seconds = time.perf_counter() - start
            err = float(np.abs(q - ref_q).max())
            self.tried.append((label, err, seconds))
            self.chosen = (label, run, q, evals, err)
            if err <= TARGET_ERROR:
                self.reached = True
                return


# --------------------------------------------------------------------------------------------
# MuJoCo
# --------------------------------------------------------------------------------------------
def mujoco_model(
    p, *, law: str | None = None, gains=None, dt: float = 0.01, zero=False, lean=False
):
    """MuJoCo model of the arm from rrt-pin's URDF (moments >= MIN_INERTIA), RK4 at ``dt``.

    law: None (no actuator), ``"motor"`` (ctrl = joint effort) or ``"model"`` (eq. 31
    inside MuJoCo: position actuators ctrl = qf, force kp·(qf − q) − kd·q̇, plus
    ``gravcomp = 1`` on every body, which adds G(q) — eq. 31's gravity terms exactly).
    zero: set the raised moments back to 0 after compilation (MuJoCo's runtime model
    accepts them; its compiler does not).
    lean: disable MuJoCo's constraint stage (``mjDSBL_CONSTRAINT``; nothing here is
    constrained: no contact, the joint limits are never reached).
    """
    import mujoco

    from rrt_pin.robot.urdf import JOINT_NAMES, urdf_xml

    spec = mujoco.MjSpec.from_string(urdf_xml(p, min_inertia=MIN_INERTIA))
    if law == "model":
        for body in spec.bodies:
            body.gravcomp = 1.0
    if law is not None:
        kp, kd = gains if gains is not None else ((0.0,) * 3, (0.0,) * 3)
        for joint, k, c in zip(JOINT_NAMES, kp, kd, strict=True):
            act = spec.add_actuator()
            act.target = joint
            act.trntype = mujoco.mjtTrn.mjTRN_JOINT
            if law == "model":  # force = gain·ctrl + b0 + b1·q + b2·q̇
                act.gaintype = mujoco.mjtGain.mjGAIN_FIXED
                act.gainprm[0] = k
                act.biastype = mujoco.mjtBias.mjBIAS_AFFINE
                act.biasprm[:3] = (0.0, -k, -c)
    m = spec.compile()
    m.opt.integrator = mujoco.mjtIntegrator.mjINT_RK4
    m.opt.timestep = dt
    if zero:
        m.body_inertia[m.body_inertia == MIN_INERTIA] = 0.0
    if lean:
        m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    return m


def mujoco_initial_state(m, q0, qd0) -> np.ndarray:
    import mujoco

    d = mujoco.MjData(m)
    d.qpos[:] = q0
    d.qvel[:] = qd0
    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    x = np.empty(mujoco.mj_stateSize(m, spec))
    mujoco.mj_getState(m, d, x, spec)
    return x


def mujoco_rollout_run(models, q0s, qd0s, qf, n_out: int, substeps: int) -> Run:
    """``mujoco.rollout`` of eq. (31) inside the model(s), one thread; q at every output."""
    import mujoco
    from mujoco import rollout

    models = list(models)
    x0 = np.array(
        [mujoco_initial_state(m, q, v) for m, q, v in zip(models, q0s, qd0s, strict=True)]
    )
    control = np.asarray(qf, dtype=float)[None, None, :]
    data = mujoco.MjData(models[0])
    nstep = (n_out - 1) * substeps
    one = len(models) == 1

    def run():
        state, _ = rollout.rollout(
            models[0] if one else models,
            data,
            x0,
            control,
            control_spec=mujoco.mjtState.mjSTATE_CTRL,
            nstep=nstep,
        )
        q = np.empty((len(models), n_out, 3))
        q[:, 0] = q0s
        q[:, 1:] = state[:, substeps - 1 :: substeps, 1:4]  # FULLPHYSICS: time, qpos, ...
        return (q[0] if one else q), 4 * nstep * len(models)

    return run


def mujoco_loop_run(m, law, q0, qd0, n_out: int, substeps: int, per_stage: bool) -> Run:
    """``mj_step`` in a Python loop with eq. (31) computed in Python.

    per_stage: through ``mjcb_control`` at each of RK4's four stages (``ctrl`` of motor
    actuators); otherwise into ``qfrc_applied`` once per step, held over the step.
    """
    import mujoco

    def run():
        d = mujoco.MjData(m)
        d.qpos[:] = q0
        d.qvel[:] = qd0
        q = np.empty((n_out, 3))
        q[0] = q0
        if per_stage:

            def control(_m, dd):
                dd.ctrl[:] = law.efforts(dd.time, dd.qpos, dd.qvel)

            mujoco.set_mjcb_control(control)
            try:
                for i in range(1, n_out):
                    for _ in range(substeps):
                        mujoco.mj_step(m, d)
                    q[i] = d.qpos
            finally:
                mujoco.set_mjcb_control(None)
        else:
            for i in range(1, n_out):
                for _ in range(substeps):
                    d.qfrc_applied[:] = law.efforts(d.time, d.qpos, d.qvel)
                    mujoco.mj_step(m, d)
                q[i] = d.qpos
        return q, 4 * (n_out - 1) * substeps

    return run


# --------------------------------------------------------------------------------------------
# Drake
# --------------------------------------------------------------------------------------------
def drake_plant(p, builder=None):
    from pydrake.multibody.parsing import Parser
    from pydrake.multibody.plant import MultibodyPlant

    from rrt_pin.robot.urdf import urdf_xml

    plant = MultibodyPlant(0.0)  # continuous: the Simulator's integrator runs it
    if builder is not None:
        plant = builder.AddSystem(plant)
    Parser(plant).AddModelsFromString(urdf_xml(p), "urdf")
    plant.Finalize()
    plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -p.g])
    return plant


def drake_diagram(p, kp, kd, qf):
    """Plant + eq. (31) in Drake's C++ systems: PidController (ki = 0) + gravity compensation.

    ``InverseDynamics(kGravityCompensation)`` outputs G(q), eq. (31)'s gravity terms.
    """
    from pydrake.systems.controllers import InverseDynamics, PidController
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import Adder, ConstantVectorSource

    b = DiagramBuilder()
    plant = drake_plant(p, b)
    pid = b.AddSystem(PidController(np.array(kp), np.zeros(3), np.array(kd)))
    target = b.AddSystem(ConstantVectorSource(np.concatenate([qf, np.zeros(3)])))
    gravity = b.AddSystem(
        InverseDynamics(plant, InverseDynamics.InverseDynamicsMode.kGravityCompensation)
    )
    add = b.AddSystem(Adder(2, 3))
    b.Connect(plant.get_state_output_port(), pid.get_input_port_estimated_state())
    b.Connect(target.get_output_port(), pid.get_input_port_desired_state())
    b.Connect(plant.get_state_output_port(), gravity.get_input_port_estimated_state())
    b.Connect(pid.get_output_port_control(), add.get_input_port(0))
    b.Connect(gravity.get_output_port_generalized_force(), add.get_input_port(1))
    b.Connect(add.get_output_port(), plant.get_applied_generalized_force_input_port())
    return b.Build(), plant


def drake_python_diagram(p, law):
    """Plant + eq. (31) as a Python ``LeafSystem`` calling ``law.efforts`` (Python per evaluation)."""
    from pydrake.systems.framework import DiagramBuilder, LeafSystem

    class Eq31(LeafSystem):
        def __init__(self):
            super().__init__()
            self.state = self.DeclareVectorInputPort("state", 6)
            self.DeclareVectorOutputPort("tau", 3, self.calc)

        def calc(self, context, output):
            x = self.state.Eval(context)
            output.SetFromVector(law.efforts(context.get_time(), x[:3], x[3:]))

    b = DiagramBuilder()
    plant = drake_plant(p, b)
    eq31 = b.AddSystem(Eq31())
    b.Connect(plant.get_state_output_port(), eq31.get_input_port(0))
    b.Connect(eq31.get_output_port(0), plant.get_applied_generalized_force_input_port())
    return b.Build(), plant


def drake_run(diagram, plant, q0, qd0, t: np.ndarray, scheme: str, accuracy: float) -> Run:
    """A Simulator with an error-controlled integrator, stopped at every output time."""
    from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator

    def run():
        sim = Simulator(diagram)
        ctx = plant.GetMyMutableContextFromRoot(sim.get_mutable_context())
        plant.SetPositions(ctx, np.asarray(q0, dtype=float))
        plant.SetVelocities(ctx, np.asarray(qd0, dtype=float))
        integrator = ResetIntegratorFromFlags(sim, scheme, float(t[1] - t[0]))
        integrator.set_target_accuracy(accuracy)
        sim.Initialize()
        q = np.empty((t.size, 3))
        q[0] = q0
        for i in range(1, t.size):
            sim.AdvanceTo(t[i])
            q[i] = plant.GetPositions(ctx)
        return q, integrator.get_num_derivative_evaluations()

    return run


# --------------------------------------------------------------------------------------------
# 1. inverse dynamics
# --------------------------------------------------------------------------------------------
def section_inverse(repeat: int) -> tuple[list[Row], list[str]]:
    import mujoco
    import pinocchio as pin
    from pydrake.multibody.tree import MultibodyForces

    from rrt_pin.dynamics.inverse import inverse_dynamics
    from rrt_pin.dynamics.trajectory import rest_to_rest
    from rrt_pin.robot.robots import chapter_arm

    robot = chapter_arm()
    p, d = robot.params, robot.defaults
    traj = rest_to_rest(d.q0, d.qf, 15.0, np.linspace(0.0, 15.0, N_INVERSE))
    q, qd, qdd = (np.ascontiguousarray(a) for a in (traj.q, traj.qd, traj.qdd))
    n = q.shape[0]
    model = robot.model
    data = model.createData()

    def rnea_loop():
        out = np.empty((n, 3))
        for i in range(n):
            out[i] = pin.rnea(model, data, q[i], qd[i], qdd[i])
        return out

    def mj_loop(m):
        md = mujoco.MjData(m)

        def run():
            out = np.empty((n, 3))
            for i in range(n):
                md.qpos[:] = q[i]
                md.qvel[:] = qd[i]
                md.qacc[:] = qdd[i]
                mujoco.mj_inverse(m, md)
                out[i] = md.qfrc_inverse
            return out

        return run

    plant = drake_plant(p)
    ctx = plant.CreateDefaultContext()
    forces = MultibodyForces(plant)
    x = np.empty(6)

    def drake_loop():
        out = np.empty((n, 3))
        for i in range(n):
            x[:3] = q[i]
            x[3:] = qd[i]
            plant.SetPositionsAndVelocities(ctx, x)
            plant.CalcForceElementsContribution(ctx, forces)  # gravity, as applied forces
            out[i] = plant.CalcInverseDynamics(ctx, qdd[i], forces)
        return out

    funcs = {
        "Python loop of pin.rnea": rnea_loop,
        "rrt-pin compiled": lambda: inverse_dynamics(robot, q, qd, qdd, backend="compiled"),
        "rrt-pin symbolic": lambda: inverse_dynamics(robot, q, qd, qdd, backend="symbolic"),
        "rrt-pin pinocchio (batched, 1 thread)": lambda: inverse_dynamics(
            robot, q, qd, qdd, num_threads=1
        ),
        "MuJoCo mj_inverse, Python loop": mj_loop(mujoco_model(p)),
        "MuJoCo mj_inverse, Python loop, no constraint stage": mj_loop(mujoco_model(p, lean=True)),
        "Drake CalcInverseDynamics, Python loop": drake_loop,
    }
    settings = {
        "Python loop of pin.rnea": "one call per sample",
        "rrt-pin compiled": 'inverse_dynamics(..., backend="compiled")',
        "rrt-pin symbolic": 'backend="symbolic" (numpy kernel)',
        "rrt-pin pinocchio (batched, 1 thread)": "pin.rneaInParallel, num_threads=1",
        "MuJoCo mj_inverse, Python loop": f"URDF min_inertia={MIN_INERTIA:g}",
        "MuJoCo mj_inverse, Python loop, no constraint stage": "+ mjDSBL_CONSTRAINT",
        "Drake CalcInverseDynamics, Python loop": "+ CalcForceElementsContribution (gravity)",
    }
    results = {k: np.asarray(f()) for k, f in funcs.items()}
    ref = inverse_dynamics(robot, q, qd, qdd)  # rrt-pin's Pinocchio efforts (default threads)

    def rel(a):
        return float((np.abs(a - ref).max(axis=0) / np.abs(ref).max(axis=0)).max())

    zeroed = rel(mj_loop(mujoco_model(p, zero=True))())
    per_joint = np.abs(results["MuJoCo mj_inverse, Python loop"] - ref).max(axis=0)
    medians = interleaved(funcs, repeat, inner=2)
    base = medians["Python loop of pin.rnea"]
    rows = [
        Row(
            "inverse",
            k,
            settings[k],
            medians[k],
            medians[k] / n * 1e9,
            "ns/sample",
            base / medians[k],
            None,
            rel(results[k]),
            "rel. diff. from rrt-pin pinocchio",
        )
        for k in funcs
    ]
    rows.insert(
        6,
        Row(
            "inverse",
            "MuJoCo batch inverse",
            "none in MuJoCo's Python API",
            math.nan,
            math.nan,
            "ns/sample",
            math.nan,
            None,
            math.nan,
            "",
            reached=False,
            note="mujoco.rollout is forward only; MJX (JAX) not measured",
        ),
    )
    notes = [
        f"MuJoCo's efforts differ from Pinocchio's by {per_joint[0]:.1e} N·m, "
        f"{per_joint[1]:.1e} N·m, {per_joint[2]:.1e} N (max over the samples): the rods' "
        f"axial moments {MIN_INERTIA:g} kg·m² instead of 0; with those moments set back to 0 "
        f"in the compiled MuJoCo model the relative difference is {zeroed:.1e}",
    ]
    return rows, notes


# --------------------------------------------------------------------------------------------
# 2. direct dynamics
# --------------------------------------------------------------------------------------------
RTOLS = (1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12)


def direct_sides(p, robot, law, t, quick: bool) -> list[Side]:

    from rrt_pin.simulate import simulate

    d = robot.defaults
    q0, qd0 = np.array(d.q0), np.array(d.qd0)
    model = robot.model
    n_out = t.size
    dt_out = float(t[1] - t[0])

    def sim(backend: str, **kw) -> Run:
        def run():
            r = simulate(robot, law, q0, qd0, t, backend=backend, estimate_error=False, **kw)
            return r.q, r.n_evals

        return run

    def tol(r: float) -> dict[str, float]:
        return {"rtol": r, "atol": r / 100}

    def dts(levels: int):
        return [(dt_out / 2**k, 2**k) for k in range(levels)]

    sides = [
        Side(
            "scipy solve_ivp DOP853 + pin.aba",
            [
                (f"rtol {r:g}", lambda r=r: baseline_direct(model, law, q0, qd0, t, **tol(r)))
                for r in RTOLS
            ],
        ),
        Side(
            "rrt-pin compiled DOP853",
            [(f"rtol {r:g}", sim("compiled", **tol(r))) for r in RTOLS],
        ),
        Side("rrt-pin compiled, simulate() defaults", [("DOP853 rtol 1e-10", sim("compiled"))]),
        Side(
            "rrt-pin pinocchio odepack",
            [(f"rtol {r:g}", sim("pinocchio", method="odepack", **tol(r))) for r in RTOLS],
        ),
        Side("rrt-pin pinocchio, simulate() defaults", [("odepack rtol 1e-12", sim("pinocchio"))]),
    ]
    gains = (d.kp, d.kd)
    for label, lean in (
        ("MuJoCo RK4, mujoco.rollout, eq. 31 in the model", False),
        ("MuJoCo RK4, mujoco.rollout, eq. 31 in the model, no constraint stage", True),
    ):
        sides.append(
            Side(
                label,
                [
                    (
                        f"dt {dt * 1e3:g} ms",
                        mujoco_rollout_run(
                            [mujoco_model(p, law="model", gains=gains, dt=dt, lean=lean)],
                            [q0],
                            [qd0],
                            d.qf,
                            n_out,
                            sub,
                        ),
                    )
                    for dt, sub in dts(3 if quick else 5)
                ],
            )
        )
    sides.append(
        Side(
            "MuJoCo RK4, mj_step loop, eq. 31 in Python per stage",
            [
                (
                    f"dt {dt * 1e3:g} ms",
                    mujoco_loop_run(
                        mujoco_model(p, law="motor", dt=dt), law, q0, qd0, n_out, sub, True
                    ),
                )
                for dt, sub in dts(2 if quick else 4)
            ],
        )
    )
    sides.append(
        Side(
            "MuJoCo RK4, mj_step loop, eq. 31 in qfrc_applied per step",
            [
                (
                    f"dt {dt * 1e3:g} ms",
                    mujoco_loop_run(mujoco_model(p, dt=dt), law, q0, qd0, n_out, sub, False),
                )
                for dt, sub in dts(2 if quick else 4)
            ],
        )
    )
    cxx = drake_diagram(p, d.kp, d.kd, d.qf)
    python = drake_python_diagram(p, law)
    for scheme, label, (diagram, plant), how in (
        ("runge_kutta3", "RK3 (default)", cxx, "as C++ systems"),
        ("runge_kutta5", "RK5", cxx, "as C++ systems"),
        ("runge_kutta3", "RK3 (default)", python, "as a Python LeafSystem"),
    ):
        sides.append(
            Side(
                f"Drake Simulator {label}, eq. 31 {how}",
                [
                    (f"accuracy {a:g}", drake_run(diagram, plant, q0, qd0, t, scheme, a))
                    for a in (1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10)
                ],
            )
        )
    return sides


def section_direct(repeat: int, quick: bool) -> tuple[list[Row], list[str], dict]:

    from rrt_pin import compiled
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.simulate.control import chapter_controller
    from rrt_pin.simulate.reference import chapter_reference

    compiled.ensure_compiled()
    robot = chapter_arm()
    p = robot.params
    law = chapter_controller(p)
    ref = chapter_reference()
    t = ref.t
    sides = direct_sides(p, robot, law, t, quick)
    notes = [
        f"reference: {ref.methods[0]} vs {ref.methods[1]} at rtol {ref.rtol:g} differ by "
        f"{ref.difference_q:.1e}"
    ]
    for side in sides:
        side.calibrate(ref.q)
        tried = ", ".join(f"{label}: {err:.1e}" for label, err, _ in side.tried)
        print(f"   calibrated {side.name}: {tried}", file=sys.stderr)
    funcs = {s.name: s.chosen[1] for s in sides}
    medians = interleaved(funcs, repeat, inner=2)
    base = medians["scipy solve_ivp DOP853 + pin.aba"]
    rows = []
    for s in sides:
        label, _, _, evals, err = s.chosen
        rows.append(
            Row(
                "direct",
                s.name,
                label,
                medians[s.name],
                medians[s.name] * 1e3,
                "ms/run",
                base / medians[s.name],
                evals,
                err,
                "max |q - q_ref|",
                reached=s.reached,
            )
        )
        if not s.reached:
            # first order in dt: the step that would reach the target, and its cost
            dt_ms = float(label.split()[1])
            need = dt_ms * TARGET_ERROR / err
            hours = medians[s.name] * dt_ms / need / 3600
            rows[-1].note = f"error ∝ dt: ≤ 1e-8 needs dt ≈ {need:.0e} ms, ~{hours:,.0f} h a run"
    mj = next(s for s in sides if s.name.startswith("MuJoCo RK4, mujoco.rollout"))
    sub = round(float(t[1] - t[0]) / (float(mj.chosen[0].split()[1]) * 1e-3))
    zero_model = mujoco_model(
        p,
        law="model",
        gains=(robot.defaults.kp, robot.defaults.kd),
        dt=float(t[1] - t[0]) / sub,
        zero=True,
    )
    d = robot.defaults
    qz, _ = mujoco_rollout_run([zero_model], [d.q0], [d.qd0], d.qf, t.size, sub)()
    # twice the output interval, compared at every other output
    coarse = mujoco_model(p, law="model", gains=(d.kp, d.kd), dt=2 * float(t[1] - t[0]))
    q2, _ = mujoco_rollout_run([coarse], [d.q0], [d.qd0], d.qf, (t.size + 1) // 2, 1)()
    coarse_err = float(np.abs(q2 - ref.q[::2]).max())
    notes.append(
        f"MuJoCo at {mj.chosen[0]}: {mj.chosen[4]:.1e} with min_inertia {MIN_INERTIA:g}; "
        f"{float(np.abs(qz - ref.q).max()):.1e} with the moments set back to 0 after "
        "compilation (RK4's own error); "
        + ", ".join(f"{label}: {err:.1e}" for label, err, _ in mj.tried)
        + f"; at dt {2e3 * float(t[1] - t[0]):g} ms with every other output: {coarse_err:.1e}"
    )
    chosen = {s.name: s for s in sides}
    return rows, notes, chosen


# --------------------------------------------------------------------------------------------
# 3. batch
# --------------------------------------------------------------------------------------------
def section_batch(count: int, repeat: int, chosen: dict, scipy_seconds: float):

    from rrt_pin.robot.model import rrt_model
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.simulate import simulate_batch
    from rrt_pin.simulate.reference import reference_run

    robot = chapter_arm()
    plants, controllers, q0s, qd0s = seed_variants(count)
    t = np.linspace(0.0, 15.0, 1501)
    rtol = float(chosen["rrt-pin compiled DOP853"].chosen[0].split()[1])
    mj_label = chosen["MuJoCo RK4, mujoco.rollout, eq. 31 in the model"].chosen[0]
    dt = float(mj_label.split()[1]) * 1e-3
    sub = round(0.01 / dt)

    def rrt():
        r = simulate_batch(
            robot,
            controllers,
            q0s,
            qd0s,
            t,
            backend="compiled",
            params=plants,
            rtol=rtol,
            atol=rtol / 100,
            efforts=False,
            estimate_error=False,
        )
        return r.q, r.n_evals

    start = time.perf_counter()
    models = [
        mujoco_model(plant, law="model", gains=(c.kp, c.kd), dt=dt)
        for plant, c in zip(plants, controllers, strict=True)
    ]
    built = time.perf_counter() - start
    mj = mujoco_rollout_run(models, q0s, qd0s, plants[0].qf, t.size, sub)
    funcs = {"rrt-pin simulate_batch compiled": rrt, "MuJoCo rollout": mj}
    out = {k: f() for k, f in funcs.items()}
    medians = interleaved(funcs, repeat, inner=1)
    checked = sorted({0, count // 2, count - 1})
    refs = {
        i: reference_run(rrt_model(plants[i]), controllers[i], q0s[i], qd0s[i], t).q
        for i in checked
    }
    base_rate = 1.0 / scipy_seconds
    rows = [
        Row(
            "batch",
            "scipy solve_ivp DOP853 + pin.aba, one run at a time",
            chosen["scipy solve_ivp DOP853 + pin.aba"].chosen[0],
            scipy_seconds,
            base_rate,
            "runs/s/core",
            1.0,
            None,
            chosen["scipy solve_ivp DOP853 + pin.aba"].chosen[4],
            "max |q - q_ref| (chapter's run)",
            note="estimated from the direct section",
        )
    ]
    labels = {
        "rrt-pin simulate_batch compiled": (
            'simulate_batch(..., backend="compiled")',
            f"DOP853 rtol {rtol:g}, states only",
        ),
        "MuJoCo rollout": ("mujoco.rollout, 1 thread, eq. 31 in the models", f"RK4 {mj_label}"),
    }
    for k, (q, evals) in out.items():
        err = max(float(np.abs(q[i] - refs[i]).max()) for i in checked)
        rate = count / medians[k]
        side, setting = labels[k]
        rows.append(
            Row(
                "batch",
                side,
                setting,
                medians[k],
                rate,
                "runs/s/core",
                rate / base_rate,
                evals // count,
                err,
                f"max |q - q_ref| on variants {checked}",
                reached=err <= TARGET_ERROR,
            )
        )
    notes = [
        f"batch: {count} variants (gains x0.8..1.25, q0 +-0.1, masses x0.8..1.25), 1,501 "
        f"outputs each; MuJoCo's {count} models compiled in {built:.1f} s (not timed)"
    ]
    return rows, notes


# --------------------------------------------------------------------------------------------
# Output
# --------------------------------------------------------------------------------------------
def versions() -> dict[str, str]:
    from importlib.metadata import version

    import mujoco
    import numba
    import pinocchio as pin
    import scipy

    import rrt_pin

    return {
        "rrt-pin": rrt_pin.__version__,
        "Pinocchio": pin.__version__,
        "MuJoCo": mujoco.__version__,
        "Drake": version("drake"),
        "scipy": scipy.__version__,
        "numpy": np.__version__,
        "numba": numba.__version__,
        "Python": platform.python_version(),
    }


def fmt_cost(r: Row) -> str:
    if math.isnan(r.cost):
        return "—"
    if r.unit == "ns/sample":
        return f"{r.cost:,.0f} ns/sample"
    if r.unit == "ms/run":
        return f"{r.cost:.3g} ms" if r.cost < 100 else f"{r.cost:,.0f} ms"
    return f"{r.cost:,.0f} runs/s"


def fmt_ratio(r: Row) -> str:
    if math.isnan(r.ratio):
        return "—"
    return f"{r.ratio:.3g}×" if r.ratio < 100 else f"{r.ratio:,.0f}×"


def fmt_error(r: Row) -> str:
    if math.isnan(r.error):
        return "—"
    mark = "" if r.reached or r.task == "inverse" else " ✗"
    return f"{r.error:.1e}{mark}"


HEADINGS = {
    "inverse": "**inverse dynamics**, 15,001 samples of eq. (30); × a Python loop of "
    "`pin.rnea`; difference: max relative, from rrt-pin's Pinocchio efforts",
    "direct": "**direct dynamics**, the chapter's run (eq. 31, 0..15 s, 1,501 outputs), "
    "each side at its cheapest setting with max \\|q − q_ref\\| ≤ 1e-8; × scipy",
    "batch": "**batch**: 1,000 chapter variants, one core; × scipy one run at a time",
}


def markdown(rows: list[Row], count: int) -> str:
    lines = [
        "| side | setting | cost | × baseline | evaluations | error |",
        "| --- | --- | ---: | ---: | ---: | ---: |",
    ]
    task = None
    for r in rows:
        if r.task != task:
            task = r.task
            heading = HEADINGS[task].replace("1,000", f"{count:,}")
            lines.append(f"| {heading} | | | | | |")
        evals = "" if r.evaluations is None else f"{r.evaluations:,}"
        note = f" ({r.note})" if r.note else ""
        setting = r.setting.replace("|", "\\|")
        lines.append(
            f"| {r.side}{note} | {setting} | {fmt_cost(r)} | {fmt_ratio(r)} | {evals} | "
            f"{fmt_error(r)} |"
        )
    return "\n".join(lines)


def write_csv(path: str, rows: list[Row]) -> None:
    fields = [
        "task",
        "side",
        "setting",
        "seconds",
        "cost",
        "unit",
        "ratio",
        "evaluations",
        "error",
        "error_kind",
        "reached",
        "note",
    ]
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(fields)
        for r in rows:
            w.writerow([getattr(r, f) for f in fields])


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="interleaved rounds (median)")
    ap.add_argument("--quick", action="store_true", help="2 rounds, 100 variants, fewer steps")
    ap.add_argument("--batch", type=int, default=None, help="variants in the batch (1000)")
    ap.add_argument("--markdown", action="store_true", help="print the table as Markdown")
    ap.add_argument("--csv", metavar="PATH", help="write the rows as CSV")
    args = ap.parse_args()
    require_peers()
    repeat = 2 if args.quick else max(1, args.repeat)
    count = args.batch if args.batch is not None else (100 if args.quick else 1000)

    start = time.perf_counter()
    v = versions()
    print("versions: " + ", ".join(f"{k} {x}" for k, x in v.items()))
    print(f"machine: {platform.machine()}, {len(os.sched_getaffinity(0))} CPUs available")
    rows, notes = section_inverse(repeat)
    r2, n2, chosen = section_direct(repeat, args.quick)
    rows += r2
    notes += n2
    scipy_s = next(r.seconds for r in r2 if r.side.startswith("scipy"))
    r3, n3 = section_batch(count, max(2, repeat // 2), chosen, scipy_s)
    rows += r3
    notes += n3

    print(f"\n{'side':<58} {'setting':<26} {'cost':>20} {'×':>7} {'evals':>9} {'error':>9}")
    for r in rows:
        evals = "" if r.evaluations is None else str(r.evaluations)
        print(
            f"{r.side[:58]:<58} {r.setting[:26]:<26} {fmt_cost(r):>20} {fmt_ratio(r):>7} "
            f"{evals:>9} {fmt_error(r):>9}"
        )
    for note in notes:
        print(f"- {note}")
    print(f"({time.perf_counter() - start:.0f} s in all; {repeat} interleaved rounds)")
    if args.markdown:
        print()
        print(markdown(rows, count))
    if args.csv:
        write_csv(args.csv, rows)
        print(f"wrote {args.csv}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
