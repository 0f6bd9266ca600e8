"""Joint reaction wrenches: each link's Newton–Euler balance, with kinematics typed from
the seed (frame (0) components, independent of Pinocchio), and the CSV columns."""

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.dynamics.wrenches import (
    RRT_WRENCH_COLUMNS,
    generic_wrench_columns,
    joint_wrenches,
    wrench_table,
)
from rrt_pin.robot.model import load_urdf_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from tests.support import DERIVED, TIGHT, mass_centres, random_states, robot_urdf, unit_vectors

I0 = np.array([1.0, 0.0, 0.0])  # the vertical ı0


def kinematics(p, q, qd, qdd):
    """ω, α of links 1 and 2 (= 3) and the accelerations of B, C1, C2, C3, in frame (0).

    From the seed: ω1 = q̇1 ı1 (5), ω2 = q̇1 ı1 + q̇2 ȷ1 (6), α1 = q̈1 ı1 (7),
    α2 = q̈1 ı1 + q̈2 ȷ1 + q̇2 ω1 × ȷ1 (8); a point P fixed in a link:
    aP = aO + α × OP + ω × (ω × OP); C3 slides along k2 (q3), adding q̈3 k2 + 2 q̇3 ω2 × k2.
    """
    i1, j1, k1, _, _, k2 = unit_vectors(q[0], q[1])
    w1, a1 = qd[0] * i1, qdd[0] * i1
    w2 = w1 + qd[1] * j1
    a2 = a1 + qdd[1] * j1 + qd[1] * np.cross(w1, j1)

    def rigid(alpha, omega, r):
        return np.cross(alpha, r) + np.cross(omega, np.cross(omega, r))

    aB = rigid(a1, w1, p.LB * k1)
    aC1 = rigid(a1, w1, p.L1 * k1)
    aC2 = aB + rigid(a2, w2, p.L2 * k2)
    aC3 = aC2 + rigid(a2, w2, q[2] * k2) + qdd[2] * k2 + 2 * qd[2] * np.cross(w2, k2)
    return w1, a1, w2, a2, aC1, aC2, aC3


def momentum_rate(moments, axes, omega, alpha):
    """dH/dt about the mass centre: Σ I_k (α·e_k) e_k + ω × H, H = Σ I_k (ω·e_k) e_k."""
    H = sum(m * (omega @ e) * e for m, e in zip(moments, axes, strict=True))
    return sum(m * (alpha @ e) * e for m, e in zip(moments, axes, strict=True)) + np.cross(omega, H)


def residuals(p, q, qd, qdd, force, moment):
    """Newton–Euler residuals of links 1, 2, 3 (force [N], moment [N·m]) at one state."""
    i1, j1, k1, i2, j2, k2 = unit_vectors(q[0], q[1])
    frame1, frame2 = np.array([i1, j1, k1]), np.array([i2, j2, k2])  # rows: unit vectors in (0)
    F01, T01 = force[0] @ frame1, moment[0] @ frame1  # components → frame (0) vectors
    F12, T12 = force[1] @ frame2, moment[1] @ frame2
    F23, M23 = force[2] @ frame2, moment[2] @ frame2
    w1, a1, w2, a2, aC1, aC2, aC3 = kinematics(p, q, qd, qdd)
    rC1, rC2, rC3 = mass_centres(p, q)
    rA, rB = np.zeros(3), p.LB * k1
    grav = -p.g * I0
    out = []
    # Link 3: F23 at C3 and M23 from link 2, gravity at C3.
    out.append(p.m3 * aC3 - (F23 + p.m3 * grav))
    out.append(momentum_rate((p.I3x, p.I3y, p.I3z), frame2, w2, a2) - M23)
    # Link 2: F12, T12 from link 1 at B; −F23, −M23 from link 3 at C3; gravity at C2.
    out.append(p.m2 * aC2 - (F12 - F23 + p.m2 * grav))
    out.append(
        momentum_rate((p.I2x, p.I2y, p.I2z), frame2, w2, a2)
        - (T12 + np.cross(rB - rC2, F12) - M23 - np.cross(rC3 - rC2, F23))
    )
    # Link 1: F01, T01 from link 0 at A; −F12, −T12 from link 2 at B; gravity at C1.
    out.append(p.m1 * aC1 - (F01 - F12 + p.m1 * grav))
    out.append(
        momentum_rate((p.I1x, p.I1y, p.I1z), frame1, w1, a1)
        - (T01 + np.cross(rA - rC1, F01) - T12 - np.cross(rB - rC1, F12))
    )
    return out


