"""The energy rule: a closed loop that cannot gain energy must not gain it in a run.

Two closed loops are known to keep or lose a mechanical energy H:

* passive motion (no controller): H = T + V, kinetic plus gravity's potential
  energy, is conserved;
* PD plus an exact gravity compensation with gains ≥ 0 (a law whose
  :meth:`~rrt_pin.simulate.control.Controller.feedback` is exactly the robot's G(q): the
  chapter's eq. (31) on its own arm, :class:`~rrt_pin.simulate.control.PDGravityController`
  on its model): H = T + ½·(q − qf)ᵀ·Kp·(q − qf) never grows (dH/dt = −q̇ᵀ·Kd·q̇ ≤ 0).

An integrator that is unstable for the step it takes (a fixed step too long for
the scene, or very loose tolerances) pumps energy into such a run: the state
stays finite for a while, and without this rule the run would come back as a
success with an error estimate in the metres. The rule: a run of either kind in
which H(t) − H(0) exceeds :data:`ENERGY_GROWTH` times the energy scale S raises
:class:`~rrt_pin.core.errors.DivergenceError` naming the first output time checked at
which it does and the velocity carrying most kinetic energy there. S is the
initial T (plus the initial spring energy ½·Δq0ᵀ·Kp·Δq0 of a PD law) plus
m·|g|·ℓ, with m the robot's mass and ℓ its reach (the distances between successive
joints and to each body's centre of mass, plus the prismatic joints' initial
extension): an exact run gains nothing, so gaining S means the numbers are no
longer a motion of the robot.

Checked: runs of fixed-step methods, and of adaptive ones at an rtol looser than
:data:`ERROR_CONTROLLED_RTOL` (tighter, their error control rules such a gain out);
:data:`SINGLE_CHECKED` output times of a single run and
:data:`BATCH_CHECKED` of each variant of a batch, evenly spaced with the last
included (a run that gains energy by instability keeps it); a run found gaining is
then checked at every output time (at most :data:`MAX_CHECKED`) to name the first.
A batch with ``keep="final"`` has its last output time only. Other laws may add
energy legitimately and are not checked; nor is a compiled batch whose variants
have parameters of their own.
"""

from __future__ import annotations

import threading
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core import backends
from rrt_pin.core.errors import DivergenceError
from rrt_pin.core.identity import IdentityCache
from rrt_pin.core.memory import check_data

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot

__all__ = [
    "BATCH_CHECKED",
    "COMPILED_CHECKED",
    "ENERGY_GROWTH",
    "ERROR_CONTROLLED_RTOL",
    "MAX_CHECKED",
    "SINGLE_CHECKED",
    "check_energy",
    "check_energy_batch",
]

#: The energy a passive or PD-with-exact-gravity run may gain, in units of its scale S.
ENERGY_GROWTH = 1.0
#: Adaptive runs at this rtol or tighter are held by their error control, not checked.
ERROR_CONTROLLED_RTOL = 1e-6
#: Output times of a single run checked at first, one at a time with Pinocchio (evenly
#: spaced, the last included): about 5 % of a default Pinocchio run. A compiled run of
#: the chapter's arm under a PD law checks :data:`COMPILED_CHECKED` at once (its M(q)).
SINGLE_CHECKED = 32
#: Output times of a compiled run of the chapter's arm under a PD law checked at once
#: (its compiled M(q); evenly spaced, the last included).
COMPILED_CHECKED = 256
#: Output times of a run checked at most once it was found gaining energy, to name
#: the first (evenly spaced, the last included).
MAX_CHECKED = 4096


