"""The RRT arm's dynamics in closed form, for arrays of states (numpy; ordinary code).

The expressions come from the sympy derivation, generated into
:mod:`rrt_pin.dynamics._kernel_terms` (``terms``, ``inverse_terms``, ``forward_terms``;
do not edit that file: ``python -m rrt_pin.dynamics.symbolic.codegen`` rewrites it and
``tests/test_kernel.py`` fails when it drifts). This module takes arrays of states
of shape (N, 3) (or one state of shape (3,)) and a :class:`rrt_pin.robot.params.Params`,
checks them, and evaluates the expressions. Units: q [rad, rad, m], q̇ [rad/s,
rad/s, m/s], q̈ [rad/s², rad/s², m/s²], τ = (T01x [N·m], T12y [N·m], F23z [N]).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.dynamics._kernel_terms import (
    FORWARD_FLOPS,
    INVERSE_FLOPS,
    forward_terms,
    inverse_constants,
    inverse_terms,
    terms,
)
from rrt_pin.robot.params import PLANT_FIELDS

if TYPE_CHECKING:
    from rrt_pin.robot.params import Params

__all__ = [
    "FORWARD_FLOPS",
    "INVERSE_FLOPS",
    "PARAM_ORDER",
    "forward_dynamics",
    "forward_terms",
    "gravity",
    "inverse_constants",
    "inverse_dynamics",
    "inverse_terms",
    "mass_matrix",
    "nonlinear_effects",
    "param_vector",
    "terms",
]

#: The parameters of ``terms``, in order (the chapter's symbols, SI units): the plant's
#: fields, :data:`rrt_pin.robot.params.PLANT_FIELDS`, the one list of them.
PARAM_ORDER = PLANT_FIELDS


def param_vector(params: Params) -> np.ndarray:
    """The parameters in ``PARAM_ORDER`` as a float64 array (SI units)."""
    return np.array([getattr(params, name) for name in PARAM_ORDER], dtype=np.float64)


def _states(name: str, a: np.ndarray) -> np.ndarray:
    """``a`` as a finite float64 array of shape (N, 3) (or (3,))."""
    a = np.asarray(a, dtype=np.float64)
    if a.ndim not in (1, 2) or a.shape[-1] != 3:
        raise InputError(f"{name}.shape={a.shape} but (N, 3) or (3,) expected")
    if not np.all(np.isfinite(a)):
        raise InputError(f"{name} has non-finite values")
    return a


def _terms(q: np.ndarray, qd: np.ndarray, params: Params) -> tuple:
    return terms(
        q[..., 0], q[..., 1], q[..., 2], qd[..., 0], qd[..., 1], qd[..., 2], *param_vector(params)
    )


def _stack(shape: tuple[int, ...], values: tuple) -> np.ndarray:
    """Arrays (or floats) ``values`` broadcast to ``shape`` and stacked on a last axis."""
    return np.stack(
        [np.broadcast_to(np.asarray(v, dtype=np.float64), shape) for v in values], axis=-1
    )


def mass_matrix(q: np.ndarray, params: Params) -> np.ndarray:
    """M(q), shape (N, 3, 3) (or (3, 3)) [kg·m², kg·m, kg]."""
    q = _states("q", q)
    M11, M12, M13, M22, M23, M33 = _terms(q, np.zeros_like(q), params)[:6]
    rows = (M11, M12, M13, M12, M22, M23, M13, M23, M33)
    return _stack(q.shape[:-1], rows).reshape(*q.shape[:-1], 3, 3)


def nonlinear_effects(q: np.ndarray, qd: np.ndarray, params: Params) -> np.ndarray:
    """c(q, q̇) + G(q), shape (N, 3) (or (3,)) [N·m, N·m, N]."""
    q, qd = _states("q", q), _states("qd", qd)
    _, _, _, _, _, _, c1, c2, c3, G1, G2, G3 = _terms(q, qd, params)
    return _stack(np.broadcast_shapes(q.shape, qd.shape)[:-1], (c1 + G1, c2 + G2, c3 + G3))


def gravity(q: np.ndarray, params: Params) -> np.ndarray:
    """G(q), shape (N, 3) (or (3,)) [N·m, N·m, N]."""
    q = _states("q", q)
    G1, G2, G3 = _terms(q, np.zeros_like(q), params)[9:]
    return _stack(q.shape[:-1], (G1, G2, G3))


def inverse_dynamics(q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, params: Params) -> np.ndarray:
    """τ = M(q)·q̈ + c(q, q̇) + G(q), shape (N, 3) (or (3,)) [N·m, N·m, N] (``inverse_terms``)."""
    q, qd, qdd = _states("q", q), _states("qd", qd), _states("qdd", qdd)
    shape = np.broadcast_shapes(q.shape, qd.shape, qdd.shape)[:-1]
    q2 = q[..., 1]
    with np.errstate(over="ignore", invalid="ignore"):  # callers check the result's finiteness
        tau = inverse_terms(
            np.cos(q2), np.sin(q2), q[..., 2], qd[..., 0], qd[..., 1], qd[..., 2],
            qdd[..., 0], qdd[..., 1], qdd[..., 2], *inverse_constants(*param_vector(params)),
        )  # fmt: skip
    return _stack(shape, tau)


def forward_dynamics(q: np.ndarray, qd: np.ndarray, tau: np.ndarray, params: Params) -> np.ndarray:
    """q̈ = M(q)⁻¹·(τ − c − G) by the closed-form symmetric 3×3 solve.

    Returns:
        q̈, shape (N, 3) (or (3,)) [rad/s², rad/s², m/s²].
    """
    q, qd, tau = _states("q", q), _states("qd", qd), _states("tau", tau)
    M11, M12, M13, M22, M23, M33, c1, c2, c3, G1, G2, G3 = _terms(q, qd, params)
    r1 = tau[..., 0] - c1 - G1
    r2 = tau[..., 1] - c2 - G2
    r3 = tau[..., 2] - c3 - G3
    A11 = M22 * M33 - M23 * M23
    A12 = M13 * M23 - M12 * M33
    A13 = M12 * M23 - M13 * M22
    A22 = M11 * M33 - M13 * M13
    A23 = M12 * M13 - M11 * M23
    A33 = M11 * M22 - M12 * M12
    det = M11 * A11 + M12 * A12 + M13 * A13
    return _stack(
        np.broadcast_shapes(q.shape, qd.shape, tau.shape)[:-1],
        (
            (A11 * r1 + A12 * r2 + A13 * r3) / det,
            (A12 * r1 + A22 * r2 + A23 * r3) / det,
            (A13 * r1 + A23 * r2 + A33 * r3) / det,
        ),
    )
