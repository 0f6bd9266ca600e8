"""Batched inverse dynamics: against per-sample RNEA, CRBA + NLE, an independent
Lagrangian typed from the seed's T and V, the seed's holding efforts, other arms."""

import importlib.util

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.model import load_urdf_model, rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from tests.support import DERIVED, TIGHT, holding_efforts, kinetic_energy, random_states, robot_urdf

HAS_KERNEL = importlib.util.find_spec("rrt_pin.dynamics.kernel") is not None


# An independent Lagrangian, typed from the seed's T (general central inertias) and V.
# T = ½·Σ m·|vC|² + ½·ω·Ī·ω with, from eqs. (5)–(11) (typos corrected):
#   vC1 = −L1·q̇1 ȷ1;  vC2 = L2·q̇2 ı2 − (LB + L2·c2)·q̇1 ȷ2;
#   vC3 = (L2 + q3)·q̇2 ı2 − (LB + (L2 + q3)·c2)·q̇1 ȷ2 + q̇3 k2;
#   ω1 = q̇1 ı1;  ω2 = ω3 = q̇1·c2 ı2 + q̇2 ȷ2 + q̇1·s2 k2.
# So M is diagonal: T = ½·(M11·q̇1² + M22·q̇2² + M33·q̇3²), and
# V = g·(m2·L2 + m3·(L2 + q3))·s2.
def lagrange_terms(p, q):
    q2, q3 = q[:, 1], q[:, 2]
    c2, s2 = np.cos(q2), np.sin(q2)
    r3 = p.L2 + q3
    arm2 = p.LB + p.L2 * c2  # distance of C2 from the vertical axis ı0
    arm3 = p.LB + r3 * c2  # distance of C3 from the vertical axis
    M11 = (
        p.m1 * p.L1**2
        + p.I1x
        + p.m2 * arm2**2
        + p.m3 * arm3**2
        + (p.I2x + p.I3x) * c2**2
        + (p.I2z + p.I3z) * s2**2
    )
    M22 = p.m2 * p.L2**2 + p.I2y + p.I3y + p.m3 * r3**2
    M33 = np.full_like(q2, p.m3)
    dM11_dq2 = (
        -2 * p.m2 * arm2 * p.L2 * s2
        - 2 * p.m3 * arm3 * r3 * s2
        + 2 * (p.I2z + p.I3z - p.I2x - p.I3x) * s2 * c2
    )
    dM11_dq3 = 2 * p.m3 * arm3 * c2
    dM22_dq3 = 2 * p.m3 * r3
    dV = np.column_stack([0 * q2, p.g * c2 * (p.m2 * p.L2 + p.m3 * r3), p.g * p.m3 * s2])
    return (M11, M22, M33), (dM11_dq2, dM11_dq3, dM22_dq3), dV


def lagrange_inverse_dynamics(p, q, qd, qdd):
    """d/dt(∂T/∂q̇) − ∂T/∂q + ∂V/∂q, row by row (N, 3)."""
    (M11, M22, M33), (a2, a3, b3), dV = lagrange_terms(p, q)
    u1, u2, u3 = qd.T
    tau1 = M11 * qdd[:, 0] + (a2 * u2 + a3 * u3) * u1
    tau2 = M22 * qdd[:, 1] + b3 * u3 * u2 - 0.5 * a2 * u1**2
    tau3 = M33 * qdd[:, 2] - 0.5 * a3 * u1**2 - 0.5 * b3 * u2**2
    return np.column_stack([tau1, tau2, tau3]) + dV


def seed_run(p):
    return rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, 0.001))


def rnea_loop(model, q, qd, qdd):
    data = model.createData()
    return np.array([pin.rnea(model, data, *s) for s in zip(q, qd, qdd, strict=True)])


def assert_close_rel(a, b, rtol):
    """|a − b| ≤ rtol·max|b| column by column (efforts cross zero, so not pointwise)."""
    scale = np.maximum(np.abs(b).max(axis=0), 1e-300)
    err = (np.abs(a - b) / scale).max()
    assert err <= rtol, f"max relative error {err:.3g} > {rtol:g}"


# --- the typed Lagrangian is right, so the comparisons below mean something ------------


def test_typed_lagrangian_energy_is_the_seeds(seed_params, rng):
    q, qd, _ = random_states(rng, 50)
    (M11, M22, M33), _, _ = lagrange_terms(seed_params, q)
    T = 0.5 * (M11 * qd[:, 0] ** 2 + M22 * qd[:, 1] ** 2 + M33 * qd[:, 2] ** 2)
    expected = [kinetic_energy(seed_params, a, b) for a, b in zip(q, qd, strict=True)]
    np.testing.assert_allclose(T, expected, rtol=TIGHT)


