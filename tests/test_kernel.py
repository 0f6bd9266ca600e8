"""The generated expressions (rrt_pin/dynamics/_kernel_terms.py) and their wrappers (rrt_pin/dynamics/kernel.py) against Pinocchio, numba and the generator."""

import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.dynamics import kernel
from rrt_pin.robot.model import rrt_model
from rrt_pin.robot.params import Params
from tests.support import DERIVED, TIGHT, holding_efforts, random_params, random_states, rel_err

N_STATES = 120


def pin_reference(model, q, qd, qdd):
    """Pinocchio's M (CRBA, symmetrized), RNEA τ, nonlinear effects and gravity per state."""
    data = model.createData()
    M, tau, nle, grav = [], [], [], []
    for qi, vi, ai in zip(q, qd, qdd, strict=True):
        Mi = pin.crba(model, data, qi).copy()
        M.append(np.triu(Mi) + np.triu(Mi, 1).T)
        tau.append(pin.rnea(model, data, qi, vi, ai).copy())
        nle.append(pin.nonLinearEffects(model, data, qi, vi).copy())
        grav.append(pin.computeGeneralizedGravity(model, data, qi).copy())
    return np.array(M), np.array(tau), np.array(nle), np.array(grav)


@pytest.fixture(scope="module", params=["seed", "random"])
def case(request):
    rng = np.random.default_rng(7 if request.param == "seed" else 8)
    params = Params() if request.param == "seed" else random_params(rng)
    q, qd, qdd = random_states(rng, N_STATES)
    model = rrt_model(params)
    return params, q, qd, qdd, pin_reference(model, q, qd, qdd), model


def test_param_vector_order():
    p = Params()
    assert kernel.PARAM_ORDER[0] == "L1" and kernel.PARAM_ORDER[-1] == "g"
    np.testing.assert_array_equal(
        kernel.param_vector(p), [getattr(p, n) for n in kernel.PARAM_ORDER]
    )
    assert kernel.param_vector(p).dtype == np.float64


def test_mass_matrix_equals_crba(case):
    params, q, _, _, (M, _, _, _), _ = case
    assert rel_err(kernel.mass_matrix(q, params), M) <= DERIVED


def test_inverse_dynamics_equals_rnea(case):
    params, q, qd, qdd, (_, tau, _, _), _ = case
    assert rel_err(kernel.inverse_dynamics(q, qd, qdd, params), tau) <= DERIVED


def test_nonlinear_effects_and_gravity_equal_pinocchio(case):
    params, q, qd, _, (_, _, nle, grav), _ = case
    assert rel_err(kernel.nonlinear_effects(q, qd, params), nle) <= DERIVED
    g = kernel.gravity(q, params)
    np.testing.assert_allclose(g, grav, rtol=0, atol=DERIVED * np.abs(grav).max())
    # and the gravity parts of the seed's eq. (15), typed independently
    expected = np.array([holding_efforts(params, qi) for qi in q])
    np.testing.assert_allclose(g, expected, rtol=0, atol=TIGHT * np.abs(expected).max())


def test_forward_dynamics_equals_aba(case):
    params, q, qd, _, _, model = case
    rng = np.random.default_rng(9)
    tau = rng.normal(0.0, 200.0, (len(q), 3))
    data = model.createData()
    expected = np.array(
        [pin.aba(model, data, qi, vi, ti) for qi, vi, ti in zip(q, qd, tau, strict=True)]
    )
    assert rel_err(kernel.forward_dynamics(q, qd, tau, params), expected) <= DERIVED


def test_forward_inverts_inverse(case):
    params, q, qd, qdd, _, _ = case
    tau = kernel.inverse_dynamics(q, qd, qdd, params)
    assert rel_err(kernel.forward_dynamics(q, qd, tau, params), qdd) <= DERIVED


def test_a_wrong_parameter_is_caught(case):
    # The comparison above has teeth: the slider's mass off by 1 % is seen.
    params, q, qd, qdd, (_, tau, _, _), _ = case
    wrong = params.with_overrides({"m3": params.m3 * 1.01})
    assert rel_err(kernel.inverse_dynamics(q, qd, qdd, wrong), tau) > 1e-6


