"""A run's backend, method and tolerances, resolved from the registries and checked once."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from rrt_pin import backends, methods, validate
from rrt_pin.errors import InputError
from rrt_pin.methods import Method

__all__ = ["JACOBIANS", "Options", "resolve"]

#: How the implicit methods get their Jacobian.
JACOBIANS = ("analytic", "finite-difference")


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
    """

    backend: str
    method: Method
    rtol: float | None
    atol: float | None
    step: float | None
    jacobian: str = "analytic"


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
) -> Options:
    """Check and complete a run's options: the backend's default method, the method's tolerances.

    ``rtol`` alone tightens the whole run: ``atol`` then keeps the method's default
    ratio to it (``atol = rtol · default atol / default rtol``, i.e. rtol/100 [rad, m,
    rad/s, m/s]), so that it does not stay at its default and dominate once the
    motion settles.

    Raises:
        InputError: an unknown backend or method, a method the backend does not
            run (in a batch), a tolerance or step that is not a finite number in
            range (a tolerance must lie in (0, 1)), or an rtol below the method's
            floor (:attr:`~rrt_pin.methods.Method.min_rtol`, named).
    """
    key = (backend, method, rtol, atol, step, jacobian, batch, type(rtol), type(atol), type(step))
    try:
        known = _RESOLVED.get(key)
    except TypeError:  # an unhashable value: resolved (and refused) below
        key, known = None, None
    if known is not None:
        return known
    options = _resolve(t, backend, method, rtol, atol, step, jacobian, batch)
    if key is not None and (options.method.adaptive or step is not None):  # not from t
        if len(_RESOLVED) >= 64:
            _RESOLVED.clear()
        _RESOLVED[key] = options
    return options


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
) -> Options:
    b = backends.get(backend, "simulate")
    m = methods.get(method if method is not None else b.default_method, b.name, batch=batch)
    validate.choice("jacobian", jacobian, JACOBIANS)
    r = validate.tolerance("rtol", rtol) if rtol is not None else None
    a = validate.tolerance("atol", atol, "rad, m, rad/s, m/s") if atol is not None else None
    s = validate.real("step", step, "s", positive=True) if step is not None else None
    if m.adaptive:
        if r is not None and m.min_rtol is not None and r < m.min_rtol:
            raise InputError(
                f"rtol={r!r} is below {m.name}'s floor of {m.min_rtol:.3g} (100 float64 "
                "epsilons: no tighter relative error can be honoured); use rtol >= "
                f"{m.min_rtol:.3g} (its default is {m.rtol:g})"
            )
        if a is None:
            a = m.atol if r is None else r * (m.atol / m.rtol)
        return Options(b.name, m, r if r is not None else m.rtol, a, None, jacobian)
    if s is None:
        s = float(np.diff(t).min())
    if s <= 0.0:  # pragma: no cover - validate.times refuses such grids
        raise InputError(f"step={s!r} must be > 0 [s]")
    return Options(b.name, m, None, None, s, jacobian)
