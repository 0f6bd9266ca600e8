"""Controllers: the contract every feedback law follows, and the laws rrt-pin ships.

The contract (:class:`Controller`) gives time to the law, as robotics-toolbox,
MuJoCo and Drake do::

    tau = controller.efforts(t, q, qd)          # one state: (nv,) -> (nv,)
    tau = controller.efforts_many(t, Q, QD)     # N states (N, nv), t scalar or (N,)

with ``t`` [s], ``q`` the joint coordinates [rad or m] (angles for continuous
joints, see :mod:`rrt_pin.robot`), ``qd`` [rad/s or m/s] and efforts [N·m for
revolute joints, N for prismatic ones]. Two optional capabilities are declared
by methods, never guessed: :meth:`Controller.jacobian` (∂τ/∂q, ∂τ/∂q̇ for the
implicit integrators) and :meth:`Controller.feedback` (the law is
τ = −kd·q̇ − kp·(q − qf) + G(q): a simulation may then fold an exact gravity
compensation into the dynamics, and a batch of such laws is evaluated as arrays).

What a batch may share: :func:`rrt_pin.simulate.simulate_batch` runs one plant
(one model) and one controller per variant. Laws whose :meth:`feedback` share
the same gravity term are evaluated together (gains and targets stacked);
any other controller is evaluated variant by variant through ``efforts``.

Any object with ``nv`` and ``efforts(t, q, qd)``, or any function
``f(t, q, qd)``, is accepted where a controller is (see :func:`as_controller`).

Laws here:

* :class:`ChapterController`: the chapter's eq. (31), exactly as printed;
* :class:`PDGravityController`: PD plus Pinocchio's gravity compensation, any robot;
* :class:`TrackingController`: computed torque along a prescribed motion
  (feed-forward M(q)·q̈_d + b(q, q̇) with PD on the tracking error).
"""

from __future__ import annotations

import functools
import inspect
import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np

from rrt_pin.errors import (
    ArgumentTypeError,
    ControllerError,
    DivergenceError,
    InputError,
    ParameterError,
)
from rrt_pin.memory import check_data
from rrt_pin.params import PLANT_FIELDS, Params
from rrt_pin.robot import Robot
from rrt_pin.trajectory import Trajectory

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.robot import Robot

