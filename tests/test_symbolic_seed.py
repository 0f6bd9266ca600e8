"""Each intermediate result of rrt_pin.dynamics.symbolic against the seed's printed formula.

Where the seed is right the derived result equals the formula as printed;
where it errs (docs/errata.md) the result equals the correction AND differs
from the printed text, so every erratum test can fail. Expected values are
typed here from the chapter, in plain symbols, independently of the package.
"""

import random

import pytest

sp = pytest.importorskip("sympy")

from sympy.physics.mechanics import Point, inertia  # noqa: E402

from rrt_pin.dynamics.symbolic import energy, forces, frames, kane, kinematics, lagrange  # noqa: E402
from rrt_pin.dynamics.symbolic.symbols import (  # noqa: E402
    F23,
    L1,
    L2,
    LB,
    T01,
    T12,
    I1x,
    I1y,
    I1z,
    I2x,
    I2y,
    I2z,
    I3x,
    I3y,
    I3z,
    g,
    m1,
    m2,
    m3,
    q,
    qd,
    t,
    to_plain,
)

q1, q2, q3 = sp.symbols("q1 q2 q3", real=True)
u1, u2, u3 = sp.symbols("qdot1 qdot2 qdot3", real=True)
a1, a2, a3 = sp.symbols("qddot1 qddot2 qddot3", real=True)
s1, c1, s2, c2 = sp.sin(q1), sp.cos(q1), sp.sin(q2), sp.cos(q2)
T01x, T12y, F23z = T01[0], T12[1], F23[2]
F0, F1, F2 = frames.frame0, frames.frame1, frames.frame2
ROD = {I1x: m1 * L1**2 / 3, I1y: m1 * L1**2 / 3, I1z: 0, I2x: m2 * L2**2 / 3}
ROD.update({I2y: m2 * L2**2 / 3, I2z: 0, LB: 2 * L1})


def is_zero(expr) -> bool:
    """Exactly zero: a numeric screen at random points, then sympy's simplify."""
    expr = sp.expand(to_plain(expr))
    if expr == 0:
        return True
    free = sorted(expr.free_symbols, key=str)
    rng = random.Random(3)
    for _ in range(3):
        value = complex(expr.evalf(30, subs={s: rng.uniform(0.3, 1.7) for s in free}))
        if abs(value) > 1e-20:
            return False
    return sp.simplify(expr) == 0


def comps(vector, frame):
    """Components of a sympy vector along the unit vectors of ``frame``, in plain symbols."""
    return [to_plain(vector.dot(e)) for e in (frame.x, frame.y, frame.z)]


def same(vector, frame, expected) -> bool:
    return all(is_zero(a - b) for a, b in zip(comps(vector, frame), expected, strict=True))


def frame_derivative(vector, frame):
    """⁽ⁿ⁾d/dt of ``vector`` (its components in ``frame`` differentiated)."""
    return vector.express(frame).diff(t, frame)


# ---- frames, eqs. (1)–(4) ------------------------------------------------------------


def test_eq1_eq2_R10_and_unit_vectors_of_frame1():
    assert sp.simplify(
        to_plain(frames.R10) - sp.Matrix([[1, 0, 0], [0, c1, s1], [0, -s1, c1]])
    ) == sp.zeros(3)
    assert same(frames.i1, F0, [1, 0, 0])
    assert same(frames.j1, F0, [0, c1, s1])
    assert same(frames.k1, F0, [0, -s1, c1])


def test_eq3_eq4_R21_and_unit_vectors_of_frame2():
    assert sp.simplify(
        to_plain(frames.R21) - sp.Matrix([[c2, 0, -s2], [0, 1, 0], [s2, 0, c2]])
    ) == sp.zeros(3)
    assert same(frames.i2, F1, [c2, 0, -s2])
    assert same(frames.i2, F0, [c2, s1 * s2, -c1 * s2])
    assert same(frames.j2, F0, [0, c1, s1])
    assert same(frames.k2, F1, [s2, 0, c2])
    assert same(frames.k2, F0, [s2, -c2 * s1, c1 * c2])
    # the line above eq. (6): ı0 = ı1 = c2 ı2 + s2 k2
    assert same(frames.i0, F2, [c2, 0, s2])


