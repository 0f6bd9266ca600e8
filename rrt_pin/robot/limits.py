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
  the joint's diagonal inertia M_kk at the run's start (critically damped, ~1/ω to settle);
* **velocity limits**: reported, not enforced.

"Not given" (URDFs often write ``lower="0" upper="0" effort="0" velocity="0"``): a zero
range is no position limit, a zero (or infinite) effort or velocity no limit. Continuous
joints have no position limit.

Units: SI (rad or m, N·m or N, N·m·s/rad or N·s/m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core.errors import InputError

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.robot.robot import Robot

__all__ = [
    "FRICTION_VELOCITY",
    "LIMIT_DAMPING_RATIO",
    "LIMIT_OMEGA",
    "Physical",
    "applied_efforts",
    "physical_model",
]

#: The velocity below which Coulomb friction fades linearly-ish to zero: τ = −f·tanh(q̇/v) [rad/s or m/s].
FRICTION_VELOCITY = 1e-3
#: The natural frequency of the compliant position limits [rad/s] (a 5 ms time constant).
LIMIT_OMEGA = 200.0
#: Their damping ratio (critical: no bounce).
LIMIT_DAMPING_RATIO = 1.0


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

    @property
    def has_positions(self) -> bool:
        """Whether a position limit applies to some joint."""
        return bool(np.isfinite(self.lower).any() or np.isfinite(self.upper).any())

    @property
    def active(self) -> bool:
        """Whether anything is applied (else a run is the law's alone, bit for bit)."""
        return bool(
            self.has_positions
            or np.isfinite(self.effort).any()
            or (self.damping > 0).any()
            or (self.friction > 0).any()
        )

    def at(self, mass_diagonal: np.ndarray) -> Physical:
        """This model with the position limits' stiffness and damping for these inertias."""
        m = np.asarray(mass_diagonal, dtype=float)
        limited = np.isfinite(self.lower) | np.isfinite(self.upper)
        k = np.where(limited, m * LIMIT_OMEGA**2, 0.0)
        b = np.where(limited, 2.0 * LIMIT_DAMPING_RATIO * m * LIMIT_OMEGA, 0.0)
        return replace(self, stiffness=k, limit_damping=b)

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

    Raises:
        InputError: a limit with lower > upper, a negative damping, friction, effort or
            velocity limit, or a NaN (the joint named).
    """
    m = robot.model if model is None else model
    nv = robot.nv
    names = [j.name for j in robot.joints for _ in range(j.nv)]
    lower, upper = np.full(nv, -np.inf), np.full(nv, np.inf)
    not_given = []
    for j in robot.joints:
        if j.kind == "continuous" or j.nq != j.nv:
            continue
        lo = float(m.lowerPositionLimit[j.idx_q])
        hi = float(m.upperPositionLimit[j.idx_q])
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
    effort = np.array(m.effortLimit, dtype=float)[:nv]
    velocity = np.array(m.velocityLimit, dtype=float)[:nv]
    damping = np.array(m.damping, dtype=float)[:nv]
    friction = np.array(m.friction, dtype=float)[:nv]
    for name, values in (("effort limit", effort), ("velocity limit", velocity),
                         ("damping", damping), ("friction", friction)):  # fmt: skip
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