def test_typed_lagrangian_derivatives_match_finite_differences(rng):
    p = Params(I2z=0.3, I1z=0.2, I2x=9.6, I3z=1.5)  # non-rod inertias reach every term
    q, _, _ = random_states(rng, 20)
    h = 1e-6
    for k, (col, name) in enumerate([(1, "dM11_dq2"), (2, "dM11_dq3"), (2, "dM22_dq3")]):
        dq = np.zeros(3)
        dq[col] = h
        which = 1 if name == "dM22_dq3" else 0
        plus = lagrange_terms(p, q + dq)[0][which]
        minus = lagrange_terms(p, q - dq)[0][which]
        fd = (plus - minus) / (2 * h)
        np.testing.assert_allclose(lagrange_terms(p, q)[1][k], fd, rtol=1e-6, atol=1e-6)


# --- the batched RNEA ----------------------------------------------------------------


def test_batched_equals_per_sample_rnea_on_the_seed_run(seed_model, seed_params):
    traj = seed_run(seed_params)
    assert len(traj) == 15001
    tau = inverse_dynamics(chapter_arm(seed_params), traj.q, traj.qd, traj.qdd)
    assert tau.shape == (15001, 3)
    assert_close_rel(tau, rnea_loop(seed_model, traj.q, traj.qd, traj.qdd), TIGHT)


def test_rnea_matches_the_lagrangian_over_the_whole_run(seed_model, seed_params):
    traj = seed_run(seed_params)
    tau = inverse_dynamics(chapter_arm(seed_params), traj.q, traj.qd, traj.qdd)
    assert_close_rel(
        tau, lagrange_inverse_dynamics(seed_params, traj.q, traj.qd, traj.qdd), DERIVED
    )


@pytest.mark.parametrize(
    "params",
    [Params(), Params(m3=7.0, L2=1.3, g=3.7, I2z=0.4, I1z=0.1, I3x=3.5)],
    ids=["seed", "other"],
)
def test_rnea_matches_the_lagrangian_at_random_states(params, rng):
    q, qd, qdd = random_states(rng, 2000)
    tau = inverse_dynamics(chapter_arm(params), q, qd, qdd)
    assert_close_rel(tau, lagrange_inverse_dynamics(params, q, qd, qdd), DERIVED)


def test_the_lagrangian_comparison_can_fail(seed_model, seed_params, rng):
    # A 1 % error in one of the slider's inertias (I3z) shows, far above the tolerance.
    q, qd, qdd = random_states(rng, 200)
    tau = inverse_dynamics(chapter_arm(seed_params), q, qd, qdd)
    wrong = lagrange_inverse_dynamics(Params(I3z=1.01), q, qd, qdd)
    with pytest.raises(AssertionError):
        assert_close_rel(tau, wrong, 1e4 * DERIVED)


def test_seed_values_at_rest_at_both_ends(seed_model, seed_params):
    # t = 0: T01x = 0, T12y = g·c2·(m2·L2 + m3·(L2 + q3)), F23z = g·m3·s2 at q(0); t = Tp: at qf.
    p = seed_params
    traj = rest_to_rest(p.q0, p.qf, p.Tp, [0.0, p.Tp])
    tau = inverse_dynamics(chapter_arm(seed_params), traj.q, traj.qd, traj.qdd)
    for row, q in ((0, p.q0), (1, p.qf)):
        expected = holding_efforts(p, np.array(q))
        scale = np.abs(expected).max()
        assert abs(tau[row, 0]) <= TIGHT * scale  # T01x = 0 (rounding of the mount's rotation)
        np.testing.assert_allclose(tau[row], expected, rtol=TIGHT, atol=TIGHT * scale)


@pytest.mark.parametrize("robot", ["ur5", "panda"])
def test_other_arms_batched_rnea_and_crba_plus_nle(robot, rng):
    model = load_urdf_model(robot_urdf(robot))
    n = 500
    lo = np.maximum(model.lowerPositionLimit, -3.0)
    hi = np.minimum(model.upperPositionLimit, 3.0)
    q = rng.uniform(lo, hi, (n, model.nq))
    qd = rng.normal(0.0, 1.5, (n, model.nv))
    qdd = rng.normal(0.0, 4.0, (n, model.nv))
    tau = inverse_dynamics(Robot.from_model(model), q, qd, qdd)
    assert_close_rel(tau, rnea_loop(model, q, qd, qdd), TIGHT)
    data = model.createData()
    for i in range(0, n, 10):
        M = pin.crba(model, data, q[i])
        M = np.triu(M) + np.triu(M, 1).T
        b = pin.nonLinearEffects(model, data, q[i], qd[i])
        expected = M @ qdd[i] + b
        np.testing.assert_allclose(tau[i], expected, rtol=0, atol=DERIVED * np.abs(expected).max())


def test_threads_do_not_change_the_result(seed_model, rng):
    q, qd, qdd = random_states(rng, 3000)
    one = inverse_dynamics(Robot.from_model(seed_model), q, qd, qdd, num_threads=1)
    two = inverse_dynamics(Robot.from_model(seed_model), q, qd, qdd, num_threads=2)
    np.testing.assert_array_equal(one, two)


