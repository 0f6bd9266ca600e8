"""Closed-form dynamics of the RRT arm in machine code, for one state or many.

The same quantities as :mod:`rrt_pin.kernel` (the generated numpy kernel) and
Pinocchio's CRBA/RNEA/ABA on :func:`rrt_pin.model.rrt_model`, computed by the
kernel's ``terms`` compiled with numba, one loop over the samples. Arrays have
shape (N, 3) (or (3,) for one state); results keep that leading shape. Units:
q [rad, rad, m], q̇ [rad/s, rad/s, m/s], q̈ [rad/s², rad/s², m/s²],
τ = (T01x [N·m], T12y [N·m], F23z [N]), M [kg·m², kg·m, kg].

The first call in a process imports numba and compiles or loads the machine
code (see :func:`rrt_pin.compiled.ensure_compiled`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.compiled import ensure_compiled
from rrt_pin.errors import InputError

if TYPE_CHECKING:
    from rrt_pin.params import Params

__all__ = [
    "coriolis",
    "forward_dynamics",
    "gravity",
    "inverse_dynamics",
    "mass_matrix",
    "nonlinear_effects",
    "param_array",
]

_UNITS = {
    "q": "rad, rad, m",
    "qd": "rad/s, rad/s, m/s",
    "qdd": "rad/s², rad/s², m/s²",
    "tau": "N·m, N·m, N",
}


def param_array(params: Params) -> np.ndarray:
    """The 15 physical parameters in ``rrt_pin.kernel.PARAM_ORDER`` (float64, SI units).

    Raises:
        InputError: ``params`` is not a :class:`~rrt_pin.params.Params`.
    """
    from rrt_pin.kernel import param_vector
    from rrt_pin.params import Params

    if not isinstance(params, Params):
        raise InputError(f"params must be a Params, not {type(params).__name__}")
    return np.ascontiguousarray(param_vector(params), dtype=np.float64)


def _states(*named: tuple[str, Any]) -> tuple[tuple[np.ndarray, ...], bool]:
    """Finite C-contiguous (N, 3) float64 arrays of one length; True if given as (3,)."""
    arrays = []
    single = None
    for name, value in named:
        try:
            a = np.asarray(value, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise InputError(f"{name} is not an array of numbers [{_UNITS[name]}]") from e
        if a.ndim not in (1, 2) or a.shape[-1] != 3:
            raise InputError(f"{name}.shape={a.shape} but (N, 3) or (3,) expected [{_UNITS[name]}]")
        one = a.ndim == 1
        if single is None:
            single = one
        elif single != one:
            raise InputError(f"{name}.shape={a.shape} does not match {named[0][0]}'s shape")
        bad = np.argwhere(~np.isfinite(a))
        if bad.size:
            where = tuple(int(i) for i in bad[0])
            raise InputError(
                f"{name}[{', '.join(map(str, where))}]={float(a[where])!r} must be finite "
                f"[{_UNITS[name]}]"
            )
        arrays.append(np.ascontiguousarray(a.reshape(-1, 3)))
    n = arrays[0].shape[0]
    for (name, _), a in zip(named, arrays, strict=True):
        if a.shape[0] != n:
            raise InputError(f"{name} has {a.shape[0]} rows but {named[0][0]} has {n}")
    return tuple(arrays), bool(single)


def _jit():
    ensure_compiled()
    from rrt_pin.compiled import _jit_dynamics

    return _jit_dynamics


def mass_matrix(q: Any, params: Params) -> np.ndarray:
    """M(q), shape (N, 3, 3) (or (3, 3)) [kg·m², kg·m, kg].

    Raises:
        InputError: bad shape or non-finite values.
    """
    (q,), one = _states(("q", q))
    p = param_array(params)
    out = np.empty((q.shape[0], 3, 3))
    _jit().mass_matrix_batch(q, p, out)
    return out[0] if one else out


def _bias(q: Any, qd: Any, params: Params, which: int) -> np.ndarray:
    (q, qd), one = _states(("q", q), ("qd", qd))
    p = param_array(params)
    out = np.empty(q.shape)
    _jit().bias_batch(q, qd, p, which, out)
    return out[0] if one else out


def nonlinear_effects(q: Any, qd: Any, params: Params) -> np.ndarray:
    """c(q, q̇) + G(q), shape (N, 3) (or (3,)) [N·m, N·m, N] (Pinocchio's ``nonLinearEffects``)."""
    return _bias(q, qd, params, 0)


def coriolis(q: Any, qd: Any, params: Params) -> np.ndarray:
    """The velocity terms c(q, q̇) alone, shape (N, 3) (or (3,)) [N·m, N·m, N]."""
    return _bias(q, qd, params, 1)


def gravity(q: Any, params: Params) -> np.ndarray:
    """G(q), shape (N, 3) (or (3,)) [N·m, N·m, N] (Pinocchio's ``computeGeneralizedGravity``)."""
    (q,), one = _states(("q", q))
    p = param_array(params)
    out = np.empty(q.shape)
    _jit().bias_batch(q, q, p, 2, out)
    return out[0] if one else out


def inverse_dynamics(q: Any, qd: Any, qdd: Any, params: Params) -> np.ndarray:
    """τ = M(q)·q̈ + c(q, q̇) + G(q), shape (N, 3) (or (3,)) [N·m, N·m, N] (RNEA).

    Raises:
        InputError: bad shapes or non-finite values.
    """
    (q, qd, qdd), one = _states(("q", q), ("qd", qd), ("qdd", qdd))
    p = param_array(params)
    out = np.empty(q.shape)
    _jit().inverse_batch(q, qd, qdd, p, out)
    return out[0] if one else out


def forward_dynamics(q: Any, qd: Any, tau: Any, params: Params) -> np.ndarray:
    """q̈ = M(q)⁻¹·(τ − c − G) by a closed-form LDLᵀ solve, (N, 3) (or (3,)) [rad/s², m/s²] (ABA).

    Raises:
        InputError: bad shapes, non-finite values, or M(q) not positive
            definite at some sample (degenerate parameters).
    """
    (q, qd, tau), one = _states(("q", q), ("qd", qd), ("tau", tau))
    p = param_array(params)
    out = np.empty(q.shape)
    bad = _jit().forward_batch(q, qd, tau, p, out)
    if bad >= 0:
        raise InputError(f"the mass matrix is singular at q[{bad}]={q[bad].tolist()!r}")
    return out[0] if one else out