# ---- angular velocities and accelerations, eqs. (5)–(8) ----------------------------


def test_eq5_eq6_angular_velocities():
    assert same(kinematics.omega10, F1, [u1, 0, 0])
    assert same(kinematics.omega20, F2, [u1 * c2, u2, u1 * s2])
    # and sympy's own angular velocity of the oriented frames
    assert same(kinematics.omega20 - F2.ang_vel_in(F0), F0, [0, 0, 0])


def test_eq7_eq8_angular_accelerations():
    assert same(kinematics.alpha10, F1, [a1, 0, 0])
    expected = [a1 * c2 - u1 * u2 * s2, a2, a1 * s2 + u1 * u2 * c2]
    assert same(kinematics.alpha20, F2, expected)
    assert same(F2.ang_acc_in(F0), F2, expected)


# ---- positions and velocities, eqs. (9)–(11) ----------------------------------------


def test_position_vectors():
    assert same(kinematics.rC1, F1, [0, 0, L1])
    assert same(kinematics.rC2, F2, [-LB * s2, 0, LB * c2 + L2])
    assert same(kinematics.rC3, F2, [-LB * s2, 0, LB * c2 + L2 + q3])


def test_eq9_vC1():
    assert same(kinematics.vC1, F1, [0, -u1 * L1, 0])
    assert same(kinematics.rC1.dt(F0), F1, [0, -u1 * L1, 0])


def test_eq10_vC2_final():
    expected = [L2 * u2, -(LB + L2 * c2) * u1, 0]
    assert same(kinematics.vC2, F2, expected)
    assert same(kinematics.rC2.dt(F0), F2, expected)  # sympy's own derivative in (0)


def test_eq10_intermediate_erratum():
    """Eq. (10): ⁽²⁾d/dt rC2 is −LB c2 q̇2 ı2 − LB s2 q̇2 k2, not −LB c1 q̇2 ı2 − LB c2 q̇2 k2."""
    derivative = frame_derivative(kinematics.rC2, F2)
    assert same(derivative, F2, [-LB * c2 * u2, 0, -LB * s2 * u2])
    assert not same(derivative, F2, [-LB * c1 * u2, 0, -LB * c2 * u2])  # as printed


def test_eq11_intermediate_erratum():
    """Eq. (11): ⁽²⁾d/dt rC3 is −LB c2 q̇2 ı2 + (−LB s2 q̇2 + q̇3) k2, not −(LB c2 q̇2 + q̇3) k2."""
    derivative = frame_derivative(kinematics.rC3, F2)
    assert same(derivative, F2, [-LB * c2 * u2, 0, -LB * s2 * u2 + u3])
    assert not same(derivative, F2, [-LB * c2 * u2, 0, -(LB * c2 * u2 + u3)])  # as printed


def _det(row2, row3):
    """The seed's determinant |ı2 ȷ2 k2; row2; row3| as components."""
    return list(sp.Matrix([[0, 0, 0], row2, row3]).cofactor_matrix().row(0))


def test_eq11_determinant_erratum():
    """Eq. (11): the determinant's last entry is LB c2 + L2 + q3, not LB c2 + L2 + q2."""
    cross = kinematics.omega20.cross(kinematics.rC3)
    w = [u1 * c2, u2, u1 * s2]
    assert same(cross, F2, _det(w, [-LB * s2, 0, LB * c2 + L2 + q3]))
    assert not same(cross, F2, _det(w, [-LB * s2, 0, LB * c2 + L2 + q2]))  # as printed


