"""Kane = Lagrange = sympy's KanesMethod = Pinocchio (CRBA, RNEA) = the generated kernel."""

import numpy as np
import pinocchio as pin
import pytest

sp = pytest.importorskip("sympy")

from rrt_pin.core.errors import ParameterError  # noqa: E402
from rrt_pin.dynamics import kernel  # noqa: E402
from rrt_pin.dynamics.symbolic import METHODS, EquationsOfMotion, equations_of_motion  # noqa: E402
from rrt_pin.dynamics.symbolic.simplify import trig_normal  # noqa: E402
from rrt_pin.dynamics.symbolic.symbols import L1, LB, to_plain  # noqa: E402
from rrt_pin.robot.model import rrt_model  # noqa: E402
from rrt_pin.robot.params import Params  # noqa: E402
from tests.support import DERIVED, TIGHT, random_params, random_states, rel_err  # noqa: E402  # noqa: E402

N_STATES = 150


def _vectorized(exprs, args):
    """One numpy function per expression, broadcast and stacked on a last axis."""
    funcs = [sp.lambdify(args, e, modules="numpy") for e in exprs]

    def evaluate(*values):
        out = [np.asarray(f(*values), dtype=float) for f in funcs]
        shape = np.broadcast_shapes(*(o.shape for o in out))
        return np.stack([np.broadcast_to(o, shape) for o in out], axis=-1)

    return evaluate


@pytest.fixture(scope="session", params=METHODS)
def numeric(request):
    """M(q, params) -> (N, 3, 3) and f(q, q̇, τ, params) -> (N, 3), lambdified once per method."""
    eom = equations_of_motion(request.param)
    args = (*eom.q, *eom.qd, *eom.efforts, *eom.parameters)
    M = _vectorized(list(eom.mass_matrix), args)
    f = _vectorized(list(eom.forcing), args)

    def mass(q, params):
        zeros = np.zeros(len(q))
        return M(*q.T, *([zeros] * 6), *kernel.param_vector(params)).reshape(-1, 3, 3)

    def forcing(q, qd, tau, params):
        return f(*q.T, *qd.T, *tau.T, *kernel.param_vector(params))

    return request.param, mass, forcing


# ---- the two derivations agree ------------------------------------------------------


def test_kane_minus_lagrange_is_zero_symbolically():
    k, lag = equations_of_motion("kane"), equations_of_motion("lagrange")
    assert sp.simplify(k.mass_matrix - lag.mass_matrix) == sp.zeros(3, 3)
    assert sp.simplify(k.forcing - lag.forcing) == sp.zeros(3, 1)


def test_kane_plus_lagrange_residuals_expand_to_zero_before_normalization():
    # Raw equations (K*r + Qr = 0 and d/dt ∂T/∂q̇r − ∂T/∂qr − Qr = 0), no normal form.
    from rrt_pin.dynamics.symbolic.kane import kane_equations
    from rrt_pin.dynamics.symbolic.lagrange import lagrange_equations

    for k, lag in zip(kane_equations(), lagrange_equations(), strict=True):
        assert sp.expand(sp.expand_trig(to_plain(k + lag))) == 0