def test_single_state_shapes():
    p = Params()
    q, qd, qdd = np.array(p.q0), np.array([0.1, -0.2, 0.3]), np.array([1.0, 2.0, 3.0])
    assert kernel.mass_matrix(q, p).shape == (3, 3)
    assert kernel.gravity(q, p).shape == (3,)
    tau = kernel.inverse_dynamics(q, qd, qdd, p)
    assert tau.shape == (3,)
    np.testing.assert_allclose(kernel.forward_dynamics(q, qd, tau, p), qdd, rtol=TIGHT)
    many = kernel.inverse_dynamics(q[None], qd[None], qdd[None], p)
    np.testing.assert_array_equal(many[0], tau)


def test_terms_on_floats_equal_terms_on_arrays(rng):
    q, qd, _ = random_states(rng, 5)
    pv = kernel.param_vector(Params())
    arrays = kernel.terms(*q.T, *qd.T, *pv)
    for i in range(5):
        scalars = kernel.terms(*q[i], *qd[i], *pv)
        for a, s in zip(arrays, scalars, strict=True):
            assert np.broadcast_to(a, (5,))[i] == s


@pytest.mark.parametrize(
    "bad, match",
    [
        (np.zeros((4, 2)), r"q\.shape=\(4, 2\)"),
        (np.zeros((2, 3, 3)), r"q\.shape=\(2, 3, 3\)"),
        (np.array([[0.0, np.nan, 0.0]]), "q has non-finite"),
        (np.array([0.0, np.inf, 0.0]), "q has non-finite"),
    ],
)
def test_bad_states_are_refused(bad, match):
    with pytest.raises(InputError, match=match):
        kernel.mass_matrix(bad, Params())
    with pytest.raises(InputError, match=match):
        kernel.inverse_dynamics(bad, np.zeros(3), np.zeros(3), Params())


def test_numba_compiles_terms_unchanged(rng):
    numba = pytest.importorskip("numba")
    fast = numba.njit(kernel.terms)
    q, qd, _ = random_states(rng, 3)
    pv = kernel.param_vector(Params())
    for qi, vi in zip(q, qd, strict=True):
        expected = kernel.terms(*qi, *vi, *pv)
        got = fast(*qi, *vi, *pv)
        np.testing.assert_allclose(got, expected, rtol=TIGHT, atol=0)
    arrays = fast(*q.T, *qd.T, *pv)  # numba also takes the arrays
    np.testing.assert_allclose(arrays[0], kernel.terms(*q.T, *qd.T, *pv)[0], rtol=TIGHT)


def test_kernel_imports_no_sympy():
    code = "import sys, rrt_pin.dynamics.kernel; print('sympy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_committed_kernel_is_the_generators_output():
    pytest.importorskip("sympy")
    from rrt_pin.dynamics.symbolic.codegen import KERNEL_PATH, kernel_source

    assert KERNEL_PATH.read_text(encoding="utf-8") == kernel_source(), (
        "rrt_pin/dynamics/_kernel_terms.py drifted from the derivation: run python -m rrt_pin.dynamics.symbolic.codegen"
    )


def test_drift_check_can_fail(tmp_path):
    pytest.importorskip("sympy")
    from rrt_pin.dynamics.symbolic.codegen import kernel_source, main

    stale = tmp_path / "kernel.py"
    stale.write_text(kernel_source().replace("x1 = cos(q2)", "x1 = sin(q2)"), encoding="utf-8")
    assert main(["--check", "-o", str(stale)]) == 1
    stale.write_text(kernel_source(), encoding="utf-8")
    assert main(["--check", "-o", str(stale)]) == 0


