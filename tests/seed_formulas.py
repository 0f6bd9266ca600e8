"""The seed's printed formulas, typed in from the chapter (corrected where it errs).

Independent of rrt_pin: used to check the generated URDF and Pinocchio's model.
Frame (0) components are (ı0, ȷ0, k0); ı0 is the vertical.
"""

from __future__ import annotations

import numpy as np


def unit_vectors(q1: float, q2: float):
    """ı1, ȷ1, k1 (eq. 1) and ı2, ȷ2, k2 (eq. 3) in frame (0) components."""
    s1, c1, s2, c2 = np.sin(q1), np.cos(q1), np.sin(q2), np.cos(q2)
    i1 = np.array([1.0, 0.0, 0.0])
    j1 = np.array([0.0, c1, s1])
    k1 = np.array([0.0, -s1, c1])
    i2 = np.array([c2, s1 * s2, -c1 * s2])
    j2 = j1
    k2 = np.array([s2, -c2 * s1, c1 * c2])
    return i1, j1, k1, i2, j2, k2


def mass_centres(p, q):
    """rC1, rC2, rC3 in frame (0) (the position vectors above eqs. 9–11)."""
    _, _, k1, _, _, k2 = unit_vectors(q[0], q[1])
    rC1 = p.L1 * k1
    rC2 = p.LB * k1 + p.L2 * k2
    rC3 = rC2 + q[2] * k2
    return rC1, rC2, rC3


def seed_to_world(v):
    """The mount: ı0 → world z, ȷ0 → world x, k0 → world y."""
    return np.array([v[1], v[2], v[0]])


def kinetic_energy(p, q, qd):
    """T = T1 + T2 + T3 as printed, for the seed's uniform rods.

    T1: the seed prints 2/3·m1·L1·q̇1², missing the square on L1 (erratum);
    ½·m1·(L1·q̇1)² + ½·(m1·L1²/3)·q̇1² = 2/3·m1·L1²·q̇1².
    """
    L1, L2, q3 = p.L1, p.L2, q[2]
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    T1 = 2.0 / 3.0 * p.m1 * L1**2 * qd[0] ** 2
    T2 = (
        p.m2
        / 3.0
        * (
            (6 * L1**2 + L2**2 + 6 * L1 * L2 * c2 + L2**2 * np.cos(2 * q[1])) * qd[0] ** 2
            + 2 * L2**2 * qd[1] ** 2
        )
    )
    T3 = 0.5 * (
        p.I3x * c2**2 * qd[0] ** 2
        + p.I3z * s2**2 * qd[0] ** 2
        + p.I3y * qd[1] ** 2
        + p.m3
        * (
            (2 * L1 + L2 * c2 + c2 * q3) ** 2 * qd[0] ** 2
            + (L2 + q3) ** 2 * qd[1] ** 2
            + qd[2] ** 2
        )
    )
    return T1 + T2 + T3


def holding_efforts(p, q):
    """Efforts that hold the arm still: minus the gravity parts of Q1, Q2, Q3 (eq. 15)."""
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    return np.array([0.0, p.g * c2 * (p.m2 * p.L2 + p.m3 * (p.L2 + q[2])), p.g * p.m3 * s2])