def test_kane_equals_sympys_own_kanes_method():
    """A third derivation: sympy's KanesMethod with rigid bodies and loads."""
    from sympy.physics.mechanics import KanesMethod, Point, RigidBody, dynamicsymbols, inertia

    from rrt_pin.dynamics.symbolic import frames
    from rrt_pin.dynamics.symbolic import symbols as S

    F0, F1, F2 = frames.frame0, frames.frame1, frames.frame2
    A = Point("A")
    A.set_vel(F0, 0)
    C1 = A.locatenew("C1", S.L1 * F1.z)
    C1.v2pt_theory(A, F0, F1)
    B = A.locatenew("B", S.LB * F1.z)
    B.v2pt_theory(A, F0, F1)
    C2 = B.locatenew("C2", S.L2 * F2.z)
    C2.v2pt_theory(B, F0, F2)
    C3 = C2.locatenew("C3", S.q3 * F2.z)
    C3.set_vel(F2, S.qd[2] * F2.z)
    C3.v1pt_theory(C2, F0, F2)
    C32 = C2.locatenew("C32", S.q3 * F2.z)
    C32.v2pt_theory(C2, F0, F2)
    bodies = [
        RigidBody("b1", C1, F1, S.m1, (inertia(F1, S.I1x, S.I1y, S.I1z), C1)),
        RigidBody("b2", C2, F2, S.m2, (inertia(F2, S.I2x, S.I2y, S.I2z), C2)),
        RigidBody("b3", C3, F2, S.m3, (inertia(F2, S.I3x, S.I3y, S.I3z), C3)),
    ]
    T01 = sum((c * e for c, e in zip(S.T01, (F1.x, F1.y, F1.z), strict=True)), 0 * F1.x)
    T12 = sum((c * e for c, e in zip(S.T12, (F2.x, F2.y, F2.z), strict=True)), 0 * F2.x)
    F23 = sum((c * e for c, e in zip(S.F23, (F2.x, F2.y, F2.z), strict=True)), 0 * F2.x)
    loads = [
        (C1, -S.m1 * S.g * F0.x),
        (C2, -S.m2 * S.g * F0.x),
        (C3, -S.m3 * S.g * F0.x),
        (F1, T01 - T12),
        (F2, T12),
        (C3, F23),
        (C32, -F23),
    ]
    u = dynamicsymbols("u1:4")
    km = KanesMethod(
        F0, q_ind=list(S.q), u_ind=u, kd_eqs=[a - b for a, b in zip(S.qd, u, strict=True)]
    )
    km.kanes_equations(bodies, loads)
    plain = {
        **{ui.diff(S.t): a for ui, a in zip(u, S.qdd_plain, strict=True)},
        **dict(zip(u, S.qd_plain, strict=True)),
    }
    eom = equations_of_motion("kane")
    for ours, theirs in ((eom.mass_matrix, km.mass_matrix), (eom.forcing, km.forcing)):
        theirs = to_plain(theirs.xreplace(plain)).subs(LB, 2 * L1)
        for a, b in zip(ours, theirs, strict=True):
            assert trig_normal(a - b, eom.q[:2]) == 0


# ---- against Pinocchio ----------------------------------------------------------------


@pytest.fixture(scope="module", params=["seed", "random"])
def states(request):
    rng = np.random.default_rng(31 if request.param == "seed" else 32)
    params = Params() if request.param == "seed" else random_params(rng)
    q, qd, qdd = random_states(rng, N_STATES)
    tau = rng.normal(0.0, 300.0, (N_STATES, 3))
    model = rrt_model(params)
    data = model.createData()
    M, rnea, bias = [], [], []
    for qi, vi, ai in zip(q, qd, qdd, strict=True):
        Mi = pin.crba(model, data, qi).copy()
        M.append(np.triu(Mi) + np.triu(Mi, 1).T)
        rnea.append(pin.rnea(model, data, qi, vi, ai).copy())
        bias.append(pin.rnea(model, data, qi, vi, np.zeros(3)).copy())
    return params, q, qd, qdd, tau, np.array(M), np.array(rnea), np.array(bias)


def test_mass_matrix_equals_crba(numeric, states):
    _, mass, _ = numeric
    params, q, _, _, _, M, _, _ = states
    assert rel_err(mass(q, params), M) <= DERIVED


def test_forcing_equals_efforts_minus_rnea_bias(numeric, states):
    # f(q, q̇, τ) = τ − RNEA(q, q̇, 0) for arbitrary efforts τ.
    _, _, forcing = numeric
    params, q, qd, _, tau, _, _, bias = states
    assert rel_err(forcing(q, qd, tau, params), tau - bias) <= DERIVED


def test_equations_hold_along_rnea(numeric, states):
    # With τ = RNEA(q, q̇, q̈): M·q̈ = f.
    _, mass, forcing = numeric
    params, q, qd, qdd, _, _, rnea, _ = states
    lhs = np.einsum("nij,nj->ni", mass(q, params), qdd)
    assert rel_err(lhs, forcing(q, qd, rnea, params)) <= DERIVED


def test_pinocchio_comparison_has_teeth(numeric, states):
    _, mass, _ = numeric
    params, q, _, _, _, M, _, _ = states
    wrong = params.with_overrides({"m2": params.m2 * 1.001})
    assert rel_err(mass(q, wrong), M) > 1e-6


