"""The energy rule: a closed loop that cannot gain energy must not gain it in a run.

Two closed loops are known to keep or lose a mechanical energy H:

* passive motion (no controller): H = T + V, kinetic plus gravity's potential
  energy, is conserved;
* PD plus an exact gravity compensation with gains ≥ 0 (a law whose
  :meth:`~rrt_pin.control.Controller.feedback` is exactly the robot's G(q): the
  chapter's eq. (31) on its own arm, :class:`~rrt_pin.control.PDGravityController`
  on its model): H = T + ½·(q − qf)ᵀ·Kp·(q − qf) never grows (dH/dt = −q̇ᵀ·Kd·q̇ ≤ 0).

An integrator that is unstable for the step it takes (a fixed step too long for
the scene, or very loose tolerances) pumps energy into such a run: the state
stays finite for a while, and without this rule the run would come back as a
success with an error estimate in the metres. The rule: a run of either kind in
which H(t) − H(0) exceeds :data:`ENERGY_GROWTH` times the energy scale S raises
:class:`~rrt_pin.errors.DivergenceError` naming the first output time checked at
which it does and the velocity carrying most kinetic energy there. S is the
initial T (plus the initial spring energy ½·Δq0ᵀ·Kp·Δq0 of a PD law) plus
m·|g|·ℓ, with m the robot's mass and ℓ its reach (the distances between successive
joints and to each body's centre of mass, plus the prismatic joints' initial
extension): an exact run gains nothing, so gaining S means the numbers are no
longer a motion of the robot.

Checked: every output time of a single run (at most :data:`MAX_CHECKED` of them,
evenly spaced, and the last); :data:`BATCH_CHECKED` output times of each variant of
a batch (then the failing variant's as a single run's, to name the first; a batch
with ``keep="final"`` has its last output time only). Other laws may add
energy legitimately and are not checked; nor is a compiled batch whose variants
have parameters of their own.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.errors import DivergenceError
from rrt_pin.memory import check_data

if TYPE_CHECKING:
    from rrt_pin.robot import Robot

__all__ = [
    "BATCH_CHECKED",
    "ENERGY_GROWTH",
    "MAX_CHECKED",
    "check_energy",
    "check_energy_batch",
]

#: The energy a passive or PD-with-exact-gravity run may gain, in units of its scale S.
ENERGY_GROWTH = 1.0
#: Output times of a single run checked at most (evenly spaced, the last included).
MAX_CHECKED = 4096


class _Rule:
    """H(q, q̇) of one kind of closed loop on one robot, and its scale."""

    def __init__(self, robot: Robot, kp: np.ndarray | None, qf: np.ndarray | None) -> None:
        model = robot.model
        self.robot = robot
        self.model = model
        check_data(model, f"the energy of a {model.nv}-joint model")
        self.data = model.createData()
        self.kp, self.qf = kp, qf
        armature = getattr(model, "armature", None)
        self.armature = np.asarray(armature, dtype=float) if armature is not None else None
        mass = sum(float(model.inertias[i].mass) for i in range(1, model.njoints))
        reach = sum(
            float(np.linalg.norm(model.jointPlacements[i].translation))
            + float(np.linalg.norm(model.inertias[i].lever))
            for i in range(1, model.njoints)
        )
        self.weight_reach = mass * float(np.linalg.norm(model.gravity.linear)) * reach
        self.prismatic = np.array([unit == "m" for unit in robot.coordinate_units], dtype=bool)

    def kinetic(self, q: np.ndarray, v: np.ndarray) -> float:
        import pinocchio as pin

        x = self.robot.configuration(q)
        t = float(pin.computeKineticEnergy(self.model, self.data, x, v))
        if self.armature is not None and self.armature.shape == v.shape:
            t += 0.5 * float(self.armature @ (v * v))
        return t

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """H at one state [J]."""
        import pinocchio as pin

        h = self.kinetic(q, v)
        if self.kp is None:
            h += float(
                pin.computePotentialEnergy(self.model, self.data, self.robot.configuration(q))
            )
        else:
            d = q - self.qf
            h += 0.5 * float(d @ (self.kp * d))
        return h

    def scale(self, q0: np.ndarray, v0: np.ndarray) -> float:
        """S at the initial state [J]."""
        s = self.kinetic(q0, v0) + self.weight_reach
        if self.kp is not None:
            d = q0 - self.qf
            s += 0.5 * float(d @ (self.kp * d))
        if self.prismatic.any():
            extension = float(np.abs(q0[self.prismatic]).sum())
            mass = sum(float(self.model.inertias[i].mass) for i in range(1, self.model.njoints))
            s += mass * float(np.linalg.norm(self.model.gravity.linear)) * extension
        return max(s, np.finfo(float).tiny)

    def fastest(self, q: np.ndarray, v: np.ndarray) -> int:
        """The velocity carrying most kinetic energy (diagonal of M)."""
        import pinocchio as pin

        m = np.diag(pin.crba(self.model, self.data, self.robot.configuration(q)))
        return int(np.argmax(np.abs(m) * v * v))


def rule_for(robot: Robot, law: Any) -> _Rule | None:
    """The energy rule of ``law`` (None: passive motion) on ``robot``, or None if it has none."""
    if law is None:
        return _Rule(robot, None, None)
    feedback = law.feedback()
    if feedback is None or not feedback.exact_for(robot):
        return None
    kp, kd = np.asarray(feedback.kp, dtype=float), np.asarray(feedback.kd, dtype=float)
    if (kp < 0).any() or (kd < 0).any():
        return None
    return _Rule(robot, kp, np.asarray(feedback.qf, dtype=float))


#: Output times of each variant of a batch checked at first (evenly spaced, the last
#: included); a variant found gaining energy is then checked as a single run.
BATCH_CHECKED = 64


def _rows(count: int, most: int = MAX_CHECKED) -> np.ndarray:
    if count <= most:
        return np.arange(count)
    return np.unique(np.linspace(0, count - 1, most).round().astype(int))


def _first_excess(
    rule: _Rule,
    t: np.ndarray,
    q: np.ndarray,
    v: np.ndarray,
    q0: np.ndarray,
    v0: np.ndarray,
    most: int = MAX_CHECKED,
) -> tuple[int, float, float, float] | None:
    """(row, H(0), H(row), S) of the first checked row gaining more than allowed, else None."""
    h0 = rule.energy(q0, v0)
    s = rule.scale(q0, v0)
    bound = h0 + ENERGY_GROWTH * s
    for i in _rows(t.size, most):
        h = rule.energy(q[i], v[i])
        if not h <= bound:  # NaN too (a non-finite state is named by the integrator)
            return int(i), h0, h, s
    return None


def _error(
    rule: _Rule,
    t: float,
    q: np.ndarray,
    v: np.ndarray,
    h0: float,
    h: float,
    s: float,
    names: Sequence[str],
    what: str,
    where: str,
    how: str,
) -> DivergenceError:
    k = rule.fastest(q, v)
    return DivergenceError(
        t,
        f"{names[k]}{where}",
        f"the energy grew from {h0:.3g} J to {h:.3g} J, more than the {s:.3g} J allowed for "
        f"{what}, which cannot gain energy: the integration is unstable; {how}",
    )


def _how(result: Any) -> str:
    if result.step is not None:
        return f"use a step shorter than {result.step:.3g} s (or an adaptive method)"
    return "use tighter tolerances (rtol, atol)"


def _what(rule: _Rule) -> str:
    return "passive motion" if rule.kp is None else "a PD law with exact gravity compensation"


def check_energy(result: Any, robot: Robot, law: Any) -> None:
    """Apply the rule to a single run (``law`` None: passive motion).

    Raises:
        DivergenceError: the run gained more energy than the rule allows.
    """
    rule = rule_for(robot, law)
    if rule is None or result.t.size < 2:
        return
    q, v = np.asarray(result.q), np.asarray(result.qd)
    found = _first_excess(rule, result.t, q, v, q[0], v[0])
    if found is not None:
        i, h0, h, s = found
        raise _error(
            rule,
            float(result.t[i]),
            q[i],
            v[i],
            h0,
            h,
            s,
            result.qd_names,
            _what(rule),
            "",
            _how(result),
        )


def check_energy_batch(
    result: Any, robot: Robot, laws: Sequence[Any], q0s: np.ndarray, qd0s: np.ndarray
) -> None:
    """Apply the rule to each variant of a batch (a law None: passive motion).

    Raises:
        DivergenceError: a variant gained more energy than the rule allows (named).
    """
    rules: dict[int, _Rule | None] = {}
    q, v = np.asarray(result.q), np.asarray(result.qd)  # (B, T, nv)
    for b, law in enumerate(laws):
        key = id(law)
        if key not in rules:
            rules[key] = rule_for(robot, law)
        rule = rules[key]
        if rule is None:
            continue
        some = _first_excess(rule, result.t, q[b], v[b], q0s[b], qd0s[b], BATCH_CHECKED)
        if some is None:
            continue
        found = _first_excess(rule, result.t, q[b], v[b], q0s[b], qd0s[b]) or some
        i, h0, h, s = found
        raise _error(
            rule, float(result.t[i]), q[b, i], v[b, i], h0, h, s, result.qd_names,
            _what(rule), f" (variant {b})", _how(result),
        )  # fmt: skip
