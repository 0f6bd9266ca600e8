"""Kinetic energies T1, T2, T3 and T = T1 + T2 + T3 in (0) [J].

Ti = ½ mi vCi·vCi + ½ ωi0·(Īi·ωi0), with the central inertia dyadics Ī1
diagonal in frame (1) and Ī2, Ī3 diagonal in frame (2) [kg·m²].
"""

from __future__ import annotations

import sympy as sp
from sympy.physics.mechanics import inertia

from rrt_pin.dynamics.symbolic.frames import frame1, frame2
from rrt_pin.dynamics.symbolic.kinematics import omega10, omega20, omega30, vC1, vC2, vC3
from rrt_pin.dynamics.symbolic.symbols import (
    I1x,
    I1y,
    I1z,
    I2x,
    I2y,
    I2z,
    I3x,
    I3y,
    I3z,
    m1,
    m2,
    m3,
)

__all__ = ["I1", "I2", "I3", "T", "T1", "T2", "T3", "kinetic_energy"]

#: Central inertia dyadic of link 1 [kg·m²].
I1 = inertia(frame1, I1x, I1y, I1z)
#: Central inertia dyadic of link 2 [kg·m²].
I2 = inertia(frame2, I2x, I2y, I2z)
#: Central inertia dyadic of the slider, link 3 [kg·m²].
I3 = inertia(frame2, I3x, I3y, I3z)


def kinetic_energy(m, vC, omega, I) -> sp.Expr:  # noqa: E741
    """½ m vC·vC + ½ ω·(Ī·ω) [J] of a rigid body."""
    return sp.expand(m * vC.dot(vC) / 2 + omega.dot(I.dot(omega)) / 2)


#: Kinetic energy of link 1 [J].
T1 = kinetic_energy(m1, vC1, omega10, I1)
#: Kinetic energy of link 2 [J].
T2 = kinetic_energy(m2, vC2, omega20, I2)
#: Kinetic energy of link 3 [J].
T3 = kinetic_energy(m3, vC3, omega30, I3)
#: Total kinetic energy [J].
T = T1 + T2 + T3
