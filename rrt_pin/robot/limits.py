"""A robot's physical limits and losses from its URDF: what a simulation applies beyond the law.

:func:`physical_model` reads a Pinocchio model's ``<limit lower upper effort velocity>``
and ``<dynamics damping friction>`` (``model.lowerPositionLimit``, ``effortLimit``, …) into
a :class:`Physical`, one value per joint coordinate, and the run's switches. Every backend
applies the same model (:func:`applied_efforts` is its definition, in numpy):

* **effort limits**: the law's efforts are saturated, τ = clip(τ_law, −e, e);
* **viscous damping**: −d·q̇;
* **Coulomb friction**, regularised: −f·tanh(q̇ / :data:`FRICTION_VELOCITY`);
* **position limits**, compliant (a spring–damper that only pushes, as MuJoCo's soft
  constraints): below ``lower``, τ = max(0, k·(lower − q) − b·q̇); above ``upper``,
  τ = min(0, k·(upper − q) − b·q̇); k = m·ω², b = 2·m·ω with ω = :data:`LIMIT_OMEGA` and m
  the joint's effective inertia 1/(M⁻¹)_kk at the run's start (what the joint pushes
  against when the others move freely, as in MuJoCo's joint limits: critically damped,
  ~1/ω to settle);
* **velocity limits**: reported, not enforced.

"Not given" (URDFs often write ``lower="0" upper="0" effort="0" velocity="0"``): a zero
range is no position limit, a zero (or infinite) effort or velocity no limit. Continuous
joints have no position limit.

Units: SI (rad or m, N·m or N, N·m·s/rad or N·s/m).
"""

from __future__ import annotations

import functools
import math
import weakref
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core import text
from rrt_pin.core.errors import InputError

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.robot.robot import Robot

__all__ = [
    "FRICTION_VELOCITY",
    "LIMIT_DAMPING_RATIO",
    "LIMIT_OMEGA",
    "LimitWarning",
    "MAX_STEP_OMEGA",
    "Physical",
    "applied_efforts",
    "applied_jacobian",
    "applier",
    "check_step",
    "gravity_bound",
    "inactive",
    "joint_names",
    "losses",
    "outside_limits",
    "physical_model",
    "saturated",
    "within",
]

#: The velocity below which Coulomb friction fades linearly-ish to zero: τ = −f·tanh(q̇/v) [rad/s or m/s].
FRICTION_VELOCITY = 1e-3
#: The natural frequency of the compliant position limits [rad/s] (time constant 1/ω).
LIMIT_OMEGA = 200.0
#: Their damping ratio (critical: no bounce).
LIMIT_DAMPING_RATIO = 1.0
#: The longest fixed step a run with position limits may take, as h·ω (h ≤ 0.5/ω).
MAX_STEP_OMEGA = 0.5


class LimitWarning(UserWarning):
    """A run starts or aims outside a joint's position limits (given in degrees?)."""


