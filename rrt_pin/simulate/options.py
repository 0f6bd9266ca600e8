"""A run's backend, method and tolerances, resolved from the registries and checked once.

The tolerances of an adaptive method follow the accuracy asked for (``accuracy=``,
default :data:`rrt_pin.simulate.methods.ACCURACY`, 1e-8 rad or m): the calibration's
loosest setting that keeps it (:func:`rrt_pin.simulate.methods.tolerances`);
``rtol`` and ``atol`` given explicitly win.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rrt_pin.core import backends, validate
from rrt_pin.core.errors import InputError
from rrt_pin.simulate import methods
from rrt_pin.simulate.methods import Method

__all__ = ["JACOBIANS", "MAX_FIXED_STEPS", "ODEPACK_MIN_FIRST_INTERVAL", "Options", "resolve"]

#: How the implicit methods get their Jacobian.
JACOBIANS = ("analytic", "finite-difference")

#: The steps a fixed-step run may take, by backend, counted before it starts (a run
#: cannot be interrupted once it is in a solver or in machine code): each limit keeps
#: the chapter's arm with rk4 under a minute on its backend (compiled: the compiled
#: loop's own step budget, :data:`rrt_pin.compiled.integrate.MAX_STEPS`). The error
#: estimate's run takes twice as many (half the step).
MAX_FIXED_STEPS = {"pinocchio": 1_000_000, "compiled": 10_000_000}
#: The shortest first output interval ODEPACK's LSODA starts on [s]: below ~1e-148 s
#: its first-step estimate underflows (it returns NaN and says "Integration
#: successful"), and it refuses an interval under a few float64 epsilons of t.
ODEPACK_MIN_FIRST_INTERVAL = 1e-100


@dataclass(frozen=True)
class Options:
    """What :func:`resolve` decided.

    Attributes:
        backend: the backend's name.
        method: the method (a registry entry).
        rtol: relative tolerance (adaptive methods), else None.
        atol: absolute tolerance [rad, m, rad/s, m/s] (adaptive methods), else None.
        step: longest step [s] (fixed-step methods), else None.
        jacobian: ``analytic`` or ``finite-difference``.
        accuracy: the accuracy asked for, max |q − q_exact| over the output times
            [rad or m], that the error estimate is judged against: ``accuracy=``
            when given; else :data:`~rrt_pin.simulate.methods.ACCURACY` (1e-8), or
            the looser of it and an explicit rtol or atol (a run at looser
            tolerances asks for no better than them).
    """

    backend: str
    method: Method
    rtol: float | None
    atol: float | None
    step: float | None
    jacobian: str = "analytic"
    accuracy: float = methods.ACCURACY


def resolve(
    t: np.ndarray,
    *,
    backend: Any = "pinocchio",
    method: Any = None,
    rtol: Any = None,
    atol: Any = None,
    step: Any = None,
    jacobian: Any = "analytic",
    batch: bool = False,
    accuracy: Any = None,
) -> Options:
    """Check and complete a run's options: the backend's default method, the tolerances.

    Without ``rtol`` and ``atol``, an adaptive method runs at the tolerances the
    calibration gives for ``accuracy`` on its backend
    (:func:`rrt_pin.simulate.methods.tolerances`). ``rtol`` alone sets the whole
    run's: ``atol`` then keeps the calibration's ratio to it (rtol/100 [rad, m,
    rad/s, m/s]), so that it does not stay at its default and dominate once the
    motion settles; ``atol`` alone keeps the calibrated rtol.

    Args:
        t: output times [s].
        backend: the backend's name.
        method: the method's name (None: the backend's default).
        rtol: relative tolerance, in (0, 1), or None.
        atol: absolute tolerance [rad, m, rad/s, m/s], in (0, 1), or None.
        step: longest step of a fixed-step method [s], or None (the shortest interval).
        jacobian: ``analytic`` or ``finite-difference``.
        batch: for ``simulate_batch`` (the method must run in a batch).
        accuracy: the accuracy asked for, max |q − q_exact| over the output times
            [rad or m], in (0, 1); None for the default, 1e-8.

    Raises:
        InputError: an unknown backend or method, a method the backend does not
            run (in a batch), a tolerance, accuracy or step that is not a finite
            number in range (a tolerance or accuracy must lie in (0, 1)), or an
            rtol below the method's floor (:attr:`~rrt_pin.simulate.methods.Method.min_rtol`,
            named).
    """
    key = (backend, method, rtol, atol, step, jacobian, batch, accuracy, type(rtol), type(atol),
           type(step), type(accuracy))  # fmt: skip
    try:
        known = _RESOLVED.get(key)
    except TypeError:  # an unhashable value: resolved (and refused) below
        key, known = None, None
    if known is not None:
        _check_grid(t, known)
        return known
    options = _resolve(t, backend, method, rtol, atol, step, jacobian, batch, accuracy)
    _check_grid(t, options)
    if key is not None and (options.method.adaptive or step is not None):  # not from t
        if len(_RESOLVED) >= 64:
            _RESOLVED.clear()
        _RESOLVED[key] = options
    return options


def fixed_steps(t: np.ndarray, step: float) -> float:
    """The steps a fixed-step run over the output times ``t`` takes with ``step`` [s].

    Each output interval is cut into ceil(interval / step) equal steps (as
    :func:`rrt_pin.simulate.integrators.integrate_fixed_step` does); a float, as it may be huge.
    """
    with np.errstate(over="ignore"):
        per = np.ceil(np.diff(t) / step * (1.0 - 1e-12))
    return float(np.maximum(per, 1.0).sum())


def _check_grid(t: np.ndarray, options: Options) -> None:
    """Refuse, before any work, a run its method cannot do in bounded time, or at all.

    Raises:
        InputError: a fixed-step run of more than :data:`MAX_FIXED_STEPS` steps, or an
            ``odepack`` run whose first output interval LSODA cannot start on.
    """
    m = options.method
    if not m.adaptive and options.step is not None:
        limit = MAX_FIXED_STEPS.get(options.backend, MAX_FIXED_STEPS["pinocchio"])
        steps = fixed_steps(t, options.step)
        if steps > limit:
            span = float(t[-1] - t[0])
            raise InputError(
                f"method {m.name!r} would take {steps:.3g} steps ({span:.6g} s of output "
                f"times at step={options.step:.3g} s): more than the {limit:,} a run may take "
                f"on backend {options.backend!r}; use a longer step (or fewer output times)"
            )
    if m.name == "odepack" and t.size >= 2:
        first = float(t[1] - t[0])
        least = max(
            ODEPACK_MIN_FIRST_INTERVAL, 8 * np.finfo(float).eps * float(np.abs(t[:2]).max())
        )
        if first < least:
            raise InputError(
                f"method 'odepack' cannot start on a first output interval of {first:.3g} s "
                f"(LSODA needs at least {least:.3g} s there); use a longer interval, or "
                "another method (e.g. DOP853)"
            )


#: Options resolved before, by their arguments (and their types: ``True`` is not ``1``),
#: when they do not depend on the output times.
_RESOLVED: dict[tuple, Options] = {}


def _resolve(
    t: np.ndarray,
    backend: Any,
    method: Any,
    rtol: Any,
    atol: Any,
    step: Any,
    jacobian: Any,
    batch: bool,
    accuracy: Any = None,
) -> Options:
    b = backends.get(backend, "simulate")
    m = methods.get(method if method is not None else b.default_method, b.name, batch=batch)
    validate.choice("jacobian", jacobian, JACOBIANS)
    r = validate.tolerance("rtol", rtol) if rtol is not None else None
    a = validate.tolerance("atol", atol, "rad, m, rad/s, m/s") if atol is not None else None
    s = validate.real("step", step, "s", positive=True) if step is not None else None
    asked = validate.tolerance("accuracy", accuracy, "rad or m") if accuracy is not None else None
    target = asked if asked is not None else methods.ACCURACY
    if m.adaptive:
        if r is not None and m.min_rtol is not None and r < m.min_rtol:
            raise InputError(
                f"rtol={r!r} is below {m.name}'s floor of {m.min_rtol:.3g} (100 float64 "
                "epsilons: no tighter relative error can be honoured); use rtol >= "
                f"{m.min_rtol:.3g} (its default is {m.rtol:g})"
            )
        given = r is not None or a is not None
        chosen_r, chosen_a = methods.tolerances(b.name, m.name, target)
        if a is None:
            a = chosen_a if r is None else r * (chosen_a / chosen_r)
        rtol_ = r if r is not None else chosen_r
        if asked is None and given:
            target = max(target, rtol_, a)
        return Options(b.name, m, rtol_, a, None, jacobian, target)
    if s is None:
        s = float(np.diff(t).min())
    if s <= 0.0:  # pragma: no cover - validate.times refuses such grids
        raise InputError(f"step={s!r} must be > 0 [s]")
    return Options(b.name, m, None, None, s, jacobian, target)
