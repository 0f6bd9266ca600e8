"""Feedback laws: the seed's eq. (31) and PD plus gravity compensation for any model.

A controller maps a state to joint efforts: ``tau = controller(q, qd)`` with ``q``
[rad or m] and ``qd`` [rad/s or m/s], arrays of shape (nv,), returning (nv,) efforts
[N·m for revolute joints, N for prismatic ones]. ``controller.efforts(q, qd)`` does
the same for arrays of shape (N, nv). Both laws here have the form

    tau = −kd·q̇ − kp·(q − qf) + G(q),

with diagonal gains kp ≥ 0 [N·m/rad or N/m] and kd ≥ 0 [N·m·s/rad or N·s/m], and
a gravity term G: the seed's printed formula (:class:`SeedController`) or
Pinocchio's generalized gravity of a model (:class:`PDGravityController`). Their
``gravity`` and ``pd`` parts are exposed separately so that a simulation can fold
an exact gravity compensation into the dynamics (see :mod:`rrt_pin.simulation`).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar, Protocol, runtime_checkable

import numpy as np

from rrt_pin.errors import InputError, ParameterError
from rrt_pin.params import Params

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "Controller",
    "PDGravityController",
    "SeedController",
    "pd_gravity_controller",
    "seed_controller",
]


@runtime_checkable
class Controller(Protocol):
    """Anything that maps one state (q, q̇) to joint efforts τ (arrays of shape (nv,))."""

    def __call__(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts [N·m or N] at configuration ``q`` and velocity ``qd``."""
        ...


def _gains(name: str, value: Any, n: int) -> tuple[float, ...]:
    """A gain vector: a scalar (same for every joint) or n finite values ≥ 0."""
    values = _floats(name, value, n)
    for i, v in enumerate(values):
        if not math.isfinite(v):
            raise ParameterError(f"{name}[{i}]", v, "gain must be finite")
        if v < 0.0:
            raise ParameterError(f"{name}[{i}]", v, "gain must be >= 0")
    return values


def _target(name: str, value: Any, n: int) -> tuple[float, ...]:
    values = _floats(name, value, n)
    for i, v in enumerate(values):
        if not math.isfinite(v):
            raise InputError(f"{name}[{i}]={v!r} must be finite [rad or m]")
    return values


def _floats(name: str, value: Any, n: int) -> tuple[float, ...]:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name}={value!r} is not a number or a list of numbers") from e
    if arr.ndim == 0:
        arr = np.full(n, float(arr))
    if arr.shape != (n,):
        raise InputError(f"{name} has shape {arr.shape} but the model has {n} joints")
    return tuple(float(v) for v in arr)


def _states(q: Any, qd: Any, n: int) -> tuple[np.ndarray, np.ndarray]:
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    if q.ndim != 2 or q.shape[1] != n or qd.shape != q.shape:
        raise InputError(f"efforts() needs q and qd of shape (N, {n}); got {q.shape=}, {qd.shape=}")
    return q, qd


#: The fields of Params that the RRT arm's model depends on (not gains, targets, states).
_PLANT_FIELDS = (
    "L1", "L2", "m1", "m2", "m3", "I1x", "I1y", "I1z", "I2x", "I2y", "I2z", "I3x", "I3y", "I3z", "g",
)  # fmt: skip


def _seed_model(params: Params) -> pin.Model:
    return _plant_model(tuple(getattr(params, name) for name in _PLANT_FIELDS))


@functools.lru_cache(maxsize=8)
def _plant_model(plant: tuple[float, ...]) -> pin.Model:
    from rrt_pin.model import rrt_model

    return rrt_model(Params(**dict(zip(_PLANT_FIELDS, plant, strict=True))))