__all__ = [
    "ChapterController",
    "Controller",
    "LinearFeedback",
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


@dataclass(frozen=True, eq=False)
class LinearFeedback:
    """The structure τ = −kd·q̇ − kp·(q − qf) + G(q) of a law (see :meth:`Controller.feedback`).

    Attributes:
        kp: stiffness gains (nv,) [N·m/rad or N/m].
        kd: damping gains (nv,) [N·m·s/rad or N·s/m].
        qf: target (nv,) [rad or m].
        gravity: G at configurations (…, nv) -> (…, nv) [N·m or N].
        key: laws with equal keys have the same G (a batch evaluates them together).
        exact_for: whether G is exactly a robot's generalized gravity (then a
            simulation of that robot may fold it into the dynamics).
    """

    kp: np.ndarray
    kd: np.ndarray
    qf: np.ndarray
    gravity: Callable[[np.ndarray], np.ndarray]
    key: Hashable
    exact_for: Callable[[Any], bool]


class Controller(ABC):
    """The contract of a feedback law: efforts from time and state.

    Subclasses implement :attr:`nv` and :meth:`efforts`; they may override
    :meth:`efforts_many` (vectorized), :meth:`jacobian` and :meth:`feedback`.
    """

    @property
    @abstractmethod
    def nv(self) -> int:
        """Number of joint coordinates the law drives."""

    @abstractmethod
    def efforts(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts (nv,) [N·m or N] at time ``t`` [s] and one state ``q``, ``qd`` (nv,)."""

    def efforts_many(self, t: Any, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """Efforts (N, nv) at N states (N, nv); ``t`` one time or N times [s].

        The default calls :meth:`efforts` once per state.
        """
        q = np.asarray(q, dtype=float)
        qd = np.asarray(qd, dtype=float)
        ts = np.broadcast_to(np.asarray(t, dtype=float), q.shape[:1])
        out = np.empty(q.shape)
        for i in range(q.shape[0]):
            out[i] = self.efforts(float(ts[i]), q[i], qd[i])
        return out

    def jacobian(
        self, t: float, q: np.ndarray, qd: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """(∂τ/∂q, ∂τ/∂q̇), each (nv, nv), or None when the law does not provide them."""
        return None

    def feedback(self) -> LinearFeedback | None:
        """The law's PD-plus-gravity structure, or None if it has none."""
        return None

    def __call__(self, *args: Any) -> np.ndarray:
        """``controller(t, q, qd)`` is :meth:`efforts`.

        The old ``controller(q, qd)`` (time 0) is deprecated and kept for one release.
        """
        if len(args) == 2:
            return self.efforts(0.0, *args)
        return self.efforts(*args)


# --------------------------------------------------------------------------
# Adapting user objects: every result of a user's law is checked
# --------------------------------------------------------------------------
#: Relative tolerance between a law's ``efforts_many`` and its ``efforts`` on the rows
#: compared (different vectorised arithmetic may differ in the last bits, not more).
BATCH_AGREEMENT = 1e-9


def _law_name(obj: Any) -> str:
    """A law's name for messages: its function or class name."""
    name = getattr(obj, "__name__", None)
    return name if isinstance(name, str) else type(obj).__name__


def _real_array(value: Any, who: str, call: str, expected: str) -> np.ndarray:
    """``value`` as a float array, or ControllerError naming the law, the call and the value."""
    head = f"the controller {who}'s {call}"
    if value is None:
        raise ControllerError(who, f"{head} returned None; expected {expected}")
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError) as e:  # ragged sequences
        raise ControllerError(who, f"{head} returned {_shown(value)}; expected {expected}") from e
    if arr.dtype.kind == "c":
        bad = arr[np.imag(arr) != 0] if arr.ndim else arr.reshape(1)
        first = complex(bad.flat[0] if bad.size else arr.flat[0])
        raise ControllerError(
            who, f"{head} returned complex numbers ({first:.6g}); expected real {expected}"
        )
    if arr.dtype.kind not in "biuf":
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError) as e:
            raise ControllerError(
                who, f"{head} returned {_shown(value)}; expected {expected}"
            ) from e
        if np.asarray(value).dtype.kind in "USV":  # numbers as text are not numbers
            raise ControllerError(who, f"{head} returned text {_shown(value)}; expected {expected}")
    return np.asarray(arr, dtype=float)


def _shown(value: Any) -> str:
    """A short text of a returned value (at most 60 characters)."""
    text = repr(value) if not isinstance(value, np.ndarray) else f"an array of {value.dtype}"
    return text if len(text) <= 60 else text[:57] + "..."


def _frozen(a: Any) -> np.ndarray:
    """A read-only view of ``a``: a law may read its state, never change it."""
    if type(a) is not np.ndarray or a.dtype != np.float64:
        a = np.asarray(a, dtype=float)
    elif not a.flags.writeable:
        return a  # already read-only (the rows of a frozen batch, an integrator's slices)
    view = a.view()
    view.flags.writeable = False
    return view


def _mutation(who: str, call: str, e: ValueError) -> ControllerError:
    return ControllerError(
        who,
        f"the controller {who}'s {call} writes into its arguments ({e}); a law must not change "
        "q or qd (copy them first: q = q.copy())",
    )


def _finite_state(q: np.ndarray, qd: np.ndarray) -> bool:
    return bool(np.isfinite(q).all() and np.isfinite(qd).all())