def test_eq11_vC3_final_erratum():
    """Eq. (11): vC3 = (L2 + q3) q̇2 ı2 − (LB + L2 c2 + c2 q3) q̇1 ȷ2 + q̇3 k2 (printed c2 q2)."""
    expected = [(L2 + q3) * u2, -(LB + L2 * c2 + c2 * q3) * u1, u3]
    assert same(kinematics.vC3, F2, expected)
    assert same(kinematics.rC3.dt(F0), F2, expected)
    assert not same(kinematics.vC3, F2, [(L2 + q3) * u2, -(LB + L2 * c2 + c2 * q2) * u1, u3])


def test_vC32():
    # vC32 = vC2 + ω20 × q3 k2 (before eq. 15): C3's velocity without the sliding q̇3 k2
    assert same(kinematics.vC32, F2, [(L2 + q3) * u2, -(LB + L2 * c2 + c2 * q3) * u1, 0])


# ---- accelerations, eqs. (12)–(14) ---------------------------------------------------


def test_eq12_aC1_and_intermediate_erratum():
    """Eq. (12): ⁽¹⁾d/dt vC1 = −L1 q̈1 ȷ1 (printed without ȷ1); aC1 = −L1 q̈1 ȷ1 − L1 q̇1² k1."""
    derivative = frame_derivative(kinematics.vC1, F1)
    assert same(derivative, F1, [0, -L1 * a1, 0])
    assert not same(derivative, F1, [-L1 * a1, 0, 0])
    assert not same(derivative, F1, [0, 0, -L1 * a1])
    cross = kinematics.omega10.cross(kinematics.vC1)
    assert same(cross, F1, _det([u1, 0, 0], [0, -L1 * u1, 0]))
    assert same(kinematics.aC1, F1, [0, -L1 * a1, -L1 * u1**2])


def _points():
    """Mass centres built with sympy's own Point kinematics (independent of eqs. 9–14)."""
    A = Point("A")
    A.set_vel(F0, 0)
    C1 = A.locatenew("C1", L1 * frames.k1)
    C1.v2pt_theory(A, F0, F1)
    B = A.locatenew("B", LB * frames.k1)
    B.v2pt_theory(A, F0, F1)
    C2 = B.locatenew("C2", L2 * frames.k2)
    C2.v2pt_theory(B, F0, F2)
    C3 = C2.locatenew("C3", q[2] * frames.k2)
    C3.set_vel(F2, qd[2] * frames.k2)
    C3.v1pt_theory(C2, F0, F2)
    C32 = C2.locatenew("C32", q[2] * frames.k2)
    C32.v2pt_theory(C2, F0, F2)
    return C1, C2, C3, C32


@pytest.mark.parametrize("name", ["vC1", "vC2", "vC3", "vC32", "aC1", "aC2", "aC3"])
def test_eqs9_to_14_agree_with_sympys_point_kinematics(name):
    C1, C2, C3, C32 = _points()
    points = {"C1": C1, "C2": C2, "C3": C3, "C32": C32}
    point = points[name[1:]]
    reference = point.vel(F0) if name[0] == "v" else point.vel(F0).dt(F0)
    assert same(getattr(kinematics, name) - reference, F0, [0, 0, 0])


# ---- generalized active forces, eq. (15) ---------------------------------------------


def test_gravity_forces_G2_G3():
    assert same(forces.G1, F1, [-m1 * g, 0, 0])
    assert same(forces.G2, F2, [-m2 * g * c2, 0, -m2 * g * s2])
    assert same(forces.G3, F2, [-m3 * g * c2, 0, -m3 * g * s2])


def test_eq15_Q():
    Q1, Q2, Q3 = (to_plain(e) for e in forces.Q)
    assert is_zero(Q1 - T01x)
    assert is_zero(Q2 - (T12y - g * m2 * L2 * c2 - g * m3 * c2 * (L2 + q3)))
    assert is_zero(Q3 - (F23z - g * m3 * s2))


