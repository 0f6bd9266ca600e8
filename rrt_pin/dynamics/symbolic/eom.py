"""One result type for both derivations: M(q)·q̈ = f(q, q̇, T01x, T12y, F23z).

:func:`equations_of_motion` builds the equations of motion of the RRT arm by
Kane's method (eqs. 16–29) or by Lagrange's equations, in plain symbols
q1, q2 [rad], q3 [m], q̇ (``qdot1``…) and q̈ (``qddot1``…), with the chapter's
LB = 2·L1 substituted. Derivations are cached: each is paid for once per
process.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache, lru_cache

import sympy as sp

from rrt_pin.core.errors import ParameterError
from rrt_pin.dynamics.symbolic.simplify import readable, trig_normal
from rrt_pin.dynamics.symbolic.symbols import (
    EFFORTS,
    L1,
    LB,
    PARAM_NAMES,
    PARAMS,
    g,
    q_plain,
    qd_plain,
    qdd_plain,
    to_plain,
)
from rrt_pin.robot.params import Params

__all__ = ["METHODS", "EquationsOfMotion", "equations_of_motion"]

#: The two derivations.
METHODS = ("kane", "lagrange")


@dataclass(frozen=True)
class EquationsOfMotion:
    """The equations of motion M(q)·q̈ = f(q, q̇, τ) of the RRT arm.

    Row r is the equation of q_r: rows 1 and 2 in N·m, row 3 in N.

    Attributes:
        method: ``"kane"`` or ``"lagrange"``.
        mass_matrix: M(q), 3×3, symmetric [kg·m², kg·m, kg].
        forcing: f(q, q̇, T01x, T12y, F23z), 3×1: the efforts minus the
            velocity-dependent and gravity terms.
        q: the symbols q1, q2 [rad], q3 [m].
        qd: the symbols q̇1, q̇2 [rad/s], q̇3 [m/s].
        qdd: the symbols q̈1, q̈2 [rad/s²], q̈3 [m/s²].
        efforts: the symbols T01x, T12y [N·m] and F23z [N].
        parameters: the parameter symbols still free (all of them, in the
            kernel's order, unless numbers were substituted).
        params: the numbers substituted, or None.
    """

    method: str
    mass_matrix: sp.ImmutableMatrix
    forcing: sp.ImmutableMatrix
    q: tuple[sp.Symbol, ...]
    qd: tuple[sp.Symbol, ...]
    qdd: tuple[sp.Symbol, ...]
    efforts: tuple[sp.Symbol, ...]
    parameters: tuple[sp.Symbol, ...]
    params: Params | None = None

    @property
    def bias(self) -> sp.ImmutableMatrix:
        """c(q, q̇) + G(q) = −f(q, q̇, 0): velocity and gravity terms [N·m, N·m, N]."""
        return sp.ImmutableMatrix(
            [sp.expand(-e) for e in self.forcing.subs({u: 0 for u in self.efforts})]
        )

    @property
    def gravity(self) -> sp.ImmutableMatrix:
        """G(q): the gravity terms, M·q̈ + c + G = τ [N·m, N·m, N]."""
        return sp.ImmutableMatrix(self.bias.subs({u: 0 for u in self.qd}))

    @property
    def velocity_terms(self) -> sp.ImmutableMatrix:
        """c(q, q̇): the Coriolis and centrifugal terms [N·m, N·m, N]."""
        return sp.ImmutableMatrix(
            [sp.expand(b - G) for b, G in zip(self.bias, self.gravity, strict=True)]
        )

    @property
    def states(self) -> tuple[sp.Symbol, ...]:
        """Q followed by q̇."""
        return (*self.q, *self.qd)

    def residual(self) -> sp.ImmutableMatrix:
        """M·q̈ − f: zero along every motion of the arm."""
        return sp.ImmutableMatrix(self.mass_matrix * sp.Matrix(self.qdd) - self.forcing)

    def equations(self, collect: bool = True) -> tuple[sp.Equality, ...]:
        """The three equations Σ_s M_rs q̈_s = f_r, r = 1, 2, 3.

        Args:
            collect: collect each side on q̈, products of q̇ and the efforts,
                then on sin and cos of q1, q2, with factored coefficients (for
                display; cached).
        """
        return _equations(self, collect)


@lru_cache(maxsize=32)
def _equations(eom: EquationsOfMotion, collect: bool) -> tuple[sp.Equality, ...]:
    keys = _display_keys(eom)
    angles = eom.q[:2]
    out = []
    for r in range(3):
        lhs = sum((eom.mass_matrix[r, s] * eom.qdd[s] for s in range(3)), sp.S.Zero)
        rhs = eom.forcing[r]
        if collect:
            lhs = readable(lhs, list(eom.qdd), angles)
            rhs = readable(rhs, keys, angles)
        out.append(sp.Eq(lhs, rhs, evaluate=False))
    return tuple(out)


def _display_keys(eom: EquationsOfMotion) -> list[sp.Expr]:
    v = eom.qd
    return [*(v[i] * v[j] for i in range(3) for j in range(i, 3)), *eom.efforts, g]


def _split(residuals: tuple[sp.Expr, ...]) -> tuple[sp.Matrix, sp.Matrix]:
    """M and f from residuals ρ = M·q̈ − f written in q(t) and its derivatives."""
    rho = sp.Matrix([to_plain(e).subs(LB, 2 * L1) for e in residuals])
    M = rho.jacobian(qdd_plain)
    f = -rho.subs({a: 0 for a in qdd_plain})
    angles = q_plain[:2]
    M = M.applyfunc(lambda e: trig_normal(e, angles))
    f = f.applyfunc(lambda e: trig_normal(e, angles))
    return M, f


@cache
def _derive(method: str) -> EquationsOfMotion:
    if method == "kane":
        from rrt_pin.dynamics.symbolic.kane import kane_equations

        # K*r + Qr = 0 and K*r = −(M·q̈)_r + …: the residual is −(K*r + Qr).
        M, f = _split(tuple(-e for e in kane_equations()))
    elif method == "lagrange":
        from rrt_pin.dynamics.symbolic.lagrange import lagrange_equations

        M, f = _split(lagrange_equations())
    else:
        raise ParameterError("method", method, f"must be one of {', '.join(METHODS)}")
    return EquationsOfMotion(
        method=method,
        mass_matrix=sp.ImmutableMatrix(M),
        forcing=sp.ImmutableMatrix(f),
        q=q_plain,
        qd=qd_plain,
        qdd=qdd_plain,
        efforts=EFFORTS,
        parameters=PARAMS,
    )


@lru_cache(maxsize=32)
def equations_of_motion(method: str = "kane", params: Params | None = None) -> EquationsOfMotion:
    """The RRT arm's equations of motion M(q)·q̈ = f(q, q̇, T01x, T12y, F23z).

    Args:
        method: ``"kane"`` (inertia forces and moments, eqs. 16–29) or
            ``"lagrange"`` (d/dt ∂T/∂q̇r − ∂T/∂qr = Qr).
        params: numbers to substitute for the parameters (SI units); the
            parameters stay symbols when None.

    Returns:
        The equations, cached per (method, params).

    Raises:
        ParameterError: ``method`` is not one of :data:`METHODS`.
    """
    if method not in METHODS:
        raise ParameterError("method", method, f"must be one of {', '.join(METHODS)}")
    eom = _derive(method)
    if params is None:
        return eom
    values = {s: sp.Float(getattr(params, n)) for s, n in zip(PARAMS, PARAM_NAMES, strict=True)}

    def num(m: sp.ImmutableMatrix) -> sp.ImmutableMatrix:
        return sp.ImmutableMatrix(m.xreplace(values).applyfunc(sp.expand))

    return EquationsOfMotion(
        method=method,
        mass_matrix=num(eom.mass_matrix),
        forcing=num(eom.forcing),
        q=eom.q,
        qd=eom.qd,
        qdd=eom.qdd,
        efforts=eom.efforts,
        parameters=(),
        params=params,
    )