class _Checked(Controller):
    """A user's law with every result checked; its inputs are read-only views.

    Checks (each failure one line naming the law, what it returned and what was expected):
    ``efforts`` gives nv real numbers, ``efforts_many`` N×nv (and, when the law
    defines its own, agrees with ``efforts`` on its first, middle and last rows to
    :data:`BATCH_AGREEMENT`: the efforts recorded are the efforts applied), ``jacobian``
    None or two real finite nv×nv arrays; a law that writes into ``q`` or ``qd`` is
    refused (:class:`~rrt_pin.errors.ControllerError`). Non-finite efforts at a finite
    state raise :class:`~rrt_pin.errors.DivergenceError` (time and effort named).
    """

    def __init__(self, obj: Any, nv: int, who: str, names: Sequence[str] | None = None) -> None:
        self.obj, self._nv, self.who = obj, nv, who
        self.names = tuple(names) if names is not None else tuple(f"tau[{k}]" for k in range(nv))

    @property
    def nv(self) -> int:
        return self._nv

    # What the law itself provides (read-only inputs).
    def _one(self, t: float, q: np.ndarray, qd: np.ndarray) -> Any:  # pragma: no cover
        raise NotImplementedError

    def _many(self) -> Callable[..., Any] | None:
        return None

    def _jac(self) -> Callable[..., Any] | None:
        return None

    def __getattr__(self, name: str) -> Any:
        # the law's own attributes (qf, params, kind …) stay visible through the check
        if name == "obj":
            raise AttributeError(name)
        return getattr(self.obj, name)

    def _call(
        self, fn: Callable[..., Any], call: str, t: Any, q: np.ndarray, qd: np.ndarray
    ) -> Any:
        """``fn(t, q, qd)``: a law that writes into q or q̇ (read-only views) is named."""
        try:
            return fn(t, q, qd)
        except ValueError as e:
            if "read-only" in str(e):
                raise _mutation(self.who, call, e) from None
            raise

    def efforts(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """The law's efforts (nv,) [N·m or N], checked."""
        q, qd = _frozen(q), _frozen(qd)
        call = "efforts(t, q, qd)"
        tau = self._call(self._one, call, t, q, qd)
        if type(tau) is np.ndarray and tau.dtype == np.float64 and tau.shape == (self._nv,):
            return tau  # what a law usually returns: nothing to check (every step calls this)
        return self._checked(tau, t, q, qd, (self._nv,), call)

    def efforts_many(self, t: Any, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        """The law's efforts (N, nv) at N states [N·m or N], checked against :meth:`efforts`."""
        many = self._many()
        q, qd = _frozen(q), _frozen(qd)  # once: their rows are read-only too
        if many is None:
            return super().efforts_many(t, q, qd)
        call = "efforts_many(t, q, qd)"
        tau = self._checked(self._call(many, call, t, q, qd), t, q, qd, q.shape, call)
        self._agrees(t, q, qd, tau)
        return tau

    def _checked(
        self, tau: Any, t: Any, q: np.ndarray, qd: np.ndarray, shape: tuple, call: str
    ) -> np.ndarray:
        expected = f"shape {shape}: efforts [N·m or N]"
        out = _real_array(tau, self.who, call, expected)
        if out.shape != shape:
            raise ControllerError(
                self.who,
                f"the controller {self.who} returned shape {out.shape} from {call}; it must be "
                f"{shape} (efforts [N·m or N])",
            )
        if out.ndim == 2:  # efforts_many: the first non-finite row at a finite state, named
            bad = np.argwhere(~np.isfinite(out))
            if bad.size:
                row, k = (int(x) for x in bad[0])
                if _finite_state(q[row], qd[row]):  # else the state diverged first: said so
                    times = np.broadcast_to(np.asarray(t, dtype=float), q.shape[:1])
                    raise DivergenceError(
                        float(times[row]),
                        self.names[k],
                        f"the controller returned {float(out[row, k])} ({self.who}'s {call} at "
                        "a finite state)",
                    )
        # efforts(): a non-finite effort makes a non-finite acceleration, which the
        # integrator reports with its time and coordinate (DivergenceError)
        return out

    def _agrees(self, t: Any, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> None:
        """The batch form against the single form on the first, middle and last rows."""
        n = q.shape[0]
        if n == 0:
            return
        times = np.broadcast_to(np.asarray(t, dtype=float), (n,))
        for i in sorted({0, n // 2, n - 1}):
            one = self.efforts(float(times[i]), q[i], qd[i])
            if not (np.isfinite(one).all() and np.isfinite(tau[i]).all()):
                continue
            scale = max(1.0, float(np.abs(one).max()), float(np.abs(tau[i]).max()))
            diff = np.abs(one - tau[i])
            if diff.max() > BATCH_AGREEMENT * scale:
                k = int(np.argmax(diff))
                raise ControllerError(
                    self.who,
                    f"the controller {self.who}'s efforts_many(t, q, qd) gives "
                    f"{self.names[k]} = {tau[i, k]:.6g} at t={times[i]:.6g} s where "
                    f"efforts(t, q, qd) gives {one[k]:.6g}: the efforts recorded must be the "
                    "efforts applied (fix efforts_many, or remove it)",
                )

    def jacobian(
        self, t: float, q: np.ndarray, qd: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray] | None:
        """The law's (∂τ/∂q, ∂τ/∂q̇), each (nv, nv), checked; None when it gives none."""
        jac = self._jac()
        if jac is None:
            return None
        q, qd = _frozen(q), _frozen(qd)
        call = "jacobian(t, q, qd)"
        pair = self._call(jac, call, t, q, qd)
        if pair is None:
            return None
        n = self._nv
        expected = f"None or (dtau/dq, dtau/dqd), each of shape ({n}, {n}), real and finite"
        if not isinstance(pair, (tuple, list)) or len(pair) != 2 or any(p is None for p in pair):
            raise ControllerError(
                self.who,
                f"the controller {self.who}'s {call} returned {_shown(pair)}; expected {expected}",
            )
        out = []
        for part, value in zip(("dtau/dq", "dtau/dqd"), pair, strict=True):
            arr = _real_array(value, self.who, f"{call} ({part})", expected)
            if arr.shape != (n, n):
                raise ControllerError(
                    self.who,
                    f"the controller {self.who}'s {call} returned {part} of shape {arr.shape}; "
                    f"expected {expected}",
                )
            if not np.isfinite(arr).all() and _finite_state(q, qd):
                i, j = (int(x) for x in np.argwhere(~np.isfinite(arr))[0])
                raise ControllerError(
                    self.who,
                    f"the controller {self.who}'s {call} returned {part}[{i}, {j}] = "
                    f"{float(arr[i, j])} at t={float(t):.6g} s (a finite state); expected "
                    f"{expected}",
                )
            out.append(arr)
        return out[0], out[1]


class _FunctionController(_Checked):
    """A plain function ``f(t, q, qd)`` (or a legacy ``f(q, qd)``) as a Controller."""

    def __init__(
        self, f: Callable[..., Any], nv: int, timed: bool, names: Sequence[str] | None = None
    ) -> None:
        super().__init__(f, nv, _law_name(f), names)
        self.f, self.timed = f, timed

    def _one(self, t: float, q: np.ndarray, qd: np.ndarray) -> Any:
        return self.f(t, q, qd) if self.timed else self.f(q, qd)


class _DuckController(_Checked):
    """Any object with ``efforts(t, q, qd)`` (and maybe ``efforts_many``, ``jacobian``).

    A user's subclass of :class:`Controller` is checked the same way.
    """

    def __init__(self, obj: Any, nv: int, names: Sequence[str] | None = None) -> None:
        super().__init__(obj, nv, type(obj).__name__, names)

    def _one(self, t: float, q: np.ndarray, qd: np.ndarray) -> Any:
        return self.obj.efforts(t, q, qd)

    def _many(self) -> Callable[..., Any] | None:
        many = getattr(self.obj, "efforts_many", None)
        if many is None:
            return None
        if isinstance(self.obj, Controller) and type(self.obj).efforts_many is (
            Controller.efforts_many
        ):
            return None  # the default loop over efforts: checked row by row here
        return many

    def _jac(self) -> Callable[..., Any] | None:
        jac = getattr(self.obj, "jacobian", None)
        return jac if callable(jac) else None

    def feedback(self) -> LinearFeedback | None:
        """The law's own feedback structure (a Controller subclass may declare one)."""
        feedback = getattr(self.obj, "feedback", None)
        return feedback() if callable(feedback) else None


def _positional_count(f: Callable[..., Any]) -> int | None:
    try:
        sig = inspect.signature(f)
    except (TypeError, ValueError):
        return None
    kinds = (inspect.Parameter.POSITIONAL_ONLY, inspect.Parameter.POSITIONAL_OR_KEYWORD)
    params = list(sig.parameters.values())
    if any(p.kind is inspect.Parameter.VAR_POSITIONAL for p in params):
        return None
    return sum(1 for p in params if p.kind in kinds)


def as_controller(obj: Any, nv: int, names: Sequence[str] | None = None) -> Controller:
    """``obj`` as a :class:`Controller` of ``nv`` coordinates, its results checked.

    Accepts a Controller; an object with ``efforts(t, q, qd)``; a function
    ``f(t, q, qd)``; or a time-invariant function ``f(q, qd)``. The laws this
    module defines are returned as they are; any other is wrapped so that each of
    its results is checked and its inputs are read-only (see :class:`_Checked`).

    Args:
        obj: the law.
        nv: number of joint coordinates of the robot.
        names: the efforts' names, for messages (default ``tau[0]``…).

    Raises:
        ArgumentTypeError: ``obj`` is none of these.
        InputError: it drives another number of joints, or its function takes
            neither (t, q, qd) nor (q, qd).
    """
    if type(obj) in _TRUSTED:
        controller = obj
    elif isinstance(obj, Controller) or (
        callable(getattr(obj, "efforts", None)) and _positional_count(obj.efforts) == 3
    ):
        controller = _DuckController(obj, int(getattr(obj, "nv", nv)), names)
    elif callable(obj):
        count = _positional_count(obj)
        if count not in (2, 3):
            raise InputError(
                f"controller {_law_name(obj)} must take (t, q, qd) (or (q, qd) for a "
                "time-invariant law)"
            )
        controller = _FunctionController(obj, nv, timed=count == 3, names=names)
    else:
        raise ArgumentTypeError(
            "controller",
            f"controller must be a Controller, an object with efforts(t, q, qd) or a function "
            f"f(t, q, qd), not {type(obj).__name__}",
        )
    if controller.nv != nv:
        raise InputError(f"the controller drives {controller.nv} joints but the robot has {nv}")
    return controller


# --------------------------------------------------------------------------
# Gains
# --------------------------------------------------------------------------
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


def _chapter_model(params: Params) -> pin.Model:
    return _plant_model(tuple(getattr(params, name) for name in PLANT_FIELDS))


@functools.lru_cache(maxsize=8)
def _plant_model(plant: tuple[float, ...]) -> pin.Model:

    from rrt_pin.model import rrt_model

    return rrt_model(Params(**dict(zip(PLANT_FIELDS, plant, strict=True))))


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
        return bool(model == _chapter_model(self.params))

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
        robot: its :class:`~rrt_pin.robot.Robot` (built from the model when None).
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
            :class:`~rrt_pin.trajectory.Trajectory` (e.g.
            :class:`~rrt_pin.trajectory.RestToRest`), or a sampled Trajectory
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


def chapter_controller(params: Params | None = None) -> ChapterController:
    """The chapter's eq. (31) with the gains, target and arm of ``params`` (the chapter's by default).

    Raises:
        ParameterError: a gain is negative or not finite.
    """
    p = params if params is not None else Params()
    return ChapterController(kp=p.kp, kd=p.kd, qf=p.qf, params=p)


def pd_gravity_controller(
    model: pin.Model,
    kp: float | Sequence[float],
    kd: float | Sequence[float],
    qf: Sequence[float],
) -> PDGravityController:
    """PD plus Pinocchio's gravity compensation for ``model``.

    Args:
        model: any Pinocchio model (its gravity vector is used as set).
        kp: stiffness gains [N·m/rad or N/m]: one per coordinate, or one for all.
        kd: damping gains [N·m·s/rad or N·s/m]: one per coordinate, or one for all.
        qf: target joint coordinates (nv,) [rad or m] (or Pinocchio's (nq,)).

    Raises:
        ParameterError: a gain is negative or not finite (names it, e.g. ``kd[2]``).
        InputError: a gain or target has the wrong length, or a target is not finite.
    """
    return PDGravityController(kp=kp, kd=kd, qf=qf, model=model)  # type: ignore[arg-type]


def tracking_controller(
    robot: Any, motion: Any, kp: Any = 100.0, kd: Any = 20.0
) -> TrackingController:
    """Computed torque along ``motion`` for ``robot`` (a Robot or a Pinocchio model).

    Raises:
        InputError: a bad robot, motion or gain.
    """
    if not isinstance(robot, Robot):
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
_TRUSTED = (ChapterController, PDGravityController, TrackingController)

#: Deprecated names (kept for one release): the chapter was called "the seed".
SeedController = ChapterController
seed_controller = chapter_controller