@dataclass(frozen=True, eq=False)
class Physical:
    """What a run applies beyond its law, one value per joint coordinate (nv,).

    Attributes:
        lower: position lower limits [rad or m] (−inf: none).
        upper: position upper limits [rad or m] (+inf: none).
        effort: effort limits [N·m or N] (inf: none).
        velocity: velocity limits [rad/s or m/s] (inf: none; reported only).
        damping: viscous damping [N·m·s/rad or N·s/m] (0: none).
        friction: Coulomb friction [N·m or N] (0: none).
        stiffness: the position limits' k [N·m/rad or N/m] (set by :meth:`at`).
        limit_damping: their b [N·m·s/rad or N·s/m] (set by :meth:`at`).
        not_given: the joints whose URDF wrote a zero range or effort (said in ``-v``).
    """

    lower: np.ndarray
    upper: np.ndarray
    effort: np.ndarray
    velocity: np.ndarray
    damping: np.ndarray
    friction: np.ndarray
    stiffness: np.ndarray = field(default=None)  # type: ignore[assignment]
    limit_damping: np.ndarray = field(default=None)  # type: ignore[assignment]
    not_given: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        n = self.lower.shape[0]
        for name in ("stiffness", "limit_damping"):
            if getattr(self, name) is None:
                object.__setattr__(self, name, np.zeros(n))
        for name in ("lower", "upper", "effort", "velocity", "damping", "friction",
                     "stiffness", "limit_damping"):  # fmt: skip
            arr = np.array(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def nv(self) -> int:
        """Joint coordinates."""
        return int(self.lower.shape[0])

    @functools.cached_property  # the arrays are read-only: computed once
    def has_positions(self) -> bool:
        """Whether a position limit applies to some joint."""
        return bool(np.isfinite(self.lower).any() or np.isfinite(self.upper).any())

    @functools.cached_property
    def active(self) -> bool:
        """Whether anything is applied (else a run is the law's alone, bit for bit)."""
        return bool(
            self.has_positions
            or np.isfinite(self.effort).any()
            or (self.damping > 0).any()
            or (self.friction > 0).any()
        )

    def at(self, inertia: np.ndarray) -> Physical:
        """This model with the position limits' stiffness and damping for these inertias.

        Args:
            inertia: each joint's effective inertia, 1/(M⁻¹)_kk [kg·m² or kg] (nv,).
        """
        m = np.asarray(inertia, dtype=float)
        limited = np.isfinite(self.lower) | np.isfinite(self.upper)
        k = np.where(limited, m * LIMIT_OMEGA**2, 0.0)
        b = np.where(limited, 2.0 * LIMIT_DAMPING_RATIO * m * LIMIT_OMEGA, 0.0)
        return replace(self, stiffness=k, limit_damping=b)

    def parameters(self) -> dict:
        """The model's parameters and values for a run's metadata (JSON-ready; inf: None)."""

        def values(a: np.ndarray) -> list[float | None]:
            return [float(x) if np.isfinite(x) else None for x in a]

        return {
            "applied": self.active,
            "position_limits": "compliant: a spring-damper outside [lower, upper] that only "
            "pushes back, k = m·omega², b = 2·zeta·m·omega, m = 1/(M^-1)_kk at the run's start",
            "omega": LIMIT_OMEGA,
            "omega_unit": "rad/s",
            "damping_ratio": LIMIT_DAMPING_RATIO,
            "friction": "Coulomb, regularised: -f·tanh(qd / v)",
            "friction_velocity": FRICTION_VELOCITY,
            "friction_velocity_unit": "rad/s or m/s",
            "velocity_limits": "reported, not enforced",
            "lower": values(self.lower),
            "upper": values(self.upper),
            "effort": values(self.effort),
            "velocity": values(self.velocity),
            "damping": [float(x) for x in self.damping],
            "friction_coefficient": [float(x) for x in self.friction],
            "stiffness": [float(x) for x in self.stiffness],
            "limit_damping": [float(x) for x in self.limit_damping],
            "not_given": list(self.not_given),
        }

    def as_array(self) -> np.ndarray:
        """(8, nv): lower, upper, effort, damping, friction, stiffness, limit damping, velocity.

        The layout the compiled integrators read.
        """
        return np.ascontiguousarray(
            np.vstack(
                [
                    self.lower,
                    self.upper,
                    self.effort,
                    self.damping,
                    self.friction,
                    self.stiffness,
                    self.limit_damping,
                    self.velocity,
                ]
            )  # fmt: skip
        )


def _check(name: str, values: np.ndarray, joints: list[str], negative_ok: bool = False) -> None:
    for k, v in enumerate(values):
        if math.isnan(v):
            raise InputError(f"{name} of joint {joints[k]!r} is NaN")
        if not negative_ok and v < 0.0:
            raise InputError(f"{name} of joint {joints[k]!r} is {v:g}: it must be >= 0")


def physical_model(
    robot: Robot,
    *,
    effort_limits: bool = True,
    position_limits: bool = True,
    losses: bool = True,
    model: pin.Model | None = None,
) -> Physical:
    """The limits and losses ``robot``'s model states, with the run's switches applied.

    Args:
        robot: the robot (its Pinocchio model, the URDF's values).
        effort_limits: saturate the law's efforts at the URDF's ``effort``.
        position_limits: apply the URDF's ``lower``/``upper`` (compliant, see the module).
        losses: apply the URDF's ``<dynamics damping friction>``.
        model: the model to read (default ``robot.model``).

    Returns:
        The model (stiffness not set yet: :meth:`Physical.at`); the chapter's arm gets an
        inactive one (:func:`inactive`): its URDF states no binding limit.

    Raises:
        InputError: a limit with lower > upper, a negative damping, friction, effort or
            velocity limit, or a NaN (the joint named).
    """
    if robot.is_chapter_arm:  # before robot.model: the arm's needs no Pinocchio model
        return inactive(robot.nv)
    m = robot.model if model is None else model
    # The model's arrays are read each call (a user may change them between runs); the
    # model built from them is kept per robot, keyed by their values and the switches.
    read = [np.asarray(a, dtype=float) for a in (m.lowerPositionLimit, m.upperPositionLimit,
                                                 m.effortLimit, m.velocityLimit, m.damping,
                                                 m.friction)]  # fmt: skip
    key = (effort_limits, position_limits, losses, b"".join(a.tobytes() for a in read))
    memo = _MEMO.setdefault(robot, {})
    found = memo.get(key)
    if found is None:
        found = _physical(robot, m, read, effort_limits, position_limits, losses)
        if len(memo) >= _MEMO_SIZE:
            memo.clear()
        memo[key] = found
    return found


#: Physical models already read, per robot (weakly: they go with the robot).
_MEMO: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
_MEMO_SIZE = 16


def _physical(
    robot: Robot,
    m: pin.Model,
    read: list[np.ndarray],
    effort_limits: bool,
    position_limits: bool,
    losses: bool,
) -> Physical:
    """:func:`physical_model` read from ``m``'s arrays (``read``, in the order of the key)."""
    nv = robot.nv
    if _chapter_urdf(robot, m):
        return inactive(nv)
    names = joint_names(robot)
    lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
    lows, highs = read[0], read[1]
    not_given = []
    for j in robot.joints:
        if j.kind == "continuous" or j.nq != j.nv:
            continue
        lo, hi = float(lows[j.idx_q]), float(highs[j.idx_q])
        if math.isnan(lo) or math.isnan(hi):
            raise InputError(f"the position limits of joint {j.name!r} are NaN")
        if lo > hi:
            raise InputError(
                f"joint {j.name!r} has lower limit {lo:g} above its upper limit {hi:g}"
            )
        if lo == hi:
            not_given.append(j.name)
            continue
        lower[j.idx_v], upper[j.idx_v] = lo, hi
    effort, velocity, damping, friction = (a[:nv].copy() for a in read[2:])
    for name, values in (("effort limit", effort), ("velocity limit", velocity),
                         ("damping", damping), ("friction", friction)):  # fmt: skip
        if not values.min(initial=0.0) >= 0.0:  # a negative value or a NaN: say which joint
            _check(name, values, names)
    for k in np.flatnonzero(effort == 0.0):
        if names[k] not in not_given:
            not_given.append(names[k])
    effort = np.where(effort > 0.0, effort, np.inf)
    velocity = np.where(velocity > 0.0, velocity, np.inf)
    if not effort_limits:
        effort = np.full(nv, np.inf)
    if not position_limits:
        lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
    if not losses:
        damping, friction = np.zeros(nv), np.zeros(nv)
    return Physical(lower, upper, effort, velocity, damping, friction,
                    not_given=tuple(not_given))  # fmt: skip


def applied_efforts(tau_law: np.ndarray, q: np.ndarray, qd: np.ndarray, p: Physical) -> np.ndarray:
    """The efforts the joints get [N·m or N]: the law's saturated, plus losses and limits.

    ``tau_law``, ``q``, ``qd`` of shape (…, nv). This is the definition every backend follows.
    """
    tau = np.clip(tau_law, -p.effort, p.effort)
    tau = tau - p.damping * qd - p.friction * np.tanh(qd / FRICTION_VELOCITY)
    with np.errstate(invalid="ignore"):
        below = np.maximum(0.0, p.stiffness * (p.lower - q) - p.limit_damping * qd)
        above = np.minimum(0.0, p.stiffness * (p.upper - q) - p.limit_damping * qd)
    below = np.where(q < p.lower, below, 0.0)
    above = np.where(q > p.upper, above, 0.0)
    return tau + below + above


def _chapter_urdf(robot: Robot, m: pin.Model) -> bool:
    """Whether ``m`` is the chapter's arm from its generated URDF (however it was loaded).

    Its limits (±4π rad, ±110 m, 1e9 N·m, 1e6 rad/s) are not binding by construction.
    """
    from rrt_pin.robot.urdf import JOINT_NAMES

    return (
        tuple(j.name for j in robot.joints) == JOINT_NAMES
        and bool((np.asarray(m.effortLimit) == 1e9).all())
        and bool((np.asarray(m.velocityLimit) == 1e6).all())
    )


@functools.lru_cache(maxsize=64)  # immutable (read-only arrays): one a size
def inactive(nv: int) -> Physical:
    """A model that applies nothing to ``nv`` coordinates (a run is its law's alone)."""
    return Physical(np.full(nv, -np.inf), np.full(nv, np.inf), np.full(nv, np.inf),
                    np.full(nv, np.inf), np.zeros(nv), np.zeros(nv))  # fmt: skip


def joint_names(robot: Robot) -> list[str]:
    """The joint of each coordinate (nv,)."""
    return [j.name for j in robot.joints for _ in range(j.nv)]


def saturated(tau_law: np.ndarray, p: Physical) -> np.ndarray:
    """The law's efforts after saturation, what the actuators apply [N·m or N] (…, nv)."""
    return np.clip(tau_law, -p.effort, p.effort)


def applied_jacobian(
    tau_law: np.ndarray,
    dtau_dq: np.ndarray,
    dtau_dv: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    p: Physical,
) -> tuple[np.ndarray, np.ndarray]:
    """∂/∂q and ∂/∂q̇ of :func:`applied_efforts` (nv, nv), given the law's and its derivatives.

    Saturated efforts have no derivative; friction's is f/v·(1 − tanh²); a position
    limit's −k and −b where it pushes.
    """
    free = (np.abs(tau_law) < p.effort)[:, None]
    dq = np.where(free, dtau_dq, 0.0)
    dv = np.where(free, dtau_dv, 0.0)
    th = np.tanh(qd / FRICTION_VELOCITY)
    dv_diag = -p.damping - p.friction / FRICTION_VELOCITY * (1.0 - th * th)
    with np.errstate(invalid="ignore"):
        below = (q < p.lower) & (p.stiffness * (p.lower - q) - p.limit_damping * qd > 0.0)
        above = (q > p.upper) & (p.stiffness * (p.upper - q) - p.limit_damping * qd < 0.0)
    pushing = below | above
    dq_diag = np.where(pushing, -p.stiffness, 0.0)
    dv_diag = dv_diag + np.where(pushing, -p.limit_damping, 0.0)
    return dq + np.diag(dq_diag), dv + np.diag(dv_diag)


def check_step(step: float | None, p: Physical, names: list[str]) -> None:
    """Refuse a fixed step too long for the position limits' stiffness (h·ω > 0.5).

    Raises:
        InputError: naming the step, the first limited joint and the longest step allowed.
    """
    if step is None or not p.has_positions or step * LIMIT_OMEGA <= MAX_STEP_OMEGA:
        return
    k = int(np.flatnonzero(np.isfinite(p.lower) | np.isfinite(p.upper))[0])
    longest = MAX_STEP_OMEGA / LIMIT_OMEGA
    off = "--no-position-limits" if text.argument("x") == "--x" else "position_limits=False"
    raise InputError(
        f"{text.argument('step')}={step:g} s is too long for the position limit of joint {names[k]!r} "
        f"(compliant, omega = {LIMIT_OMEGA:g} rad/s: h·omega = {step * LIMIT_OMEGA:.3g} > "
        f"{MAX_STEP_OMEGA:g}); the longest step allowed is {longest:g} s (or "
        f"{off})"
    )


def outside_limits(
    q: np.ndarray, p: Physical, names: list[str]
) -> list[tuple[str, float, float, float]]:
    """The coordinates of ``q`` outside their position limits: (joint, value, lower, upper)."""
    q = np.asarray(q, dtype=float)
    out = []
    for k in np.flatnonzero((q < p.lower) | (q > p.upper)):
        out.append((names[k], float(q[k]), float(p.lower[k]), float(p.upper[k])))
    return out


def within(p: Physical, room: np.ndarray | None = None) -> Callable[[np.ndarray, np.ndarray], bool]:
    """f(τ, q) for one state (nv,): whether −room ≤ τ ≤ room and lower ≤ q ≤ upper everywhere.

    With ``room`` the effort limits (the default), True says that neither the saturation
    nor a position limit acts on ``τ`` at ``q``: :func:`applied_efforts` is then
    τ − d·q̇ − f·tanh(q̇/v). False on NaN. A comparison of Python floats, joint by joint:
    a numpy call on a few coordinates costs more than the whole loop.
    """
    room = p.effort if room is None else np.asarray(room, dtype=float)
    keep = np.isfinite(room) | np.isfinite(p.lower) | np.isfinite(p.upper)
    index = np.flatnonzero(keep).tolist()
    rows = list(zip(p.lower[keep].tolist(), p.upper[keep].tolist(),
                    (-room[keep]).tolist(), room[keep].tolist(), strict=True))  # fmt: skip
    if not rows:
        return lambda tau, q: True
    if len(index) == p.nv:

        def inside(tau: np.ndarray, q: np.ndarray) -> bool:
            for x, s, (lo, hi, least, most) in zip(q.tolist(), tau.tolist(), rows, strict=True):
                if not (lo <= x <= hi and least <= s <= most):
                    return False
            return True

        return inside

    def inside_some(tau: np.ndarray, q: np.ndarray) -> bool:
        qs, ss = q.tolist(), tau.tolist()
        for k, (lo, hi, least, most) in zip(index, rows, strict=True):
            if not (lo <= qs[k] <= hi and least <= ss[k] <= most):
                return False
        return True

    return inside_some


def applier(p: Physical) -> Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]:
    """:func:`applied_efforts` for one model, as f(τ_law, q, q̇): the same values, faster.

    Terms the model does not have (no effort limit, no damping, no friction, no
    position limit) are left out; for one state (nv,), the saturation and the position
    limits only when :func:`within` says one acts, else a position limit's spring only
    when some coordinate is past one. States of shape (…, nv).
    """
    clip = bool(np.isfinite(p.effort).any())
    damp = bool((p.damping > 0).any())
    rub = bool((p.friction > 0).any())
    stops = p.has_positions
    lo, hi, e, d, f, k, b = (p.lower, p.upper, p.effort, p.damping, p.friction, p.stiffness,
                             p.limit_damping)  # fmt: skip
    minus_e = -e
    v = FRICTION_VELOCITY
    tanh, where, maximum, minimum = np.tanh, np.where, np.maximum, np.minimum
    least = np.minimum.reduce
    free = within(p)

    def apply(tau_law: np.ndarray, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        bound = not (tau_law.ndim == 1 and free(tau_law, q))
        tau = minimum(maximum(tau_law, minus_e), e) if clip and bound else tau_law
        if damp:
            tau = tau - d * qd
        if rub:
            tau = tau - f * tanh(qd / v)
        if bound and stops and least(minimum(q - lo, hi - q), axis=None) < 0.0:  # one is past
            below, above = q < lo, q > hi
            tau = tau + where(below, maximum(0.0, k * (lo - q) - b * qd), 0.0)
            tau = tau + where(above, minimum(0.0, k * (hi - q) - b * qd), 0.0)
        return tau

    return apply


def losses(p: Physical) -> Callable[[np.ndarray, np.ndarray], np.ndarray] | None:
    """τ ↦ τ − d·q̇ − f·tanh(q̇/v) as f(τ, q̇), what the joints get where :func:`within` holds.

    None when the model has neither damping nor friction (τ itself).
    """
    damp = bool((p.damping > 0).any())
    rub = bool((p.friction > 0).any())
    d, f, v, tanh = p.damping, p.friction, FRICTION_VELOCITY, np.tanh
    if damp and rub:
        return lambda tau, qd: tau - d * qd - f * tanh(qd / v)
    if damp:
        return lambda tau, qd: tau - d * qd
    if rub:
        return lambda tau, qd: tau - f * tanh(qd / v)
    return None


#: Pinocchio's revolute and prismatic joints (what :func:`gravity_bound` knows).
_REVOLUTE = {"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned",
             "JointModelRUBX", "JointModelRUBY", "JointModelRUBZ",
             "JointModelRevoluteUnboundedUnaligned"}  # fmt: skip
_PRISMATIC = {"JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned"}


def gravity_bound(model: pin.Model, p: Physical) -> np.ndarray:
    """An upper bound of |G_k(q)| over every q within ``p``'s position limits [N·m or N] (nv,).

    G_k = Σ_b m_b·gᵀ·∂c_b/∂q_k over the bodies b that joint k carries, with
    |∂c_b/∂q_k| = 1 for a prismatic joint and ≤ |c_b − o_k| for a revolute one, o_k on
    its axis; |c_b − o_k| is at most the lengths of the joint placements between them,
    the travel of the prismatic joints among them (their limits) and b's centre-of-mass
    offset. inf where no bound is known: a joint of another kind in the model, or an
    unlimited prismatic joint on the way. With it, |τ_PD| ≤ effort − bound says
    that PD plus G(q) is not saturated, without computing G.
    """
    nv, joints = model.nv, range(model.njoints)
    kinds = [model.joints[j].shortname() for j in joints]
    if any(kind not in _REVOLUTE | _PRISMATIC for kind in kinds[1:]):
        return np.full(nv, np.inf)
    g = float(np.linalg.norm(model.gravity.linear))
    travel = np.maximum(np.abs(p.lower), np.abs(p.upper))
    mass = [model.inertias[j].mass for j in joints]
    lever = [float(np.linalg.norm(model.inertias[j].lever)) for j in joints]
    # how far joint j's origin may lie from its parent's: its placement, its travel
    step = [float(np.linalg.norm(model.jointPlacements[j].translation)) for j in joints]
    for j in joints[1:]:
        if kinds[j] in _PRISMATIC:
            step[j] += float(travel[model.joints[j].idx_v])
    parents = list(model.parents)
    bound = np.zeros(nv)
    for k in joints[1:]:
        total = 0.0
        for body in model.subtrees[k]:
            reach = 1.0
            if kinds[k] not in _PRISMATIC:
                reach, j = lever[body], body
                while j != k:
                    reach += step[j]
                    j = parents[j]
            total += mass[body] * reach
        bound[model.joints[k].idx_v] = g * total
    return bound * (1.0 + 1e-9)  # room for the rounding of G's sum
