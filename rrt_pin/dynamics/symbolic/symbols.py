"""The symbols of the derivation, with the chapter's names.

Generalized coordinates q1 [rad], q2 [rad], q3 [m] are functions of time t [s]
(``sympy.physics.mechanics.dynamicsymbols``); their derivatives are the
generalized speeds of Kane's method (u_r = q̇_r). Parameters are positive real
symbols in the order of :data:`PARAM_NAMES` (the kernel's ``PARAM_ORDER``).
"""

from __future__ import annotations

import sympy as sp
from sympy.physics.mechanics import dynamicsymbols

from rrt_pin.robot.params import PLANT_FIELDS

__all__ = [
    "EFFORTS",
    "F23",
    "LATEX_NAMES",
    "LB",
    "PARAM_NAMES",
    "PARAMS",
    "T01",
    "T12",
    "I1x",
    "I1y",
    "I1z",
    "I2x",
    "I2y",
    "I2z",
    "I3x",
    "I3y",
    "I3z",
    "L1",
    "L2",
    "g",
    "m1",
    "m2",
    "m3",
    "q",
    "q1",
    "q2",
    "q3",
    "qd",
    "qdd",
    "q_plain",
    "qd_plain",
    "qdd_plain",
    "t",
    "to_plain",
]

#: Time [s] (the symbol ``dynamicsymbols`` differentiate by).
t = dynamicsymbols._t
#: Generalized coordinates q1 [rad], q2 [rad], q3 [m] as functions of t.
q1, q2, q3 = dynamicsymbols("q1 q2 q3", real=True)
q = (q1, q2, q3)
#: Generalized speeds q̇1, q̇2 [rad/s], q̇3 [m/s].
qd = tuple(qi.diff(t) for qi in q)
#: Generalized accelerations q̈1, q̈2 [rad/s²], q̈3 [m/s²].
qdd = tuple(qi.diff(t, 2) for qi in q)

#: Parameter names, in the kernel's order: :data:`rrt_pin.robot.params.PLANT_FIELDS`.
PARAM_NAMES = PLANT_FIELDS
L1, L2, m1, m2, m3 = sp.symbols("L1 L2 m1 m2 m3", positive=True)
I1x, I1y, I1z, I2x, I2y, I2z, I3x, I3y, I3z = sp.symbols(
    "I1x I1y I1z I2x I2y I2z I3x I3y I3z", nonnegative=True
)
g = sp.Symbol("g", positive=True)
#: The parameter symbols, in the order of :data:`PARAM_NAMES`.
PARAMS = (L1, L2, m1, m2, m3, I1x, I1y, I1z, I2x, I2y, I2z, I3x, I3y, I3z, g)
#: Distance A→B [m]; the chapter's LB = 2·L1, kept as a symbol in the kinematics.
LB = sp.Symbol("LB", positive=True)

#: Components of the torque T01 [N·m] from 0 on 1, in frame (1).
T01 = sp.symbols("T01x T01y T01z", real=True)
#: Components of the torque T12 [N·m] from 1 on 2, in frame (2).
T12 = sp.symbols("T12x T12y T12z", real=True)
#: Components of the force F23 [N] from 2 on 3, in frame (2).
F23 = sp.symbols("F23x F23y F23z", real=True)
#: The three driving efforts that remain in the equations: T01x, T12y [N·m], F23z [N].
EFFORTS = (T01[0], T12[1], F23[2])

#: Plain symbols standing for q1, q2, q3 in the equations of motion.
q_plain = sp.symbols("q1 q2 q3", real=True)
#: Plain symbols standing for q̇1, q̇2, q̇3 (print as q̇₁…).
qd_plain = sp.symbols("qdot1 qdot2 qdot3", real=True)
#: Plain symbols standing for q̈1, q̈2, q̈3 (print as q̈₁…).
qdd_plain = sp.symbols("qddot1 qddot2 qddot3", real=True)

_TO_PLAIN = {
    **dict(zip(qdd, qdd_plain, strict=True)),
    **dict(zip(qd, qd_plain, strict=True)),
    **dict(zip(q, q_plain, strict=True)),
}


def to_plain(expr):
    """``expr`` with q(t), q̇(t), q̈(t) replaced by plain symbols (second derivatives first)."""
    from sympy.physics.mechanics import msubs

    return msubs(expr, _TO_PLAIN)


#: LaTeX for the symbols whose names sympy would not typeset well (I_{1x}, T_{01x}, …).
LATEX_NAMES = {
    s: f"{s.name[0]}_{{{s.name[1:]}}}"
    for s in (LB, I1x, I1y, I1z, I2x, I2y, I2z, I3x, I3y, I3z, *T01, *T12, *F23)
}
