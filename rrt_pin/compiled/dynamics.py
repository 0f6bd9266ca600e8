"""Closed-form dynamics of the RRT arm in machine code, for one state or many.

The same quantities as :mod:`rrt_pin.dynamics.kernel` (the generated numpy kernel) and
Pinocchio's CRBA/RNEA/ABA on :func:`rrt_pin.robot.model.rrt_model`, computed by the
kernel's ``terms`` compiled with numba, one loop over the samples. Arrays have
shape (N, 3) (or (3,) for one state); results keep that leading shape. Units:
q [rad, rad, m], q̇ [rad/s, rad/s, m/s], q̈ [rad/s², rad/s², m/s²],
τ = (T01x [N·m], T12y [N·m], F23z [N]), M [kg·m², kg·m, kg].

The first call in a process loads the ahead-of-time module of these functions
when it is built (:mod:`rrt_pin.compiled._aot`: no numba import), else imports
numba and compiles or loads the machine code (see
:func:`rrt_pin.compiled.ensure_compiled`, which also builds that module once).
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.dynamics.kernel import param_vector
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import CHAPTER_COLUMNS

if TYPE_CHECKING:
    from rrt_pin.robot.params import Params

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
    """The 15 physical parameters in ``rrt_pin.dynamics.kernel.PARAM_ORDER`` (float64, SI units, read-only).

    Raises:
        InputError: ``params`` is not a :class:`~rrt_pin.robot.params.Params`.
    """
    if not isinstance(params, Params):
        raise InputError(f"params must be a Params, not {type(params).__name__}")
    return _param_array(params)


@functools.lru_cache(maxsize=256)
def _param_array(params: Params) -> np.ndarray:

    p = np.ascontiguousarray(param_vector(params), dtype=np.float64)
    p.setflags(write=False)
    return p


def _states(*named: tuple[str, Any]) -> tuple[tuple[np.ndarray, ...], bool]:
    """C-contiguous (N, 3) float64 arrays of one length; True if given as (3,).

    Finiteness is checked by the compiled loops as they read the values (see
    :func:`_refuse_nonfinite`), not here: a pass over the arrays in numpy would
    cost about as much as the dynamics.
    """
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
        arrays.append(np.ascontiguousarray(a.reshape(-1, 3)))
    n = arrays[0].shape[0]
    for (name, _), a in zip(named, arrays, strict=True):
        if a.shape[0] != n:
            raise InputError(f"{name} has {a.shape[0]} rows but {named[0][0]} has {n}")
    return tuple(arrays), bool(single)


def _refuse_nonfinite(
    check: float, named: tuple[tuple[str, np.ndarray], ...], single: bool
) -> None:
    """Raise for the first non-finite input if a compiled loop flagged one (``check`` is nan)."""
    if np.isfinite(check):
        return
    for name, a in named:
        bad = np.argwhere(~np.isfinite(a))
        if bad.size:
            row, k = (int(i) for i in bad[0])
            where = f"{k}" if single else f"{row}, {k}"
            raise InputError(
                f"{name}[{where}]={float(a[row, k])!r} must be finite [{_UNITS[name]}]"
            )


def _refuse_overflow(check: float, out: np.ndarray) -> None:
    """Raise if an effort is not finite although every input is (values out of range)."""
    if not np.isfinite(check):
        bad = np.argwhere(~np.isfinite(out))
        if bad.size:
            i, k = (int(x) for x in bad[0])
            raise InputError(
                f"the efforts overflow: {CHAPTER_COLUMNS[3][k]} = {float(out[i, k])!r} at "
                f"sample {i} (positions, velocities, accelerations or parameters beyond any "
                "sensible range)"
            )


def _jit():
    """The dynamics' machine code: the ahead-of-time module when built, else numba's JIT."""
    from rrt_pin.compiled import machine_code

    return machine_code()


def mass_matrix(q: Any, params: Params) -> np.ndarray:
    """M(q), shape (N, 3, 3) (or (3, 3)) [kg·m², kg·m, kg].

    Raises:
        InputError: bad shape or non-finite values.
    """
    (q,), one = _states(("q", q))
    p = param_array(params)
    out = np.empty((q.shape[0], 3, 3))
    _refuse_nonfinite(_jit().mass_matrix_batch(q, p, out), (("q", q),), one)
    return out[0] if one else out


def _bias(q: Any, qd: Any, params: Params, which: int) -> np.ndarray:
    (q, qd), one = _states(("q", q), ("qd", qd))
    p = param_array(params)
    out = np.empty(q.shape)
    _refuse_nonfinite(_jit().bias_batch(q, qd, p, which, out), (("q", q), ("qd", qd)), one)
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
    _refuse_nonfinite(_jit().bias_batch(q, q, p, 2, out), (("q", q),), one)
    return out[0] if one else out


def inverse_dynamics(q: Any, qd: Any, qdd: Any, params: Params) -> np.ndarray:
    """τ = M(q)·q̈ + c(q, q̇) + G(q), shape (N, 3) (or (3,)) [N·m, N·m, N] (RNEA).

    The compiled loop flags non-finite inputs and efforts as it runs; the numpy
    passes that name them run only when it does.

    Raises:
        InputError: bad shapes, non-finite values, or efforts that overflow.
    """
    (q, qd, qdd), one = _states(("q", q), ("qd", qd), ("qdd", qdd))
    p = param_array(params)
    out = np.empty(q.shape)
    check = _jit().inverse_batch(q, qd, qdd, p, out)
    _refuse_nonfinite(check, (("q", q), ("qd", qd), ("qdd", qdd)), one)
    _refuse_overflow(check, out)
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
    check, bad = _jit().forward_batch(q, qd, tau, p, out)
    _refuse_nonfinite(check, (("q", q), ("qd", qd), ("tau", tau)), one)
    if bad >= 0:
        raise InputError(
            f"the mass matrix is singular or ill-conditioned at q[{bad}]={q[bad].tolist()!r}"
        )
    return out[0] if one else out
