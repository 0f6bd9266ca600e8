"""A run's physical model, as the front doors use it: made once, handed over, and reported.

:func:`run_physics` reads the robot's limits and losses once a run
(:func:`rrt_pin.robot.limits.physical_model`, with the switches ``effort_limits``,
``position_limits``, ``losses``), sets the compliant limits' stiffness from each joint's
effective inertia at q0 (:func:`limit_inertia`), refuses a fixed step too long for it and warns (:class:`LimitWarning`)
when a start or a target lies outside a joint's position limits. The backends apply
:attr:`RunPhysics.applied` (None: nothing, the law's run bit for bit) and return the
actuators' efforts (the law's, saturated); :func:`with_limits` and
:func:`batch_limits` then measure what each run crossed at its output samples
(:mod:`rrt_pin.simulate.crossings`) against the robot's stated limits.
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.robot.limits import (
    LimitWarning,
    Physical,
    check_step,
    joint_names,
    outside_limits,
    physical_model,
)
from rrt_pin.simulate.crossings import batch_limit_events, limit_events
from rrt_pin.simulate.extremes import peak
from rrt_pin.simulate.methods import FIXED_STEP, SYMPLECTIC

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate.options import Options

__all__ = [
    "RunPhysics",
    "batch_limits",
    "demanded",
    "energy_law",
    "limit_inertia",
    "outside_messages",
    "physics_facts",
    "run_physics",
    "with_limits",
]


@dataclass(frozen=True, eq=False)
class RunPhysics:
    """A run's physical model.

    Attributes:
        applied: what the joints get beyond the law (None: nothing).
        stated: the robot's stated limits, all switches on (what events are measured against).
        joints: each coordinate's joint name (nv,).
        units: each coordinate's unit, ``rad`` or ``m`` (nv,).
    """

    applied: Physical | None
    stated: Physical
    joints: list[str]
    units: list[str]

    @property
    def measures(self) -> bool:
        """Whether some limit is stated (else a run has no events to measure)."""
        s = self.stated
        return bool(s.has_positions or np.isfinite(s.effort).any() or np.isfinite(s.velocity).any())

    @property
    def needs_demand(self) -> bool:
        """Whether effort events need the law's demanded efforts."""
        return bool(np.isfinite(self.stated.effort).any())


def _switch(name: str, value: Any) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise InputError(f"{name} must be True or False, not {value!r}")
    return bool(value)


def run_physics(
    robot: Robot,
    q0s: np.ndarray,
    laws: Sequence[Any],
    options: Options,
    *,
    effort_limits: Any = True,
    position_limits: Any = True,
    losses: Any = True,
    name: str = "q0",
) -> RunPhysics:
    """The run's physical model (see the module), the step checked and the starts looked at.

    Args:
        robot: the robot.
        q0s: initial coordinates (B, nv) [rad or m]; the first sets the limits' stiffness.
        laws: the laws (their ``qf``, if any, is looked at too).
        options: the run's options (a fixed step is checked).
        effort_limits: saturate the law's efforts at the URDF's ``effort``.
        position_limits: apply the URDF's ``lower``/``upper`` (compliant).
        losses: apply the URDF's ``<dynamics damping friction>``.
        name: the initial coordinates' argument, for messages.

    Raises:
        InputError: a bad switch, bad limits in the URDF, or a fixed step too long.
    """
    switches = {
        "effort_limits": _switch("effort_limits", effort_limits),
        "position_limits": _switch("position_limits", position_limits),
        "losses": _switch("losses", losses),
    }
    joints = joint_names(robot)
    stated = physical_model(robot)
    run = RunPhysics(None, stated, joints, list(robot.coordinate_units))
    if not stated.active:  # nothing stated (the chapter's arm): nothing to apply or warn of
        return run
    p = stated if all(switches.values()) else physical_model(robot, **switches)
    if p.active:
        p = p.at(limit_inertia(robot, q0s[0]))
        if options.method.family in (FIXED_STEP, SYMPLECTIC):
            check_step(options.step, p, joints)
        run = replace(run, applied=p)
    _warn_outside(robot, stated, q0s, laws, joints, name)
    return run


def _warn_outside(
    robot: Robot,
    stated: Physical,
    q0s: np.ndarray,
    laws: Sequence[Any],
    joints: list[str],
    name: str,
) -> None:
    """Warn once about a start or a target outside a joint's position limits."""
    if not stated.has_positions:
        return
    targets = [qf for qf in (getattr(law, "qf", None) for law in laws) if qf is not None]
    for what, rows in ((name, q0s), ("qf", targets)):
        if len(rows) == 0:
            continue
        q = np.asarray(rows, dtype=float)
        bad = np.flatnonzero(((q < stated.lower) | (q > stated.upper)).any(axis=1))
        if bad.size:
            i = int(bad[0])
            label = what if len(rows) == 1 else f"{what}[{i}]"
            line = outside_messages(robot, {label: q[i]})[0]
            warnings.warn(line, LimitWarning, stacklevel=4)