def check_balances(p, q, qd, qdd):
    w = joint_wrenches(chapter_arm(p), q, qd, qdd)
    scale_f = np.abs(w.force).max()
    scale_m = np.abs(w.moment).max()
    worst = 0.0
    for i in range(len(q)):
        res = residuals(p, q[i], qd[i], qdd[i], w.force[i], w.moment[i])
        for k, r in enumerate(res):
            worst = max(worst, np.abs(r).max() / (scale_f if k % 2 == 0 else scale_m))
    return worst


def test_kinematics_match_finite_differences_of_the_seeds_positions(seed_params):
    # The typed accelerations of C1, C2, C3 against the seed's mass-centre positions.
    p, h = seed_params, 1e-4
    times = np.linspace(1.0, 14.0, 7)
    traj = rest_to_rest(p.q0, p.qf, p.Tp, np.concatenate([times - h, times, times + h]))
    n = times.size
    for i in range(n):
        r = [np.array(mass_centres(p, traj.q[i + k * n])) for k in range(3)]
        fd = (r[0] - 2 * r[1] + r[2]) / h**2
        a = kinematics(p, traj.q[i + n], traj.qd[i + n], traj.qdd[i + n])[4:]
        np.testing.assert_allclose(a, fd, rtol=0, atol=1e-6)


def test_newton_euler_balance_along_the_seed_run(seed_params):
    p = seed_params
    traj = rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, 0.05))
    assert check_balances(p, traj.q, traj.qd, traj.qdd) <= DERIVED


@pytest.mark.parametrize(
    "params",
    [Params(), Params(m1=3.0, m3=70.0, L1=0.9, g=1.6, I1z=0.5, I2z=0.2, I3z=2.0)],
    ids=["seed", "other"],
)
def test_newton_euler_balance_at_fast_random_states(params, rng):
    q, qd, qdd = random_states(rng, 200)
    assert check_balances(params, q, qd, qdd) <= DERIVED


def test_balance_check_can_fail(seed_params, rng):
    # Wrenches of a heavier slider do not balance the seed's links.
    q, qd, qdd = random_states(rng, 5)
    w = joint_wrenches(chapter_arm(Params(m3=40.5)), q, qd, qdd)
    res = residuals(seed_params, q[0], qd[0], qdd[0], w.force[0], w.moment[0])
    assert np.abs(res[0]).max() > 1e-3


def test_axis_components_are_the_efforts(seed_model, seed_params):
    p = seed_params
    traj = rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, 0.01))
    w = joint_wrenches(chapter_arm(seed_params), traj.q, traj.qd, traj.qdd)
    tau = inverse_dynamics(chapter_arm(seed_params), traj.q, traj.qd, traj.qdd)
    np.testing.assert_allclose(w.moment[:, 0, 0], tau[:, 0], rtol=0, atol=TIGHT)  # T01x
    np.testing.assert_allclose(w.moment[:, 1, 1], tau[:, 1], rtol=TIGHT)  # T12y
    np.testing.assert_allclose(w.force[:, 2, 2], tau[:, 2], rtol=TIGHT)  # F23z


def test_holding_loads_at_rest(seed_model, seed_params):
    # At rest the base carries the whole weight along ı1 = ı0, and the slider its own.
    p = seed_params
    q = np.array(p.q0)
    w = joint_wrenches(chapter_arm(seed_params), q, np.zeros(3), np.zeros(3))
    total = (p.m1 + p.m2 + p.m3) * p.g
    np.testing.assert_allclose(w.force[0, 0], [total, 0, 0], rtol=TIGHT, atol=TIGHT * total)
    s2, c2 = np.sin(q[1]), np.cos(q[1])
    # Weight m3·g·ı0 = m3·g·(c2 ı2 + s2 k2), carried by F23 from link 2.
    np.testing.assert_allclose(
        w.force[0, 2], p.m3 * p.g * np.array([c2, 0, s2]), rtol=TIGHT, atol=1e-12
    )
    np.testing.assert_allclose(w.moment[0, 2], 0.0, atol=1e-12)


