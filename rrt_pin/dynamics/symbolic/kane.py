"""Kane's dynamical equations K*r + Qr = 0 from inertia forces and moments, eqs. (16)–(29).

For each link j the inertia force is Fin j = −mj aCj (eqs. 19, 26) and the
inertia moment Min j = −αj0·Īj − ωj0 × (Īj·ωj0) (eq. 20); the generalized
inertia force is K*r = Σj ∂vCj/∂q̇r · Fin j + ∂ωj0/∂q̇r · Min j (eqs. 27, 28),
with generalized speeds ur = q̇r. Units: Fin [N], Min [N·m], K*1, K*2 [N·m],
K*3 [N].
"""

from __future__ import annotations

from functools import cache

import sympy as sp
from sympy.physics.mechanics import Dyadic, Vector

from rrt_pin.dynamics.symbolic.energy import I1, I2, I3
from rrt_pin.dynamics.symbolic.forces import Q, partial
from rrt_pin.dynamics.symbolic.kinematics import (
    aC1,
    aC2,
    aC3,
    alpha10,
    alpha20,
    alpha30,
    omega10,
    omega20,
    omega30,
    vC1,
    vC2,
    vC3,
)
from rrt_pin.dynamics.symbolic.symbols import m1, m2, m3

__all__ = [
    "Fin1",
    "Fin2",
    "Fin3",
    "Min1",
    "Min2",
    "Min3",
    "generalized_inertia_forces",
    "inertia_moment",
    "kane_equations",
]


def inertia_moment(alpha: Vector, omega: Vector, I: Dyadic) -> Vector:  # noqa: E741
    """Eq. (20): Min = −α·Ī − ω × (Ī·ω) [N·m]."""
    return -alpha.dot(I) - omega.cross(I.dot(omega))


#: Eq. (26): inertia forces of links 1, 2, 3 [N].
Fin1 = -m1 * aC1
Fin2 = -m2 * aC2
Fin3 = -m3 * aC3
#: Eqs. (24), (25): inertia moments of links 1, 2, 3 [N·m].
Min1 = inertia_moment(alpha10, omega10, I1)
Min2 = inertia_moment(alpha20, omega20, I2)
Min3 = inertia_moment(alpha30, omega30, I3)

_LINKS = ((vC1, Fin1, omega10, Min1), (vC2, Fin2, omega20, Min2), (vC3, Fin3, omega30, Min3))


@cache
def generalized_inertia_forces() -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """Eq. (28): K*1, K*2 [N·m] and K*3 [N], in q(t) and its derivatives."""
    return tuple(
        sp.expand(
            sum(
                (partial(v, r).dot(F) + partial(w, r).dot(M) for v, F, w, M in _LINKS),
                sp.S.Zero,
            )
        )
        for r in (1, 2, 3)
    )


@cache
def kane_equations() -> tuple[sp.Expr, sp.Expr, sp.Expr]:
    """Eq. (29): the left-hand sides K*r + Qr, each equal to zero."""
    return tuple(k + qr for k, qr in zip(generalized_inertia_forces(), Q, strict=True))