def demanded(
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    tau: np.ndarray,
    laws: Sequence[Any],
    applied: Physical | None,
) -> np.ndarray:
    """The laws' efforts before saturation at the samples (B, T, nv) [N·m or N].

    ``tau``: the efforts applied (the laws', saturated at ``applied``'s effort limits);
    elsewhere they are the demand, which is computed again (the law's ``efforts_many``)
    only at the samples where some effort is at its limit (the one rule: single runs'
    events use it too).
    """
    if applied is None or not np.isfinite(applied.effort).any():
        return tau
    out = tau
    for b, law in enumerate(laws):
        if law is None or not tau.shape[1] or (peak(tau[b : b + 1])[0] < applied.effort).all():
            continue  # no sample, or no effort at its limit (one pass over the samples)
        rows = np.flatnonzero((np.abs(tau[b]) >= applied.effort).any(axis=1))
        if rows.size == 0:
            continue
        if out is tau:
            out = tau.copy()
        with np.errstate(all="ignore"):
            out[b, rows] = np.asarray(law.efforts_many(t[rows], q[b, rows], qd[b, rows]), float)
    return out


def _demanded(
    t: np.ndarray, q: np.ndarray, qd: np.ndarray, tau: np.ndarray | None, law: Any, rp: RunPhysics
) -> np.ndarray | None:
    """One run's demanded efforts at the samples (T, nv) (:func:`demanded`), None if unneeded."""
    if not rp.needs_demand:
        return None
    if tau is not None:
        return demanded(t, q[None], qd[None], tau[None], [law], rp.applied)[0]
    if law is None:
        return np.zeros_like(q)
    with np.errstate(all="ignore"):
        return np.asarray(law.efforts_many(t, q, qd), dtype=float)


def with_limits(result: Any, rp: RunPhysics, law: Any) -> Any:
    """One run's result with its limit events (``law``: the law, to recompute demands)."""
    if not rp.measures:
        return result
    demanded = _demanded(result.t, result.q, result.qd, result.tau, law, rp)
    events = limit_events(result.t, result.q, result.qd, demanded, rp.stated, rp.joints, rp.units)
    object.__setattr__(result, "limits", events)  # a result just made, shared with no one
    return result


def batch_limits(
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    tau: np.ndarray | None,
    laws: Sequence[Any],
    rp: RunPhysics,
) -> tuple[tuple[Any, ...], ...]:
    """Each variant's limit events from its samples (B, T, nv)."""
    if not rp.measures:
        return ()
    demand = None
    if rp.needs_demand and tau is not None:
        demand = demanded(t, q, qd, tau, laws, rp.applied)
    elif rp.needs_demand:
        demand = np.array([_demanded(t, q[b], qd[b], None, law, rp) for b, law in enumerate(laws)])
    events = batch_limit_events(t, q, qd, demand, rp.stated, rp.joints, rp.units)
    return tuple(events)


class _Unruled:
    """A stand-in law with no energy rule (a saturated law may gain energy legitimately)."""

    def feedback(self) -> None:
        """No feedback: no rule."""
        return None


_UNRULED = _Unruled()


def energy_law(law: Any, events: Sequence[Any], rp: RunPhysics) -> Any:
    """The law for the energy rule: ``law``, or none when the run saturated its efforts.

    Saturated gravity compensation lets the robot fall: a PD law's energy may then grow.
    """
    p = rp.applied
    if p is None or law is None or not np.isfinite(p.effort).any():
        return law
    if any(e.kind == "effort" for e in events):
        return _UNRULED
    return law


def outside_messages(robot: Robot, named: dict[str, Any]) -> list[str]:
    """One line per named coordinates (``{"q0": q0, "qf": qf}``) outside a position limit.

    E.g. "q0 of joint 'elbow_joint' is 4.2 rad, outside [-3.14, 3.14]: given in degrees?"
    (the first joint outside; a value past π rad asks whether it was given in degrees).
    """
    stated = physical_model(robot)
    joints = joint_names(robot)
    lines = []
    for label, q in named.items():
        if q is None:
            continue
        found = outside_limits(np.asarray(q, dtype=float), stated, joints)
        if found:
            joint, value, lo, hi = found[0]
            unit = robot.coordinate_units[joints.index(joint)]
            hint = ": given in degrees?" if unit == "rad" and abs(value) > np.pi else ""
            lines.append(
                f"{label} of joint {joint!r} is {value:.6g} {unit}, outside "
                f"[{lo:.3g}, {hi:.3g}]{hint}"
            )
    return lines


def limit_inertia(robot: Robot, q0: Any) -> np.ndarray:
    """Each joint's effective inertia at ``q0``, 1 / (M⁻¹)_kk [kg·m² or kg] (nv,).

    What a joint's position limit pushes against when the other joints move freely (as
    MuJoCo's joint-limit constraints see it): the compliant limit set from it is
    critically damped on that joint at the run's start, whatever the coupling.
    """
    import pinocchio as pin

    model = robot.model
    x = robot.configuration(np.asarray(q0, dtype=float))
    return 1.0 / np.diag(pin.computeMinverse(model, model.createData(), x))  # its upper triangle


def physics_facts(robot: Robot, q0: Any, **switches: bool) -> dict:
    """The run's physical model for metadata: switches, parameters, what was not given."""
    if not physical_model(robot).active:  # the chapter's arm, or a URDF that states none
        return {"applied": False, "why": f"{robot.name} states no binding limit"}
    p = physical_model(robot, **switches)
    if p.active:
        p = p.at(limit_inertia(robot, q0))
    return {"switches": dict(switches), **p.parameters()}