class _Rule:
    """H(q, q̇) of one kind of closed loop on one robot, and its scale."""

    def __init__(self, robot: Robot, kp: np.ndarray | None, qf: np.ndarray | None) -> None:
        model = robot.model
        self.robot = robot
        self.model = model
        check_data(model, f"the energy of a {model.nv}-joint model")
        self._local = threading.local()  # one Pinocchio Data a thread: rules are shared
        self.kp, self.qf = kp, qf
        armature = getattr(model, "armature", None)
        self.armature = np.asarray(armature, dtype=float) if armature is not None else None
        mass = sum(float(model.inertias[i].mass) for i in range(1, model.njoints))
        reach = sum(
            float(np.linalg.norm(model.jointPlacements[i].translation))
            + float(np.linalg.norm(model.inertias[i].lever))
            for i in range(1, model.njoints)
        )
        self.weight = mass * float(np.linalg.norm(model.gravity.linear))  # [N]
        self.weight_reach = self.weight * reach
        self.prismatic = np.array([unit == "m" for unit in robot.coordinate_units], dtype=bool)
        #: Pinocchio's configuration of joint coordinates (cos, sin of continuous joints).
        self.configuration = robot.configuration if robot.has_continuous_joints else _same

    @property
    def data(self) -> Any:
        """This thread's Pinocchio Data of the model."""
        data = getattr(self._local, "data", None)
        if data is None:
            data = self._local.data = self.model.createData()
        return data

    def kinetic(self, q: np.ndarray, v: np.ndarray) -> float:
        import pinocchio as pin

        x = self.configuration(q)
        t = float(pin.computeKineticEnergy(self.model, self.data, x, v))
        if self.armature is not None and self.armature.shape == v.shape:
            t += 0.5 * float(self.armature @ (v * v))
        return t

    def energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """H at one state [J]."""
        import pinocchio as pin

        h = self.kinetic(q, v)
        if self.kp is None:
            h += float(pin.computePotentialEnergy(self.model, self.data, self.configuration(q)))
        else:
            d = q - self.qf
            h += 0.5 * float(d @ (self.kp * d))
        return h

    def energies(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """H at the states ``q``, ``v`` (rows) [J], one state at a time (Pinocchio)."""
        return np.array([self.energy(a, b) for a, b in zip(q, v, strict=True)])

    def energies_compiled(self, q: np.ndarray, v: np.ndarray, params: Any) -> np.ndarray | None:
        """H at every state at once from the arm's compiled M(q) [J], None where it has none.

        Only for the chapter's arm (of ``params``) under a PD law, H = T + spring
        energy, after a compiled run (its machine code is loaded: nothing compiles here).
        """
        if self.kp is None or q.shape[-1] != 3:
            return None
        mass_matrix = backends.get("compiled").entry("mass_matrix")
        m = mass_matrix(np.ascontiguousarray(q), params)
        d = q - self.qf
        return 0.5 * np.einsum("ki,kij,kj->k", v, m, v) + 0.5 * (d * d) @ self.kp

    def scale(self, q0: np.ndarray, v0: np.ndarray, h0: float) -> float:
        """S at the initial state [J] (``h0``: H there)."""
        s = h0 + self.weight_reach
        if self.kp is None:  # H holds the potential energy; S counts T only
            s = self.kinetic(q0, v0) + self.weight_reach
        if self.prismatic.any():
            s += self.weight * float(np.abs(q0[self.prismatic]).sum())
        return max(s, np.finfo(float).tiny)

    def fastest(self, q: np.ndarray, v: np.ndarray) -> int:
        """The velocity carrying most kinetic energy (diagonal of M)."""
        import pinocchio as pin

        m = np.diag(pin.crba(self.model, self.data, self.configuration(q)))
        return int(np.argmax(np.abs(m) * v * v))


def _same(q: np.ndarray) -> np.ndarray:
    return q


def rule_for(robot: Robot, law: Any) -> _Rule | None:
    """The energy rule of ``law`` (None: passive motion) on ``robot``, or None if it has none.

    Kept for the last few (robot, law) pairs: a law's gains and a robot's model are
    fixed once made (a Pinocchio model changed in place is a new robot's business:
    :func:`rrt_pin.simulate.api.as_robot` makes one).
    """
    kept = _RULES.get(robot, law)
    if kept is not None:
        return kept[0]
    return _RULES.put(robot, law, value=(_rule_for(robot, law),))[0]


#: The rules of the last few (robot, law) pairs, by identity.
_RULES: IdentityCache[tuple[_Rule | None]] = IdentityCache(16)


def _rule_for(robot: Robot, law: Any) -> _Rule | None:
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
    """At most ``most`` rows of ``count``, evenly spaced, the first and the last included."""
    if count <= most:
        return np.arange(count)
    return np.unique(np.arange(most) * (count - 1) // (most - 1))


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
    s = rule.scale(q0, v0, h0)
    bound = h0 + ENERGY_GROWTH * s
    rows = _rows(t.size, most)
    if rows.size > 1:
        rows = rows[1:]  # row 0 is the initial state: H there is h0
    h = rule.energies(q[rows], v[rows])
    over = np.flatnonzero(~(h <= bound))  # NaN too (a non-finite state is named by the integrator)
    if over.size == 0:
        return None
    k = int(over[0])
    return int(rows[k]), h0, float(h[k]), s


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


def _held_by_error_control(result: Any) -> bool:
    """Whether the run's own error control rules out an energy gain of the order of S.

    An adaptive method at rtol ≤ :data:`ERROR_CONTROLLED_RTOL` keeps each step's local
    error within its tolerances (or stops, naming why): pumping in energy of the
    order of the run's whole scale would take errors many orders above them. Fixed
    steps and loose tolerances have no such bound and are checked.
    """
    rtol = getattr(result, "rtol", None)
    return result.step is None and rtol is not None and rtol <= ERROR_CONTROLLED_RTOL


def _how(result: Any) -> str:
    if result.step is not None:
        return f"use a step shorter than {result.step:.3g} s (or an adaptive method)"
    return "use tighter tolerances (rtol, atol)"


def _what(rule: _Rule) -> str:
    return "passive motion" if rule.kp is None else "a PD law with exact gravity compensation"


def check_energy(result: Any, robot: Robot, law: Any, params: Any = None) -> None:
    """Apply the rule to a single run (``law`` None: passive motion).

    Args:
        result: the run.
        robot: its robot.
        law: its controller (None: passive motion).
        params: the chapter arm's parameters of a compiled run (its M(q) then serves
            every output time at once), else None.

    Raises:
        DivergenceError: the run gained more energy than the rule allows.
    """
    if _held_by_error_control(result):
        return
    rule = rule_for(robot, law)
    if rule is None or result.t.size < 2:
        return
    q, v = np.asarray(result.q), np.asarray(result.qd)
    found = None
    every = None
    if params is not None and result.backend == "compiled":
        rows = _rows(result.t.size, COMPILED_CHECKED)[1:]
        every = rule.energies_compiled(q[rows], v[rows], params)
    if every is not None:
        h0 = rule.energy(q[0], v[0])
        s = rule.scale(q[0], v[0], h0)
        over = np.flatnonzero(~(every <= h0 + ENERGY_GROWTH * s))
        if over.size:
            k = int(over[0])
            found = int(rows[k]), h0, float(every[k]), s
    else:
        found = _first_excess(rule, result.t, q, v, q[0], v[0], SINGLE_CHECKED)
        if found is not None:  # then every output time (up to MAX_CHECKED), to name the first
            found = _first_excess(rule, result.t, q, v, q[0], v[0]) or found
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
    if _held_by_error_control(result):
        return
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