@dataclass(frozen=True)
class SeedController:
    """The seed's feedback law, eq. (31), exactly as printed.

    ::

        T01x = −β01·q̇1 − γ01·(q1 − q1f)
        T12y = −β12·q̇2 − γ12·(q2 − q2f) + g·m2·L2·c2 + g·m3·c2·(L2 + q3)
        F23z = −β23·q̇3 − γ23·(q3 − q3f) + g·m3·s2

    Attributes:
        kp: stiffness gains (γ01 [N·m/rad], γ12 [N·m/rad], γ23 [N/m]).
        kd: damping gains (β01 [N·m·s/rad], β12 [N·m·s/rad], β23 [N·s/m]).
        qf: target (q1f [rad], q2f [rad], q3f [m]).
        params: the arm whose g, m2, m3, L2 the gravity terms use (SI units).
        kind: ``"seed"``.
    """

    kp: tuple[float, float, float]
    kd: tuple[float, float, float]
    qf: tuple[float, float, float]
    params: Params = field(repr=False)
    kind: ClassVar[str] = "seed"

    def __post_init__(self) -> None:
        object.__setattr__(self, "kp", _gains("kp", self.kp, 3))
        object.__setattr__(self, "kd", _gains("kd", self.kd, 3))
        object.__setattr__(self, "qf", _target("qf", self.qf, 3))
        if not isinstance(self.params, Params):
            raise InputError(f"params must be a Params, not {type(self.params).__name__}")

    @property
    def nv(self) -> int:
        """Number of joints (3)."""
        return 3

    def __call__(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts (T01x [N·m], T12y [N·m], F23z [N]) at one state (not validated)."""
        p = self.params
        kp1, kp2, kp3 = self.kp
        kd1, kd2, kd3 = self.kd
        f1, f2, f3 = self.qf
        q1, q2, q3 = float(q[0]), float(q[1]), float(q[2])
        c2, s2 = math.cos(q2), math.sin(q2)
        return np.array(
            (
                -kd1 * qd[0] - kp1 * (q1 - f1),
                -kd2 * qd[1]
                - kp2 * (q2 - f2)
                + p.g * p.m2 * p.L2 * c2
                + p.g * p.m3 * c2 * (p.L2 + q3),
                -kd3 * qd[2] - kp3 * (q3 - f3) + p.g * p.m3 * s2,
            )
        )

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """The law's gravity terms at configurations of any shape (…, 3) -> (…, 3) [N·m, N]."""
        p = self.params
        q = np.asarray(q, dtype=float)
        out = np.empty_like(q)  # same memory layout: each component may be contiguous
        out[..., 0] = 0.0
        # g·m2·L2·c2 + g·m3·c2·(L2 + q3) = c2·(g·(m2 + m3)·L2 + g·m3·q3)
        np.multiply(q[..., 2], p.g * p.m3, out=out[..., 1])
        out[..., 1] += p.g * (p.m2 + p.m3) * p.L2
        out[..., 1] *= np.cos(q[..., 1])
        np.sin(q[..., 1], out=out[..., 2])
        out[..., 2] *= p.g * p.m3
        return out

    def pd(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """The PD part −kd·q̇ − kp·(q − qf), any leading shape (…, 3) [N·m, N]."""
        return -np.asarray(self.kd) * qd - np.asarray(self.kp) * (q - np.asarray(self.qf))

    def efforts(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts at N states: q, qd of shape (N, 3) -> (N, 3) [N·m, N·m, N].

        Raises:
            InputError: the shapes do not match (N, 3).
        """
        q, qd = _states(q, qd, 3)
        return self.pd(q, qd) + self.gravity(q)

    def derivatives(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """∂τ/∂q and ∂τ/∂q̇ at one state, each (3, 3)."""
        p = self.params
        c2, s2 = math.cos(q[1]), math.sin(q[1])
        dq = -np.diag(self.kp)
        dq[1, 1] -= p.g * s2 * (p.m2 * p.L2 + p.m3 * (p.L2 + q[2]))
        dq[1, 2] += p.g * p.m3 * c2
        dq[2, 1] += p.g * p.m3 * c2
        return dq, -np.diag(self.kd)

    def compensates_gravity_of(self, model: pin.Model) -> bool:
        """Whether the law's gravity terms are exactly ``model``'s generalized gravity.

        True when ``model`` equals the RRT arm generated from :attr:`params` (then
        eq. (31)'s gravity terms are G(q) of eq. (15), as the tests verify).
        """
        return bool(model == _seed_model(self.params))


@dataclass(frozen=True)
class PDGravityController:
    """PD plus gravity compensation for any model: τ = −kd·q̇ − kp·(q − qf) + G(q).

    G(q) is ``pin.computeGeneralizedGravity`` of :attr:`model` (a private copy).

    Attributes:
        kp: stiffness gains, one per joint [N·m/rad or N/m].
        kd: damping gains, one per joint [N·m·s/rad or N·s/m].
        qf: target configuration [rad or m].
        model: the Pinocchio model whose gravity is compensated.
        kind: ``"pd_gravity"``.
    """

    kp: tuple[float, ...]
    kd: tuple[float, ...]
    qf: tuple[float, ...]
    model: pin.Model = field(repr=False, compare=False)
    kind: ClassVar[str] = "pd_gravity"
    _data: Any = field(init=False, repr=False, compare=False, default=None)
    _pool: Any = field(init=False, repr=False, compare=False, default=None)

    def __post_init__(self) -> None:
        import pinocchio as pin

        if not isinstance(self.model, pin.Model):
            raise InputError(f"model must be a pinocchio.Model, not {type(self.model).__name__}")
        model = self.model.copy()
        object.__setattr__(self, "model", model)
        object.__setattr__(self, "kp", _gains("kp", self.kp, model.nv))
        object.__setattr__(self, "kd", _gains("kd", self.kd, model.nv))
        object.__setattr__(self, "qf", _target("qf", self.qf, model.nq))
        object.__setattr__(self, "_data", model.createData())

    @property
    def nv(self) -> int:
        """Number of velocity coordinates of the model."""
        return int(self.model.nv)

    def __call__(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts [N·m or N] at one state (not validated)."""
        import pinocchio as pin

        g = pin.computeGeneralizedGravity(self.model, self._data, q)
        return self.pd(q, qd) + g

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """G(q) at configurations ``q`` of shape (N, nq) -> (N, nv) [N·m or N]."""
        import pinocchio as pin

        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.array(pin.computeGeneralizedGravity(self.model, self._data, q))
        if self._pool is None:
            object.__setattr__(self, "_pool", pin.ModelPool(self.model, 1))
        zeros = np.zeros((self.model.nv, q.shape[0]))
        return pin.rneaInParallel(1, self._pool, np.ascontiguousarray(q.T), zeros, zeros).T

    def pd(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """The PD part −kd·q̇ − kp·(q − qf), any leading shape (…, nv) [N·m or N]."""
        return -np.asarray(self.kd) * qd - np.asarray(self.kp) * (q - np.asarray(self.qf))

    def efforts(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts at N states: q, qd of shape (N, nv) -> (N, nv) [N·m or N].

        Raises:
            InputError: the shapes do not match (N, nv).
        """
        q, qd = _states(q, qd, self.model.nv)
        return self.pd(q, qd) + self.gravity(q)

    def derivatives(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """∂τ/∂q and ∂τ/∂q̇ at one state, each (nv, nv)."""
        import pinocchio as pin

        dg = pin.computeGeneralizedGravityDerivatives(self.model, self._data, q)
        return np.array(dg) - np.diag(self.kp), -np.diag(self.kd)

    def compensates_gravity_of(self, model: pin.Model) -> bool:
        """Whether ``model`` equals :attr:`model` (then G(q) is its generalized gravity)."""
        return bool(model == self.model)


def seed_controller(params: Params | None = None) -> SeedController:
    """The seed's eq. (31) with the gains, target and arm of ``params`` (seed's by default).

    Raises:
        ParameterError: a gain is negative or not finite.
    """
    p = params if params is not None else Params()
    return SeedController(kp=p.kp, kd=p.kd, qf=p.qf, params=p)


def pd_gravity_controller(
    model: pin.Model,
    kp: float | Sequence[float],
    kd: float | Sequence[float],
    qf: Sequence[float],
) -> PDGravityController:
    """PD plus Pinocchio's gravity compensation for ``model``.

    Args:
        model: any Pinocchio model (its gravity vector is used as set).
        kp: stiffness gains [N·m/rad or N/m]: one per joint, or one for all.
        kd: damping gains [N·m·s/rad or N·s/m]: one per joint, or one for all.
        qf: target configuration (nq,) [rad or m].

    Raises:
        ParameterError: a gain is negative or not finite (names it, e.g. ``kd[2]``).
        InputError: a gain or target has the wrong length, or a target is not finite.
    """
    return PDGravityController(kp=kp, kd=kd, qf=qf, model=model)  # type: ignore[arg-type]