def test_single_state_empty_batch_and_gravity_changes(seed_params):
    model = rrt_model(seed_params)
    q = np.array(seed_params.q0)
    tau = inverse_dynamics(Robot.from_model(model), q, np.zeros(3), np.zeros(3))
    assert tau.shape == (3,)  # one sample in, (nv,) out, as pin.rnea
    np.testing.assert_allclose(tau, holding_efforts(seed_params, q), rtol=TIGHT, atol=1e-12)
    assert inverse_dynamics(
        Robot.from_model(model), np.empty((0, 3)), np.empty((0, 3)), np.empty((0, 3))
    ).shape == (
        0,
        3,
    )
    model.gravity.linear[:] = 0.0  # the thread pool copies the model on each call
    np.testing.assert_array_equal(
        inverse_dynamics(Robot.from_model(model), q, np.zeros(3), np.zeros(3)), 0.0
    )


def test_inputs_are_not_modified(seed_model, rng):
    q, qd, qdd = random_states(rng, 10)
    copies = [a.copy() for a in (q, qd, qdd)]
    inverse_dynamics(Robot.from_model(seed_model), q, qd, qdd)
    for a, b in zip((q, qd, qdd), copies, strict=True):
        np.testing.assert_array_equal(a, b)


# --- the other backends ----------------------------------------------------------------


@pytest.mark.skipif(not HAS_KERNEL, reason="rrt_pin/dynamics/kernel.py not generated yet")
def test_symbolic_backend_matches_pinocchio_and_the_lagrangian(seed_model, seed_params):
    traj = seed_run(seed_params)
    sym = inverse_dynamics(chapter_arm(seed_params), traj.q, traj.qd, traj.qdd, backend="symbolic")
    assert_close_rel(
        sym, inverse_dynamics(chapter_arm(seed_params), traj.q, traj.qd, traj.qdd), DERIVED
    )
    assert_close_rel(
        sym, lagrange_inverse_dynamics(seed_params, traj.q, traj.qd, traj.qdd), DERIVED
    )


def test_compiled_backend_reports_when_unavailable(seed_params, monkeypatch):
    from rrt_pin.core import backends
    from rrt_pin.core.extras import MissingExtra

    monkeypatch.setattr(backends.Backend, "available", lambda self: self.name != "compiled")
    with pytest.raises(MissingExtra, match=r"numba not found \(needed for backend 'compiled'\)"):
        inverse_dynamics(
            chapter_arm(seed_params), np.zeros(3), np.zeros(3), np.zeros(3), backend="compiled"
        )


@pytest.mark.parametrize(
    "kwargs, words",
    [
        (dict(q=np.zeros((4, 2))), "q has shape (4, 2) but needs (N, 3)"),
        (dict(qd=np.zeros((4, 3, 1))), "qd has shape (4, 3, 1) but needs (N, 3)"),
        (dict(qdd=np.zeros((5, 3))), "sample counts differ"),
        (dict(q=np.full((4, 3), np.nan)), "q[0, 0]=nan must be finite"),
        (dict(qd=np.array([[0, 0, 0]] * 3 + [[0, np.inf, 0]])), "qd[3, 1]=inf must be finite"),
        (dict(qdd=[["a", 0, 0]] * 4), "qdd is not an array of numbers"),
        (dict(backend="fast"), "backend='fast' is not one of pinocchio, symbolic, compiled"),
        (dict(backend="symbolic"), "backend='symbolic' computes the chapter's RRT arm only"),
        (dict(model=None), "backend='pinocchio' needs a Robot or a Pinocchio model"),
        (dict(num_threads=0), "num_threads=0 must be >= 1"),
    ],
)
def test_bad_input_names_the_problem(seed_model, kwargs, words):
    args = dict(
        model=Robot.from_model(seed_model), q=np.zeros((4, 3)), qd=np.zeros((4, 3)),
        qdd=np.zeros((4, 3)),
    )  # fmt: skip
    args.update(kwargs)
    with pytest.raises(InputError) as info:
        inverse_dynamics(**args)
    assert words in str(info.value)


def test_kernel_backends_refuse_other_models(seed_params):
    ur5 = load_urdf_model(robot_urdf("ur5"))
    with pytest.warns(DeprecationWarning), pytest.raises(InputError, match="model.nq=6"):
        inverse_dynamics(
            ur5, np.zeros(3), np.zeros(3), np.zeros(3), backend="symbolic", params=seed_params
        )


def test_default_threads_follow_omp_num_threads(monkeypatch):
    from rrt_pin.dynamics.inverse import default_num_threads

    monkeypatch.delenv("OMP_NUM_THREADS", raising=False)
    cpus = default_num_threads()
    assert cpus >= 1
    monkeypatch.setenv("OMP_NUM_THREADS", "1")
    assert default_num_threads() == 1
    monkeypatch.setenv("OMP_NUM_THREADS", "not-a-number")
    assert default_num_threads() == cpus