def test_kernel_equals_the_sympy_expressions(states):
    from rrt_pin.dynamics.symbolic.codegen import kernel_expressions

    params, q, qd, _, _, _, _, _ = states
    args, exprs = kernel_expressions()
    reference = _vectorized(exprs, args)(*q.T, *qd.T, *kernel.param_vector(params))
    got = np.stack(
        [
            np.broadcast_to(v, (len(q),))
            for v in kernel.terms(*q.T, *qd.T, *kernel.param_vector(params))
        ],
        axis=-1,
    )
    scale = np.abs(reference).max(axis=0)
    np.testing.assert_allclose(got, reference, rtol=TIGHT, atol=TIGHT * scale.max())


def test_kernel_terms_are_the_eoms_split(states):
    # Kernel's M, c + G against the result type's mass_matrix and −forcing(τ = 0).
    params, q, qd, _, _, _, _, _ = states
    eom = equations_of_motion("lagrange")
    args = (*eom.q, *eom.qd, *eom.parameters)
    pv = kernel.param_vector(params)
    bias = _vectorized(list(eom.bias), args)(*q.T, *qd.T, *pv)
    grav = _vectorized(list(eom.gravity), args)(*q.T, *qd.T, *pv)
    assert rel_err(kernel.nonlinear_effects(q, qd, params), bias) <= DERIVED
    np.testing.assert_allclose(
        kernel.gravity(q, params), grav, rtol=TIGHT, atol=TIGHT * np.abs(grav).max()
    )


# ---- the result type ------------------------------------------------------------------


def test_one_result_type_for_both_methods():
    k, lag = equations_of_motion("kane"), equations_of_motion("lagrange")
    assert type(k) is type(lag) is EquationsOfMotion
    assert (k.method, lag.method) == ("kane", "lagrange")
    assert k.mass_matrix.shape == (3, 3) and k.forcing.shape == (3, 1)
    assert k.mass_matrix == k.mass_matrix.T
    assert [str(s) for s in k.efforts] == ["T01x", "T12y", "F23z"]
    assert tuple(str(s) for s in k.parameters) == kernel.PARAM_ORDER
    allowed = set(k.q) | set(k.qd) | set(k.efforts) | set(k.parameters)
    assert k.forcing.free_symbols <= allowed
    assert k.mass_matrix.free_symbols <= set(k.q) | set(k.parameters)
    with pytest.raises(AttributeError):
        k.method = "lagrange"  # frozen


def test_derivation_is_cached():
    assert equations_of_motion("kane") is equations_of_motion("kane")
    assert equations_of_motion("lagrange", Params()) is equations_of_motion("lagrange", Params())


def test_numbers_substituted():
    p = Params()
    eom = equations_of_motion("kane", p)
    assert eom.params == p and eom.parameters == ()
    assert eom.mass_matrix.free_symbols <= set(eom.q)
    symbolic = equations_of_motion("kane")
    values = dict(zip(symbolic.parameters, kernel.param_vector(p), strict=True))
    point = {
        **dict(zip(eom.q, (0.3, -1.1, 0.4), strict=True)),
        **dict(zip(eom.qd, (0.5, 2.0, -1.0), strict=True)),
    }
    point.update(dict(zip(eom.efforts, (10.0, -20.0, 30.0), strict=True)))
    for a, b in zip(eom.forcing, symbolic.forcing, strict=True):
        assert float(a.subs(point)) == pytest.approx(float(b.subs(values).subs(point)), rel=1e-13)


def test_equations_residual_and_split():
    eom = equations_of_motion("kane")
    for e, res in zip(eom.equations(), eom.residual(), strict=True):
        assert sp.expand(e.lhs - e.rhs - res) == 0
    assert sp.expand(eom.velocity_terms + eom.gravity - eom.bias) == sp.zeros(3, 1)
    assert eom.gravity.free_symbols <= set(eom.q) | set(eom.parameters)


def test_bad_method_is_refused():
    with pytest.raises(ParameterError, match="method='hamilton'"):
        equations_of_motion("hamilton")
