"""The contract every feedback law follows, and how any law is held to it.

The contract (:class:`Controller`) gives time to the law, as robotics-toolbox,
MuJoCo and Drake do::

    tau = controller.efforts(t, q, qd)          # one state: (nv,) -> (nv,)
    tau = controller.efforts_many(t, Q, QD)     # N states (N, nv), t scalar or (N,)

with ``t`` [s], ``q`` the joint coordinates [rad or m] (angles for continuous
joints, see :mod:`rrt_pin.robot.robot`), ``qd`` [rad/s or m/s] and efforts [N·m for
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
``f(t, q, qd)``, is accepted where a controller is (see :func:`as_controller`);
its results are checked at every call unless it is one of the laws rrt-pin ships
(:mod:`rrt_pin.simulate.control`, registered with :func:`trusted`).
"""

from __future__ import annotations

import inspect
from abc import ABC, abstractmethod
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core.errors import ArgumentTypeError, ControllerError, DivergenceError, InputError

if TYPE_CHECKING:
    pass

__all__ = ["BATCH_AGREEMENT", "Controller", "LinearFeedback", "as_controller", "trusted"]

#: The laws whose results are trusted (tested), not checked at every call: exact types.
_TRUSTED: set[type] = set()


def trusted(cls: type) -> type:
    """Register ``cls`` (a law rrt-pin ships and tests) as exempt from per-call checks."""
    _TRUSTED.add(cls)
    return cls


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
    refused (:class:`~rrt_pin.core.errors.ControllerError`). Non-finite efforts at a finite
    state raise :class:`~rrt_pin.core.errors.DivergenceError` (time and effort named).
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