def test_rrt_table_columns(seed_model, seed_params, rng):
    q, qd, qdd = random_states(rng, 4)
    w = joint_wrenches(chapter_arm(seed_params), q, qd, qdd)
    names, table = wrench_table(w, rrt=True)
    assert names == RRT_WRENCH_COLUMNS and table.shape == (4, 15)
    assert len(set(names)) == 15 and not {"T01x", "T12y", "F23z"} & set(names)
    col = dict(zip(names, table.T, strict=True))
    np.testing.assert_array_equal(col["F01y"], w.force[:, 0, 1])
    np.testing.assert_array_equal(col["T01z"], w.moment[:, 0, 2])
    np.testing.assert_array_equal(col["T12x"], w.moment[:, 1, 0])
    np.testing.assert_array_equal(col["F23x"], w.force[:, 2, 0])
    np.testing.assert_array_equal(col["M23y"], w.moment[:, 2, 1])


@pytest.mark.parametrize("robot", ["ur5", "panda"])
def test_other_arms_base_wrench_is_the_momentum_rate(robot, rng):
    # Whole-arm balance: joint 1 carries d(momentum)/dt minus gravity (Pinocchio's
    # centroidal-momentum rate, a different algorithm from RNEA).
    model = load_urdf_model(robot_urdf(robot))
    data = model.createData()
    n = 20
    q = rng.uniform(
        np.maximum(model.lowerPositionLimit, -3),
        np.minimum(model.upperPositionLimit, 3),
        (n, model.nq),
    )
    qd, qdd = rng.normal(0, 1.5, (n, model.nv)), rng.normal(0, 4, (n, model.nv))
    w = joint_wrenches(Robot.from_model(model), q, qd, qdd)
    assert w.joint_names == tuple(model.names[1:]) and w.force.shape == (n, model.njoints - 1, 3)
    names, table = wrench_table(w, rrt=False)
    assert names == generic_wrench_columns(w.joint_names)
    assert table.shape == (n, 6 * model.nv)
    mass = sum(model.inertias[j].mass for j in range(1, model.njoints))
    for i in range(n):
        dh = pin.computeCentroidalMomentumTimeVariation(model, data, q[i], qd[i], qdd[i])
        com = data.com[0]
        base = data.oMi[1].act(pin.Force(w.force[i, 0], w.moment[i, 0]))
        at_com = pin.SE3(np.eye(3), com).actInv(base)
        expected_f = dh.linear - mass * model.gravity.linear
        scale = np.abs(w.force[i]).max() + np.abs(w.moment[i]).max()
        np.testing.assert_allclose(at_com.linear, expected_f, rtol=0, atol=DERIVED * scale)
        np.testing.assert_allclose(at_com.angular, dh.angular, rtol=0, atol=DERIVED * scale)


def test_generic_column_names():
    assert generic_wrench_columns(["a", "b"]) == (
        "fx_a", "fy_a", "fz_a", "mx_a", "my_a", "mz_a",
        "fx_b", "fy_b", "fz_b", "mx_b", "my_b", "mz_b",
    )  # fmt: skip


def test_bad_input(seed_model):
    with pytest.raises(InputError, match="q has shape \\(2, 2\\) but needs \\(N, 3\\)"):
        joint_wrenches(
            Robot.from_model(seed_model), np.zeros((2, 2)), np.zeros((2, 3)), np.zeros((2, 3))
        )
    with pytest.raises(InputError, match="qdd\\[1, 0\\]=nan must be finite"):
        joint_wrenches(
            Robot.from_model(seed_model),
            np.zeros((2, 3)),
            np.zeros((2, 3)),
            [[0, 0, 0], [np.nan, 0, 0]],
        )
