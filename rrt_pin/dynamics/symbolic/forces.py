"""Generalized active forces Q1, Q2, Q3 from the driving efforts and gravity, eq. (15).

Each link's contribution follows the chapter's remark: a set of forces
equivalent to a couple T and a force R applied at P contributes
∂ω/∂q̇r · T + ∂vP/∂q̇r · R to Qr. Link 1 carries T01 and the reaction −T12,
link 2 carries T12 and the reaction −F23 at C32, link 3 carries F23 at C3;
gravity G1, G2, G3 acts at the mass centres along −ı0 (ı0 is up).
Units: torques [N·m], forces [N], Q1 and Q2 [N·m], Q3 [N].
"""

from __future__ import annotations

import sympy as sp
from sympy.physics.mechanics import Vector

from rrt_pin.dynamics.symbolic.frames import frame0, frame2, i1, i2, j1, j2, k1, k2
from rrt_pin.dynamics.symbolic.kinematics import omega10, omega20, vC1, vC2, vC3, vC32
from rrt_pin.dynamics.symbolic.symbols import F23, T01, T12, g, m1, m2, m3, qd

__all__ = [
    "F23_vec",
    "G1",
    "G2",
    "G3",
    "Q",
    "Q_link1",
    "Q_link2",
    "Q_link3",
    "T01_vec",
    "T12_vec",
    "partial",
]

#: Torque from 0 on 1 at A [N·m]: T01x ı1 + T01y ȷ1 + T01z k1.
T01_vec = T01[0] * i1 + T01[1] * j1 + T01[2] * k1
#: Torque from 1 on 2 at B [N·m]: T12x ı2 + T12y ȷ2 + T12z k2.
T12_vec = T12[0] * i2 + T12[1] * j2 + T12[2] * k2
#: Force from 2 on 3 at C3 [N]: F23x ı2 + F23y ȷ2 + F23z k2.
F23_vec = F23[0] * i2 + F23[1] * j2 + F23[2] * k2

#: Gravity on link 1 [N]: −m1 g ı1.
G1 = -m1 * g * i1
#: Gravity on link 2 [N]: −m2 g ı1 = −m2 g (c2 ı2 + s2 k2).
G2 = (-m2 * g * i1).express(frame2)
#: Gravity on link 3 [N]: −m3 g ı1 = −m3 g (c2 ı2 + s2 k2).
G3 = (-m3 * g * i1).express(frame2)


def partial(vector: Vector, r: int) -> Vector:
    """The partial velocity ∂vector/∂q̇r (r = 1, 2, 3) in (0)."""
    return vector.diff(qd[r - 1], frame0, var_in_dcm=False)


def _link1(r: int) -> sp.Expr:
    return partial(omega10, r).dot(T01_vec - T12_vec) + partial(vC1, r).dot(G1)


def _link2(r: int) -> sp.Expr:
    return (
        partial(omega20, r).dot(T12_vec) + partial(vC2, r).dot(G2) + partial(vC32, r).dot(-F23_vec)
    )


def _link3(r: int) -> sp.Expr:
    return partial(vC3, r).dot(G3) + partial(vC3, r).dot(F23_vec)


#: (Qr)1, r = 1, 2, 3: contributions of the forces and torques on link 1.
Q_link1 = tuple(sp.expand(_link1(r)) for r in (1, 2, 3))
#: (Qr)2, r = 1, 2, 3: contributions of the forces and torques on link 2.
Q_link2 = tuple(sp.expand(_link2(r)) for r in (1, 2, 3))
#: (Qr)3, r = 1, 2, 3: contributions of the forces on link 3.
Q_link3 = tuple(sp.expand(_link3(r)) for r in (1, 2, 3))
#: Eq. (15): Qr = (Qr)1 + (Qr)2 + (Qr)3 [N·m, N·m, N].
Q = tuple(
    sp.factor_terms(sp.expand(a + b + c)) for a, b, c in zip(Q_link1, Q_link2, Q_link3, strict=True)
)