def test_eq15_reactions_drop_out():
    reactions = {T01[1], T01[2], T12[0], T12[2], F23[0], F23[1]}
    for e in forces.Q:
        assert not (sp.expand(e).free_symbols & reactions)
    # but each contribution (Qr)j alone does carry them: the cancellation is real
    assert sp.expand(forces.Q_link1[0]).free_symbols >= {T12[0], T12[2]}
    assert sp.expand(forces.Q_link2[0]).free_symbols >= {T12[0], T12[2]}


def test_eq15_gravity_part_is_minus_grad_of_potential():
    # V = Σ mj g (ı0 · rCj): heights along the vertical ı0, independent of the remark's sums.
    V = g * sum(
        m * r.dot(frames.i0)
        for m, r in ((m1, kinematics.rC1), (m2, kinematics.rC2), (m3, kinematics.rC3))
    )
    zero_efforts = {s: 0 for s in (*T01, *T12, *F23)}
    for r in range(3):
        assert is_zero(forces.Q[r].subs(zero_efforts) + V.diff(q[r]))


def test_a_couple_between_2_and_3_contributes_nothing():
    # The seed lets 2 act on 3 by a force only; the couple a slider joint also
    # transmits does no work (ω30 = ω20), so leaving it out changes no Qr.
    T23 = sp.symbols("T23x T23y T23z")
    T = T23[0] * frames.i2 + T23[1] * frames.j2 + T23[2] * frames.k2
    for r in (1, 2, 3):
        on3 = forces.partial(kinematics.omega30, r).dot(T)
        on2 = forces.partial(kinematics.omega20, r).dot(-T)
        assert sp.expand(on3 + on2) == 0


# ---- kinetic energies ----------------------------------------------------------------


def test_T1_erratum_missing_square():
    """T1 = ½ m1 L1² q̇1² + ⅙ m1 L1² q̇1² = ⅔ m1 L1² q̇1² (printed ⅔ m1 L1 q̇1²)."""
    T1 = to_plain(energy.T1).subs(ROD)
    assert is_zero(to_plain(m1 * kinematics.vC1.dot(kinematics.vC1) / 2) - m1 * L1**2 * u1**2 / 2)
    assert is_zero(T1 - sp.Rational(2, 3) * m1 * L1**2 * u1**2)
    assert not is_zero(T1 - sp.Rational(2, 3) * m1 * L1 * u1**2)  # as printed


def test_T2_as_printed_for_the_seeds_rods():
    T2 = to_plain(energy.T2).subs(ROD)
    printed = (
        m2
        / 3
        * (
            (6 * L1**2 + L2**2 + 6 * L1 * L2 * c2 + L2**2 * sp.cos(2 * q2)) * u1**2
            + 2 * L2**2 * u2**2
        )
    )
    assert is_zero(T2 - printed)


def test_T3_as_printed():
    T3 = to_plain(energy.T3).subs(LB, 2 * L1)
    printed = (
        I3x * c2**2 * u1**2
        + I3z * s2**2 * u1**2
        + I3y * u2**2
        + m3 * ((2 * L1 + L2 * c2 + c2 * q3) ** 2 * u1**2 + (L2 + q3) ** 2 * u2**2 + u3**2)
    ) / 2
    assert is_zero(T3 - printed)


def test_rod_inertias_are_the_seeds():
    # Fig. 2: m (2L)²/12 = m L²/3 for both rods; Params uses the same defaults.
    from rrt_pin.robot.params import Params

    p = Params()
    assert p.I1x == pytest.approx(p.m1 * (2 * p.L1) ** 2 / 12, rel=1e-15)
    assert p.I2y == pytest.approx(p.m2 * (2 * p.L2) ** 2 / 12, rel=1e-15)


# ---- Kane, eqs. (16)–(29) --------------------------------------------------------------


