"""Controllers: the laws rrt-pin ships.

Every law follows the contract of :mod:`rrt_pin.simulate.contract` (``efforts(t, q,
qd)``, optional ``efforts_many``, ``jacobian`` and ``feedback``; see there), whose
:class:`Controller`, :class:`LinearFeedback` and :func:`as_controller` are offered here
too.

Laws here:

* :class:`ChapterController`: the chapter's eq. (31), exactly as printed;
* :class:`PDGravityController`: PD plus Pinocchio's gravity compensation, any robot;
* :class:`TrackingController`: computed torque along a prescribed motion
  (feed-forward M(q)·q̈_d + b(q, q̇) with PD on the tracking error);
* :class:`OpenLoop`: efforts played from samples, whatever the state.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from rrt_pin.core.errors import (
    InputError,
    ParameterError,
)
from rrt_pin.core.memory import check_data
from rrt_pin.dynamics.trajectory import Trajectory
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot, bare_model
from rrt_pin.simulate.contract import Controller, LinearFeedback, as_controller, trusted

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.robot.robot import Robot

__all__ = [
    "ChapterController",
    "Controller",
    "LinearFeedback",
    "OpenLoop",
    "PDGravityController",
    "SeedController",
    "TrackingController",
    "as_controller",
    "chapter_controller",
    "pd_gravity_controller",
    "regulator",
    "seed_controller",
    "tracking_controller",
]


# --------------------------------------------------------------------------
# Gains
# --------------------------------------------------------------------------
def _gains(name: str, value: Any, n: int) -> tuple[float, ...]:
    """A gain vector: a scalar (same for every joint) or n finite values ≥ 0."""
    values = _floats(name, value, n)
    if all(0.0 <= v < math.inf for v in values):  # the common case, at once
        return values
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
    if type(value) is tuple and len(value) == n and all(type(v) is float for v in value):
        return value  # already what is returned (a sweep's Params make thousands)
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
        raise InputError(
            f"efforts_many() needs q and qd of shape (N, {n}); got {q.shape=}, {qd.shape=}"
        )
    return q, qd


class _ModelKey:
    """Equal when the models are equal (``pin.Model.__eq__``): laws on equal models share G."""

    def __init__(self, model: pin.Model) -> None:
        self.model = model

    def __eq__(self, other: object) -> bool:
        return isinstance(other, _ModelKey) and bool(self.model == other.model)

    def __hash__(self) -> int:
        return int(self.model.nv)


class _PDGravity(Controller):
    """τ = −kd·q̇ − kp·(q − qf) + G(q), the shared shape of the two regulators.

    Deprecated forms kept for one release: ``efforts(Q, QD)`` (N states, no
    time; use :meth:`efforts_many`) and ``derivatives(q, qd)`` (use :meth:`jacobian`).
    """

    def __init_subclass__(cls, **kwargs: Any) -> None:
        super().__init_subclass__(**kwargs)
        one = cls.__dict__.get("efforts")
        if one is None:
            return

        def efforts(self: Any, *args: Any) -> np.ndarray:
            if len(args) == 2:  # deprecated: efforts(q, qd), one state or N states
                q = np.asarray(args[0], dtype=float)
                return one(self, 0.0, *args) if q.ndim == 1 else self.efforts_many(0.0, *args)
            return one(self, *args)

        efforts.__doc__ = one.__doc__
        cls.efforts = efforts

    def derivatives(self, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Deprecated: :meth:`jacobian` at t = 0."""
        return self.jacobian(0.0, q, qd)  # type: ignore[return-value]

    kp: tuple[float, ...]
    kd: tuple[float, ...]
    qf: tuple[float, ...]

    def gravity(self, q: np.ndarray) -> np.ndarray:  # pragma: no cover - abstract
        raise NotImplementedError

    def pd(self, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """The PD part −kd·q̇ − kp·(q − qf), any leading shape (…, nv) [N·m or N]."""
        return -np.asarray(self.kd) * qd - np.asarray(self.kp) * (q - np.asarray(self.qf))

    def efforts_many(self, t: Any, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts at N states: q, qd of shape (N, nv) -> (N, nv) [N·m or N] (time-invariant).

        Raises:
            InputError: the shapes do not match (N, nv).
        """
        q, qd = _states(q, qd, self.nv)
        return self.pd(q, qd) + self.gravity(q)


@dataclass(frozen=True, eq=False)
class ChapterController(_PDGravity):
    """The chapter's feedback law, eq. (31), exactly as printed.

    ::

        T01x = −β01·q̇1 − γ01·(q1 − q1f)
        T12y = −β12·q̇2 − γ12·(q2 − q2f) + g·m2·L2·c2 + g·m3·c2·(L2 + q3)
        F23z = −β23·q̇3 − γ23·(q3 − q3f) + g·m3·s2

    Attributes:
        kp: stiffness gains (γ01 [N·m/rad], γ12 [N·m/rad], γ23 [N/m]).
        kd: damping gains (β01 [N·m·s/rad], β12 [N·m·s/rad], β23 [N·s/m]).
        qf: target (q1f [rad], q2f [rad], q3f [m]).
        params: the arm whose g, m2, m3, L2 the gravity terms use (SI units).
        kind: ``"chapter"``.
    """

    kp: tuple[float, float, float]
    kd: tuple[float, float, float]
    qf: tuple[float, float, float]
    params: Params = field(repr=False)
    kind: ClassVar[str] = "chapter"

    def __post_init__(self) -> None:
        object.__setattr__(self, "kp", _gains("kp", self.kp, 3))
        object.__setattr__(self, "kd", _gains("kd", self.kd, 3))
        object.__setattr__(self, "qf", _target("qf", self.qf, 3))
        if not isinstance(self.params, Params):
            raise InputError(f"params must be a Params, not {type(self.params).__name__}")

    @classmethod
    def of(cls, params: Params) -> ChapterController:
        """The law with ``params``' own gains and target, on its arm.

        What ``ChapterController(kp=params.kp, kd=params.kd, qf=params.qf, params=params)``
        makes, without checking again what :class:`Params` has checked (finite gains
        ≥ 0, a finite target): a sweep makes thousands a second.
        """
        if not isinstance(params, Params):
            raise InputError(f"params must be a Params, not {type(params).__name__}")
        law = object.__new__(cls)
        law.__dict__.update(kp=params.kp, kd=params.kd, qf=params.qf, params=params)
        return law

    @property
    def nv(self) -> int:
        """Number of joints (3)."""
        return 3

    def efforts(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts (T01x [N·m], T12y [N·m], F23z [N]) at one state (not validated; no t)."""
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

    def jacobian(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
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
        from rrt_pin.robot.model import chapter_model

        return bool(model == chapter_model(self.params))

    def _exact_for(self, robot: Robot) -> bool:
        plant = robot.params
        if plant is not None:  # the chapter's arm: its G(q) depends on g, m2, m3, L2 only
            p = self.params
            return (plant.g, plant.m2, plant.m3, plant.L2) == (p.g, p.m2, p.m3, p.L2)
        return self.compensates_gravity_of(robot.model)

    def feedback(self) -> LinearFeedback:
        """PD plus the printed gravity terms; batches share them when g, m2, m3, L2 agree."""
        p = self.params
        return LinearFeedback(
            kp=np.array(self.kp),
            kd=np.array(self.kd),
            qf=np.array(self.qf),
            gravity=self.gravity,
            key=("chapter", p.g, p.m2, p.m3, p.L2),
            exact_for=self._exact_for,
        )


@dataclass(frozen=True, eq=False)
class PDGravityController(_PDGravity):
    """PD plus gravity compensation for any robot: τ = −kd·q̇ − kp·(q − qf) + G(q).

    G(q) is ``pin.computeGeneralizedGravity`` of :attr:`model` (a private copy).

    Attributes:
        kp: stiffness gains, one per coordinate [N·m/rad or N/m].
        kd: damping gains, one per coordinate [N·m·s/rad or N·s/m].
        qf: target joint coordinates [rad or m].
        model: the Pinocchio model whose gravity is compensated.
        robot: its :class:`~rrt_pin.robot.robot.Robot` (built from the model when None).
        kind: ``"pd_gravity"``.
    """

    kp: tuple[float, ...]
    kd: tuple[float, ...]
    qf: tuple[float, ...]
    model: pin.Model = field(repr=False)
    robot: Any = field(default=None, repr=False)
    kind: ClassVar[str] = "pd_gravity"
    _data: Any = field(init=False, repr=False, default=None)
    _pool: Any = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:
        import pinocchio as pin

        if not isinstance(self.model, pin.Model):
            raise InputError(f"model must be a pinocchio.Model, not {type(self.model).__name__}")
        model = self.model.copy()
        object.__setattr__(self, "model", model)
        if self.robot is None:
            object.__setattr__(self, "robot", Robot.from_model(model))
        n = model.nv
        object.__setattr__(self, "kp", _gains("kp", self.kp, n))
        object.__setattr__(self, "kd", _gains("kd", self.kd, n))
        if model.nq != n and np.shape(self.qf) == (model.nq,):
            object.__setattr__(self, "qf", tuple(self.robot.coordinates(np.asarray(self.qf))))
        object.__setattr__(self, "qf", _target("qf", self.qf, n))
        check_data(model, f"a controller of a {n}-joint model")
        object.__setattr__(self, "_data", model.createData())

    @property
    def nv(self) -> int:
        """Number of joint coordinates of the model."""
        return int(self.model.nv)

    def efforts(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts [N·m or N] at one state (not validated; time-invariant)."""
        import pinocchio as pin

        g = pin.computeGeneralizedGravity(self.model, self._data, self.robot.configuration(q))
        return self.pd(q, qd) + g

    def gravity(self, q: np.ndarray) -> np.ndarray:
        """G at joint coordinates ``q`` of shape (nv,) or (N, nv) [N·m or N]."""
        import pinocchio as pin

        q = np.asarray(q, dtype=float)
        if q.ndim == 1:
            return np.array(
                pin.computeGeneralizedGravity(self.model, self._data, self.robot.configuration(q))
            )
        if self._pool is None:
            object.__setattr__(self, "_pool", pin.ModelPool(self.model, 1))
        shape = q.shape
        flat = self.robot.configuration(q.reshape(-1, shape[-1]))
        zeros = np.zeros((self.model.nv, flat.shape[0]))
        out = pin.rneaInParallel(1, self._pool, np.ascontiguousarray(flat.T), zeros, zeros).T
        return out.reshape(shape)

    def jacobian(self, t: float, q: np.ndarray, qd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """∂τ/∂q and ∂τ/∂q̇ at one state, each (nv, nv)."""
        import pinocchio as pin

        dg = pin.computeGeneralizedGravityDerivatives(
            self.model, self._data, self.robot.configuration(q)
        )
        return np.array(dg) - np.diag(self.kp), -np.diag(self.kd)

    def compensates_gravity_of(self, model: pin.Model) -> bool:
        """Whether ``model`` equals :attr:`model` (then G(q) is its generalized gravity)."""
        return bool(model == self.model)

    def feedback(self) -> LinearFeedback:
        """PD plus this model's gravity; batches share it when the models are equal."""
        return LinearFeedback(
            kp=np.array(self.kp),
            kd=np.array(self.kd),
            qf=np.array(self.qf),
            gravity=self.gravity,
            key=_ModelKey(self.model),
            exact_for=lambda robot: self.compensates_gravity_of(robot.model),
        )


@dataclass(frozen=True, eq=False)
class TrackingController(Controller):
    """Computed torque along a prescribed motion: exact tracking for an exact model.

    ::

        τ = M(q)·(q̈d + kd·(q̇d − q̇) + kp·(qd − q)) + b(q, q̇)      (one RNEA call)

    with (qd, q̇d, q̈d) the motion at time t. With the robot's own model the
    tracking error e obeys ë + kd·ė + kp·e = 0: starting on the motion, the
    robot follows it up to the integration error.

    Attributes:
        robot: the robot whose model gives M and b.
        motion: the reference, a function of time returning a
            :class:`~rrt_pin.dynamics.trajectory.Trajectory` (e.g.
            :class:`~rrt_pin.dynamics.trajectory.RestToRest`), or a sampled Trajectory
            (interpolated linearly between samples).
        kp: stiffness of the error dynamics [1/s²], one per coordinate or one for all.
        kd: damping of the error dynamics [1/s], one per coordinate or one for all.
        kind: ``"tracking"``.
    """

    robot: Robot = field(repr=False)
    motion: Any = field(repr=False)
    kp: Any = 100.0
    kd: Any = 20.0
    kind: ClassVar[str] = "tracking"
    _data: Any = field(init=False, repr=False, default=None)

    def __post_init__(self) -> None:

        n = self.robot.nv
        object.__setattr__(self, "kp", np.array(_gains("kp", self.kp, n)))
        object.__setattr__(self, "kd", np.array(_gains("kd", self.kd, n)))
        if isinstance(self.motion, Trajectory):
            if self.motion.n != n:
                raise InputError(f"the motion has {self.motion.n} coordinates but the robot {n}")
        elif not callable(self.motion):
            raise InputError("motion must be a Trajectory or a function of time returning one")
        check_data(self.robot.model, f"a controller of a {n}-joint model")
        object.__setattr__(self, "_data", self.robot.model.createData())

    @property
    def nv(self) -> int:
        """Number of joint coordinates."""
        return self.robot.nv

    def reference(self, t: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, q̇, q̈) of the motion at time(s) ``t`` [s], each (…, nv)."""
        m = self.motion
        if isinstance(m, Trajectory):
            ts = np.atleast_1d(np.asarray(t, dtype=float))
            cols = [
                np.column_stack([np.interp(ts, m.t, a[:, k]) for k in range(m.n)])
                for a in (m.q, m.qd, m.qdd)
            ]
        else:
            sample = m(t)
            cols = [sample.q, sample.qd, sample.qdd]
        if np.ndim(t) == 0:
            return cols[0][0], cols[1][0], cols[2][0]
        return cols[0], cols[1], cols[2]

    def efforts(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Computed-torque efforts [N·m or N] at time ``t`` [s] and one state."""
        import pinocchio as pin

        qr, qdr, qddr = self.reference(float(t))
        a = qddr + self.kd * (qdr - qd) + self.kp * (qr - q)
        model = self.robot.model
        return np.array(pin.rnea(model, self._data, self.robot.configuration(q), qd, a))


@dataclass(frozen=True, eq=False)
class OpenLoop(Controller):
    """Efforts played from samples, whatever the state: τ(t) interpolated linearly.

    Between samples the efforts are interpolated linearly; before the first and after
    the last sample they hold the end values.

    Attributes:
        t: sample times, strictly increasing (N,) [s].
        tau: efforts at those times (N, nv) [N·m or N].
    """

    t: np.ndarray = field(repr=False)
    tau: np.ndarray = field(repr=False)

    def __post_init__(self) -> None:
        t = np.array(self.t, dtype=float)
        tau = np.array(self.tau, dtype=float)
        if t.ndim != 1 or tau.ndim != 2 or tau.shape[0] != t.size or t.size == 0:
            raise InputError(f"OpenLoop needs t (N,) and tau (N, nv); got {t.shape}, {tau.shape}")
        if not (np.isfinite(t).all() and np.isfinite(tau).all()) or (np.diff(t) <= 0).any():
            raise InputError("OpenLoop needs finite efforts at strictly increasing times")
        for a in (t, tau):
            a.setflags(write=False)
        object.__setattr__(self, "t", t)
        object.__setattr__(self, "tau", tau)

    @property
    def nv(self) -> int:
        """Number of joint coordinates."""
        return int(self.tau.shape[1])

    def efforts(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """The efforts at time ``t`` [N·m or N] (the state is not used)."""
        return np.array([np.interp(t, self.t, self.tau[:, k]) for k in range(self.nv)])

    def efforts_many(self, t: Any, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """The efforts at each time of ``t`` (scalar or (N,)) for N states."""
        ts = np.broadcast_to(np.asarray(t, dtype=float), (np.asarray(q).shape[0],))
        return np.column_stack([np.interp(ts, self.t, self.tau[:, k]) for k in range(self.nv)])


def chapter_controller(params: Params | None = None) -> ChapterController:
    """The chapter's eq. (31) with the gains, target and arm of ``params`` (the chapter's by default).

    Raises:
        ParameterError: a gain is negative or not finite.
    """
    p = params if params is not None else Params()
    return ChapterController(kp=p.kp, kd=p.kd, qf=p.qf, params=p)


def pd_gravity_controller(
    model: Robot | pin.Model,
    kp: float | Sequence[float],
    kd: float | Sequence[float],
    qf: Sequence[float],
) -> PDGravityController:
    """PD plus Pinocchio's gravity compensation for the robot ``model``.

    Args:
        model: any robot (its model's gravity vector is used as set); a bare
            Pinocchio model is deprecated (pass ``Robot.from_model(model)``).
        kp: stiffness gains [N·m/rad or N/m]: one per coordinate, or one for all.
        kd: damping gains [N·m·s/rad or N·s/m]: one per coordinate, or one for all.
        qf: target joint coordinates (nv,) [rad or m] (or Pinocchio's (nq,)).

    Raises:
        ParameterError: a gain is negative or not finite (names it, e.g. ``kd[2]``).
        InputError: a gain or target has the wrong length, or a target is not finite.
    """
    if isinstance(model, Robot):
        return PDGravityController(kp=kp, kd=kd, qf=qf, model=model.model, robot=model)  # type: ignore[arg-type]
    bare_model("pd_gravity_controller", model)
    return PDGravityController(kp=kp, kd=kd, qf=qf, model=model)  # type: ignore[arg-type]


def tracking_controller(
    robot: Any, motion: Any, kp: Any = 100.0, kd: Any = 20.0
) -> TrackingController:
    """Computed torque along ``motion`` for ``robot`` (a Robot; a bare model is deprecated).

    Raises:
        InputError: a bad robot, motion or gain.
    """
    if not isinstance(robot, Robot):
        bare_model("tracking_controller", robot)
        robot = Robot.from_model(robot)
    return TrackingController(robot=robot, motion=motion, kp=kp, kd=kd)


def regulator(robot: Robot, kp: Any = None, kd: Any = None, qf: Any = None) -> Controller:
    """The robot's default feedback law to ``qf`` with gains ``kp``, ``kd``.

    The chapter's arm: eq. (31) (gains and target from the robot's defaults
    unless given). Any other robot: PD plus gravity compensation
    (:class:`PDGravityController`), which needs all three.

    Raises:
        InputError: a value is missing or has the wrong length.
    """
    d = robot.defaults
    kp = d.kp if kp is None else kp
    kd = d.kd if kd is None else kd
    qf = d.qf if qf is None else qf
    missing = [n for n, v in (("kp", kp), ("kd", kd), ("qf", qf)) if v is None]
    if missing:
        raise InputError(f"{robot.name} has no default {', '.join(missing)}: give them")
    if robot.params is not None:
        return ChapterController(kp=kp, kd=kd, qf=qf, params=robot.params)
    return PDGravityController(kp=kp, kd=kd, qf=qf, model=robot.model, robot=robot)


#: The laws defined here: their results are trusted (tested), not checked at every call.
for _law in (ChapterController, PDGravityController, TrackingController, OpenLoop):
    trusted(_law)

#: Deprecated names (kept for one release): the chapter was called "the seed".
SeedController = ChapterController
seed_controller = chapter_controller