@pytest.mark.parametrize(
    "table, name, wrong, message",
    [
        ("SHARED_LINES", "x15", "c2*(m3L1x2 + s2*mr)", "tau1 of the plan differs"),
        ("INVERSE_LINES", "tau3", "m3*qdd3 - (qd2*qd2*mr + w1*x15)", "tau3 of the plan differs"),
        ("FORWARD_LINES", "M22", "kM22 + mr", "M22 of the plan differs"),
        ("FORWARD_LINES", "n2", "w1*x19 + qd2*qd3*mr", "n2 of the plan differs"),
    ],
)
def test_the_plans_are_proved_and_a_wrong_line_is_caught(monkeypatch, table, name, wrong, message):
    pytest.importorskip("sympy")
    from rrt_pin.dynamics.symbolic import codegen

    codegen.check_inverse_plan()  # the committed plans equal Kane's equations
    lines = list(getattr(codegen, table))
    i = [n for n, _ in lines].index(name)
    lines[i] = (name, wrong)
    monkeypatch.setattr(codegen, table, tuple(lines))
    with pytest.raises(AssertionError, match=message):
        codegen.check_inverse_plan()


def test_flop_count_counts_operations():
    pytest.importorskip("sympy")
    from rrt_pin.dynamics.symbolic.codegen import flop_count

    assert flop_count("a*b + c - d**2") == 4
    assert flop_count("-(a + b)*c") == 3
    assert flop_count("x") == 0
    with pytest.raises(ValueError, match="only squares"):
        flop_count("a**3")


def test_inverse_terms_equal_the_full_terms(case):
    """The hand-factored inverse against M·q̈ + c + G of the CSE'd ``terms`` (both generated)."""
    params, q, qd, qdd, _, _ = case
    M11, M12, M13, M22, M23, M33, c1, c2, c3, G1, G2, G3 = kernel.terms(
        *q.T, *qd.T, *kernel.param_vector(params)
    )
    a1, a2, a3 = qdd.T
    full = np.column_stack(
        [
            M11 * a1 + M12 * a2 + M13 * a3 + c1 + G1,
            M12 * a1 + M22 * a2 + M23 * a3 + c2 + G2,
            M13 * a1 + M23 * a2 + M33 * a3 + c3 + G3,
        ]
    )
    fast = np.column_stack(
        kernel.inverse_terms(
            np.cos(q[:, 1]),
            np.sin(q[:, 1]),
            q[:, 2],
            *qd.T,
            *qdd.T,
            *kernel.inverse_constants(*kernel.param_vector(params)),
        )  # fmt: skip
    )
    assert rel_err(fast, full) <= 1e-14
    assert kernel.INVERSE_FLOPS < 60  # ~166 multiplications and additions in the full form


def test_forward_terms_equal_the_full_terms(case):
    """forward_terms' diagonal M, c and G against the CSE'd ``terms``; its q̈ against ABA."""
    params, q, qd, _, _, model = case
    full = kernel.terms(*q.T, *qd.T, *kernel.param_vector(params))
    full = np.array([np.broadcast_to(v, q.shape[:1]) for v in full])
    M11, M22, n1, n2, n3, G2, G3 = kernel.forward_terms(
        np.cos(q[:, 1]), np.sin(q[:, 1]), q[:, 2], *qd.T,
        *kernel.inverse_constants(*kernel.param_vector(params)),
    )  # fmt: skip
    for mine, theirs in zip(
        (M11, M22, n1, n2, n3, G2, G3), full[[0, 3, 6, 7, 8, 10, 11]], strict=True
    ):
        np.testing.assert_allclose(mine, theirs, rtol=1e-13, atol=1e-12 * np.abs(theirs).max())
    np.testing.assert_array_equal(full[[1, 2, 4, 9]], 0.0)  # what it leaves out
    tau = np.random.default_rng(3).normal(0.0, 50.0, q.shape)
    qdd = np.column_stack(
        [(tau[:, 0] - n1) / M11, (tau[:, 1] - n2 - G2) / M22, (tau[:, 2] - n3 - G3) / params.m3]
    )
    data = model.createData()
    aba = np.array([pin.aba(model, data, a, b, c) for a, b, c in zip(q, qd, tau, strict=True)])
    assert rel_err(qdd, aba) <= DERIVED