def test_eq17_erratum_generalized_inertia_forces_need_minus_m():
    """Eq. (17): K*r = Σ ∂vPj/∂ur · Fin j = −Σ mj ∂vPj/∂ur · aPj (printed without −mj).

    Checked on the three mass centres taken as particles: their K*r must be
    minus the Lagrange left-hand side of their kinetic energy ½ Σ mj vj².
    """
    particles = (
        (m1, kinematics.vC1, kinematics.aC1),
        (m2, kinematics.vC2, kinematics.aC2),
        (m3, kinematics.vC3, kinematics.aC3),
    )
    T = sum(m * v.dot(v) / 2 for m, v, _ in particles)
    for r in range(3):
        lagrange_lhs = T.diff(qd[r]).diff(t) - T.diff(q[r])
        correct = sum(forces.partial(v, r + 1).dot(-m * a) for m, v, a in particles)
        printed = sum(forces.partial(v, r + 1).dot(a) for _, v, a in particles)
        assert is_zero(correct + lagrange_lhs)
        assert not is_zero(printed + lagrange_lhs)


def test_eq22_eq23_dyadic_products():
    w = sp.symbols("wx wy wz")
    al = sp.symbols("ax ay az")
    Ix, Iy, Iz = sp.symbols("Ix Iy Iz")
    I = inertia(F2, Ix, Iy, Iz)  # noqa: E741
    omega = w[0] * F2.x + w[1] * F2.y + w[2] * F2.z
    alpha = al[0] * F2.x + al[1] * F2.y + al[2] * F2.z
    assert same(alpha.dot(I), F2, [al[0] * Ix, al[1] * Iy, al[2] * Iz])
    assert same(I.dot(alpha), F2, [al[0] * Ix, al[1] * Iy, al[2] * Iz])
    eq23 = [-w[1] * w[2] * (Iy - Iz), -w[2] * w[0] * (Iz - Ix), -w[0] * w[1] * (Ix - Iy)]
    assert same(omega.cross(I.dot(omega)), F2, eq23)


def test_eq24_Min1():
    assert same(kane.Min1, F1, [-I1x * a1, 0, 0])


def test_eq25_erratum_sign_of_Min3():
    """Eq. (25): Min3 = −α20·Ī3 − ω20 × (Ī3·ω20) (printed +α20·Ī3)."""
    I3 = energy.I3
    w, al = kinematics.omega20, kinematics.alpha20
    correct = -al.dot(I3) - w.cross(I3.dot(w))
    printed = al.dot(I3) - w.cross(I3.dot(w))
    assert same(kane.Min3 - correct, F2, [0, 0, 0])
    assert not same(kane.Min3 - printed, F2, [0, 0, 0])
    # The printed sign breaks Kane = Lagrange: K*r + Qr with it is not −(Lagrange residual).
    r = 1
    k_printed = kane.generalized_inertia_forces()[r] + sp.expand(
        forces.partial(kinematics.omega30, r + 1).dot(printed - kane.Min3)
    )
    assert not is_zero(k_printed + lagrange.lagrange_lhs()[r])
    assert is_zero(kane.generalized_inertia_forces()[r] + lagrange.lagrange_lhs()[r])


def test_eq28_generalized_inertia_forces_are_minus_lagrange_lhs():
    # K*r (eq. 28, inertia forces and moments) = −(d/dt ∂T/∂q̇r − ∂T/∂qr), r = 1, 2, 3.
    for k, lhs in zip(kane.generalized_inertia_forces(), lagrange.lagrange_lhs(), strict=True):
        assert is_zero(k + lhs)


def test_eq29_kane_equals_lagrange():
    for k, lag in zip(kane.kane_equations(), lagrange.lagrange_equations(), strict=True):
        assert is_zero(k + lag)


def test_every_test_named_in_the_errata_exists():
    import re
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    names = set(
        re.findall(r"`(?:tests/[\w.]+::)?(test_\w+)`", (root / "docs" / "errata.md").read_text())
    )
    defined = set()
    for path in (root / "tests").glob("test_symbolic_*.py"):
        defined |= set(re.findall(r"^def (test_\w+)", path.read_text(), re.M))
    assert len(names) >= 20
    assert names <= defined, sorted(names - defined)
