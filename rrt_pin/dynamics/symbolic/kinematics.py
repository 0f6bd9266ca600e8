"""Angular and linear velocities and accelerations, eqs. (5)–(14), as the chapter derives them.

Every velocity and acceleration comes from the transport theorem the chapter
uses, d/dt X = ⁽ⁿ⁾d/dt X + ωn0 × X, with X written in the components of the
frame (n) in which it was given (link 1: frame (1); links 2 and 3: frame (2)).
Units: ω [rad/s], α [rad/s²], r [m], v [m/s], a [m/s²].
"""

from __future__ import annotations

from sympy.physics.mechanics import Vector

from rrt_pin.dynamics.symbolic.frames import frame1, frame2, i1, j1, k1, k2
from rrt_pin.dynamics.symbolic.symbols import L1, L2, LB, q3, qd, t

__all__ = [
    "aC1",
    "aC2",
    "aC3",
    "alpha10",
    "alpha20",
    "alpha30",
    "omega10",
    "omega20",
    "omega21",
    "omega30",
    "rC1",
    "rC2",
    "rC3",
    "transport",
    "vC1",
    "vC2",
    "vC3",
    "vC32",
]


def transport(vector: Vector, frame, omega: Vector) -> Vector:
    """The time derivative in (0) of ``vector``: ⁽ⁿ⁾d/dt X + ω × X.

    Args:
        vector: X, expressed in the components of ``frame``.
        frame: the frame (n) whose components are differentiated.
        omega: the angular velocity of ``frame`` in (0) [rad/s].
    """
    return vector.express(frame).diff(t, frame) + omega.cross(vector)


#: Eq. (5): angular velocity of link 1 in (0) [rad/s].
omega10 = qd[0] * i1
#: Angular velocity of link 2 relative to link 1 [rad/s].
omega21 = qd[1] * j1
#: Eq. (6): angular velocity of link 2 in (0), in frame (2) components [rad/s].
omega20 = (omega10 + omega21).express(frame2)
#: Link 3 turns with link 2 [rad/s].
omega30 = omega20

#: Eq. (7): angular acceleration of link 1 in (0) [rad/s²].
alpha10 = transport(omega10, frame1, omega10)
#: Eq. (8): angular acceleration of link 2 in (0) [rad/s²] (ω20 × ω20 = 0).
alpha20 = transport(omega20, frame2, omega20)
#: Link 3 has the angular acceleration of link 2 [rad/s²].
alpha30 = alpha20

#: Position of C1 from A [m].
rC1 = L1 * k1
#: Position of C2 from A, in frame (2) [m]: −LB s2 ı2 + (LB c2 + L2) k2.
rC2 = (LB * k1 + L2 * k2).express(frame2)
#: Position of C3 from A, in frame (2) [m].
rC3 = rC2 + q3 * k2

#: Eq. (9): velocity of C1 in (0) [m/s].
vC1 = transport(rC1, frame1, omega10)
#: Eq. (10): velocity of C2 in (0) [m/s].
vC2 = transport(rC2, frame2, omega20)
#: Eq. (11): velocity of C3 in (0) [m/s].
vC3 = transport(rC3, frame2, omega20)
#: Velocity of the point C32 of link 2 that coincides with C3 [m/s].
vC32 = vC2 + omega20.cross(q3 * k2)

#: Eq. (12): acceleration of C1 in (0) [m/s²].
aC1 = transport(vC1, frame1, omega10)
#: Eq. (13): acceleration of C2 in (0) [m/s²].
aC2 = transport(vC2, frame2, omega20)
#: Eq. (14): acceleration of C3 in (0) [m/s²].
aC3 = transport(vC3, frame2, omega20)
