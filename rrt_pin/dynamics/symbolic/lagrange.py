"""Lagrange's equations d/dt(∂T/∂q̇r) − ∂T/∂qr = Qr from the kinetic energy T."""

from __future__ import annotations

from functools import cache

import sympy as sp

from rrt_pin.dynamics.symbolic.energy import T
from rrt_pin.dynamics.symbolic.forces import Q
from rrt_pin.dynamics.symbolic.symbols import q, qd, t

__all__ = ["lagrange_equations", "lagrange_lhs"]


@cache
def lagrange_lhs() -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """d/dt(∂T/∂q̇r) − ∂T/∂qr, r = 1, 2, 3 [N·m, N·m, N]."""
    return tuple(
        sp.expand(T.diff(qd_r).diff(t) - T.diff(q_r)) for q_r, qd_r in zip(q, qd, strict=True)
    )


@cache
def lagrange_equations() -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """Lagrange's equations as left-hand sides equal to zero: (d/dt ∂T/∂q̇r − ∂T/∂qr) − Qr."""
    return tuple(lhs - qr for lhs, qr in zip(lagrange_lhs(), Q, strict=True))
