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

    Raises:
        InputError: an unknown backend or method, a method the backend does not
            run (in a batch), or a tolerance or step that is not a finite
            number in range (a tolerance must lie in (0, 1)).
    """
    b = backends.get(backend, "simulate")
    m = methods.get(method if method is not None else b.default_method, b.name, batch=batch)
    validate.choice("jacobian", jacobian, JACOBIANS)
    r = validate.tolerance("rtol", rtol) if rtol is not None else None
    a = validate.tolerance("atol", atol, "rad, m, rad/s, m/s") if atol is not None else None
    s = validate.real("step", step, "s", positive=True) if step is not None else None
    if m.adaptive:
        return Options(b.name, m, r if r is not None else m.rtol, a if a is not None else m.atol,
                       None, jacobian)  # fmt: skip
    if s is None:
        s = float(np.diff(t).min())
    if s <= 0.0:  # pragma: no cover - validate.times refuses such grids
        raise InputError(f"step={s!r} must be > 0 [s]")
    return Options(b.name, m, None, None, s, jacobian)
