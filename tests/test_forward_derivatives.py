"""The Jacobian of the generated forward dynamics, by tangent propagation, and its kernels.

(rrt_pin.dynamics.forward_derivatives_source generates, rrt_pin.compiled.jacobian
compiles.) The generated q̈, ∂q̈/∂q, ∂q̈/∂q̇ and M⁻¹ are checked against Pinocchio's
``computeABADerivatives`` at random states for every fixed-base robot the package names
and for random trees, run as plain Python (the code the kernels loop over; UR5's and
Panda's Jacobians take 12 and 33 s to compile); against central differences of the
generated q̈ itself (no Pinocchio); and the closed loop of PD plus gravity against
Pinocchio's ABA and gravity derivatives. Compiled kernels are checked on small models.
"""

from __future__ import annotations

from math import cos, sin

import mpmath
import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.compiled.jacobian import derivative_kernel_for, module_source
from rrt_pin.core.errors import InputError
from rrt_pin.dynamics import forward_derivatives_source as fds
from rrt_pin.dynamics.forward_source import forward_source
from rrt_pin.robot import robots
from tests.test_generated_forward import EXAMPLE_ROBOTS, configuration, random_tree

#: Agreement asked of each block (q̈, ∂q̈/∂q, ∂q̈/∂q̇, M⁻¹), per state: max |x − x_pin|
#: relative to the block's max |x_pin|. Reached over 200 states: 5e-14 or better on every
#: model but kinova, 1.8e-12 (its M's condition number reaches 1.3e4); there, and on the
#: double pendulum's worst of 10⁴ states (2.4e-11), the generated code run in 40 digits
#: shows Pinocchio's rounding, not ours (see the last test).
AGREEMENT = 1e-11
#: Central differences of step h·(1 + |x|) agree to about h² · q̈''' ≈ 1e-8 relative.
FD_STEP = 1e-5
FD_AGREEMENT = 1e-6
STATES = 4
TREES = (1, 2, 5)


def _models() -> dict:
    return {
        "rrt": lambda: robots.get("rrt").model,
        **{name: (lambda name=name: robots.get(name).model) for name in EXAMPLE_ROBOTS},
        **{f"random_tree_{s}": (lambda s=s: random_tree(s)) for s in TREES},
    }


def run(gen, *arrays) -> np.ndarray:
    """The generated function of one sample, run by Python on each row of ``arrays``."""
    namespace = {"sin": sin, "cos": cos}
    exec(gen.function(), namespace)  # noqa: S102 - the generator's own code
    fn = namespace[gen.name]
    out = np.empty((arrays[0].shape[0], *gen.shape))
    for i, row in enumerate(zip(*arrays, strict=True)):
        fn(*row, out[i])
    return out


def states(nv: int, n: int = STATES, seed: int = 11):
    rng = np.random.default_rng(seed)
    return rng.uniform(-3, 3, (n, nv)), rng.normal(0, 2, (n, nv)), rng.normal(0, 10, (n, nv))


def reference(model: pin.Model, x, v, tau) -> list[np.ndarray]:
    """Pinocchio's q̈, ∂q̈/∂q, ∂q̈/∂q̇, M⁻¹ (M⁻¹ symmetrised from its upper triangle)."""
    data = model.createData()
    out: list[list] = [[], [], [], []]
    for q, qd, u in zip(configuration(model, x), v, tau, strict=True):
        dq, dv, minv = pin.computeABADerivatives(model, data, q, qd, u)
        upper = np.triu(minv)
        for k, value in enumerate((data.ddq, dq, dv, upper + np.triu(upper, 1).T)):
            out[k].append(np.array(value))
    return [np.array(x) for x in out]


def blocks(out: np.ndarray, nv: int) -> list[np.ndarray]:
    count = (out.shape[2] - 1) // nv
    return [out[:, :, 0]] + [out[:, :, 1 + b * nv : 1 + (b + 1) * nv] for b in range(count)]


def worst(a: np.ndarray, ref: np.ndarray) -> float:
    n = ref.shape[0]
    err = np.abs(a - ref).reshape(n, -1).max(axis=1)
    return float((err / np.abs(ref).reshape(n, -1).max(axis=1)).max())


@pytest.fixture(
    scope="module", params=[(m, v) for m in _models() for v in fds.VARIANTS], ids="-".join
)
def case(request):
    """(name, model, the generated q̈ and Jacobian along q, q̇, τ), generated once a module."""
    name, variant = request.param
    model = _models()[name]()
    return name, model, fds.forward_derivatives_source(model, variant, wrt=fds.DIRECTIONS)


def test_the_jacobian_agrees_with_compute_aba_derivatives(case):
    name, model, gen = case
    x, v, tau = states(model.nv)
    assert gen.shape == (model.nv, 1 + 3 * model.nv)
    got = blocks(run(gen, x, v, tau), model.nv)
    for what, a, ref in zip(
        ("ddq", "ddq_dq", "ddq_dv", "Minv"), got, reference(model, x, v, tau), strict=True
    ):
        assert worst(a, ref) <= AGREEMENT, (name, what, worst(a, ref))


@pytest.mark.parametrize("name", list(_models()))
def test_the_jacobian_agrees_with_central_differences_of_the_generated_forward_dynamics(name):
    """Independent of Pinocchio: the generated ABA, moved along each coordinate and velocity."""
    model = _models()[name]()
    gen = fds.forward_derivatives_source(model)
    nv = model.nv
    x, v, tau = states(nv, n=2, seed=5)
    jac = run(gen, x, v, tau)[:, :, 1:]
    aba = forward_source(model)
    for j in range(2 * nv):
        which = x if j < nv else v
        h = FD_STEP * (1.0 + np.abs(which[:, j % nv]))
        moved = []
        for sign in (1.0, -1.0):
            shifted = which.copy()
            shifted[:, j % nv] += sign * h
            args = (shifted, v) if j < nv else (x, shifted)
            moved.append(run(aba, *args, tau))
        fd = (moved[0] - moved[1]) / (2 * h[:, None])
        scale = np.abs(jac[:, :, : 2 * nv]).max()
        assert np.abs(fd - jac[:, :, j]).max() <= FD_AGREEMENT * scale, (name, j)


@pytest.mark.parametrize("name", ["ur5", "panda", "double_pendulum_continuous", "random_tree_2"])
def test_inverse_and_gravity_derivatives_agree_with_pinocchio(name):
    """τ, ∂τ/∂q, ∂τ/∂q̇ as computeRNEADerivatives; G, ∂G/∂q as its gravity derivatives."""
    model = _models()[name]()
    data = model.createData()
    x, v, a = states(model.nv, seed=9)
    inverse = blocks(run(fds.inverse_derivatives_source(model), x, v, a), model.nv)
    gravity = blocks(run(fds.gravity_derivatives_source(model), x), model.nv)
    want: list[list] = [[], [], [], [], []]
    for q, qd, qdd in zip(configuration(model, x), v, a, strict=True):
        dq, dv, _ = pin.computeRNEADerivatives(model, data, q, qd, qdd)
        values = (pin.rnea(model, data, q, qd, qdd), dq, dv)
        values += (
            pin.computeGeneralizedGravity(model, data, q),
            pin.computeGeneralizedGravityDerivatives(model, data, q),
        )
        for k, value in enumerate(values):
            want[k].append(np.array(value))
    for what, got, ref in zip(("tau", "dtau_dq", "dtau_dv", "G", "dG_dq"), [*inverse, *gravity],
                              want, strict=True):  # fmt: skip
        assert worst(got, np.array(ref)) <= AGREEMENT, (name, what, worst(got, np.array(ref)))


def test_the_check_can_fail():
    """A model with one body 1 % heavier is told apart in every block."""
    model = robots.get("double_pendulum").model
    heavier = pin.Model(model)
    heavier.inertias[2].mass *= 1.01
    x, v, tau = states(model.nv)
    got = blocks(run(fds.forward_derivatives_source(heavier, wrt=fds.DIRECTIONS), x, v, tau), 2)
    for a, ref in zip(got, reference(model, x, v, tau), strict=True):
        assert worst(a, ref) > 1e-5


def test_structural_zeros_are_dropped():
    """UR5's first joint turns about gravity's axis: its angle moves no q̈ (constant zeros)."""
    model = robots.get("ur5").model
    gen = fds.forward_derivatives_source(model)
    nv = model.nv
    assert gen.shape == (nv, 1 + 2 * nv)
    column = [gen.outputs[r * (1 + 2 * nv) + 1] for r in range(nv)]
    assert column == ["0.0"] * nv
    assert all(x.startswith("t") for x in gen.outputs[1 + nv :: 1 + 2 * nv])  # ∂q̈/∂q̇₀
    # a joint's velocity directions, not its q's, reach everything: fewer than 2nv copies
    assert gen.flops < 2 * nv * forward_source(model).flops


def test_the_closed_loop_jacobian_is_pd_plus_gravity_through_aba():
    """∂q̈/∂(q, q̇) of τ = G(q) − kd q̇ − kp (q − qf): Pinocchio's ABA and gravity derivatives."""
    for name in ("double_pendulum_continuous", "panda"):
        model = robots.get(name).model
        data = model.createData()
        nv = model.nv
        x, v, _ = states(nv, n=3, seed=8)
        rng = np.random.default_rng(2)
        kp, kd, qf = (
            rng.uniform(5, 50, (3, nv)),
            rng.uniform(1, 5, (3, nv)),
            rng.normal(0, 1, (3, nv)),
        )
        out = run(fds.closed_loop_derivatives_source(model), x, v, kp, kd, qf)
        for i, q in enumerate(configuration(model, x)):
            tau = (
                pin.computeGeneralizedGravity(model, data, q)
                - kd[i] * v[i]
                - kp[i] * (x[i] - qf[i])
            )
            dq, dv, minv = pin.computeABADerivatives(model, data, q, v[i], tau)
            minv = np.triu(minv) + np.triu(minv, 1).T
            dg = pin.computeGeneralizedGravityDerivatives(model, data, q)
            want = np.hstack(
                (pin.aba(model, data, q, v[i], tau)[:, None], dq + minv @ (dg - np.diag(kp[i])),
                 dv - minv * kd[i])
            )  # fmt: skip
            assert np.abs(out[i] - want).max() <= AGREEMENT * np.abs(want).max(), (name, i)


@pytest.fixture(scope="module")
def compiled():
    """Kernels of a small model (continuous joints) and a small random tree, compiled once.

    The tree: four joints (a branch; continuous, prismatic along x and an oblique axis).
    """
    return {
        name: (model, derivative_kernel_for(model, name))
        for name, model in (
            ("double_pendulum_continuous", robots.get("double_pendulum_continuous").model),
            ("small_tree", random_tree(1, joints=4)),
        )
    }


def test_the_compiled_kernels_run_the_generated_code(compiled):
    for name, (model, kernels) in compiled.items():
        x, v, tau = states(model.nv, n=50)
        qdd, dq, dv, minv = kernels.derivatives(x, v, tau, minv=True)
        ref = reference(model, x, v, tau)
        for what, a, r in zip(
            ("ddq", "ddq_dq", "ddq_dv", "Minv"), (qdd, dq, dv, minv), ref, strict=True
        ):
            assert worst(a, r) <= AGREEMENT, (name, what, worst(a, r))
        plain = kernels.derivatives(x, v, tau)
        assert len(plain) == 3 and all(
            np.array_equal(a, b) for a, b in zip(plain, (qdd, dq, dv), strict=True)
        )
        assert np.array_equal(kernels.derivatives(x, v, tau, num_threads=2)[1], dq)
    model, kernels = compiled["double_pendulum_continuous"]
    x, v, a = states(model.nv, n=20)
    want = blocks(run(kernels.source("inverse_derivatives"), x, v, a), model.nv)
    for got, ref in zip(kernels.inverse_derivatives(x, v, a), want, strict=True):
        assert np.allclose(got, ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())
    want = blocks(run(kernels.source("gravity_derivatives"), x), model.nv)
    for got, ref in zip(kernels.gravity_derivatives(x), want, strict=True):
        assert np.allclose(got, ref, rtol=1e-13, atol=1e-13 * np.abs(ref).max())


def test_the_vectorised_kernel_follows_the_one_sample_kernel(compiled):
    """Lanes of a block: the same statements (sines and cosines by polynomial, libm's for a
    huge angle), a sample's result independent of its block, a bad sample refused."""
    model, kernels = compiled["small_tree"]
    x, v, tau = states(model.nv, n=150)  # two blocks of 64 and one of 22
    x[70, 0] = 1e9  # beyond the polynomial's range: this block takes libm's
    want = kernels.derivatives(x, v, tau)
    got = kernels.derivatives(x, v, tau, vectorised=True)
    for a, b in zip(got, want, strict=True):
        assert np.abs(a - b).max() <= 1e-13 * np.abs(b).max()
    alone = kernels.derivatives(x[70:71], v[70:71], tau[70:71], vectorised=True)
    assert all(np.array_equal(a[70:71], b) for a, b in zip(got, alone, strict=True))
    bad = tau.copy()
    bad[149, 1] = np.inf
    with pytest.raises(InputError, match=r"tau\[149, 1\]=inf"):
        kernels.derivatives(x, v, bad, vectorised=True)
    with pytest.raises(InputError, match="vectorised=True"):
        kernels.derivatives(x, v, tau, vectorised=True, minv=True)


def test_the_closed_loop_kernel_and_the_solve_ivp_jac_agree(compiled):
    model, kernels = compiled["small_tree"]
    nv = model.nv
    x, v, _ = states(nv, n=6)
    rng = np.random.default_rng(4)
    kp, kd, qf = rng.uniform(5, 50, (6, nv)), rng.uniform(1, 5, (6, nv)), rng.normal(0, 1, (6, nv))
    qdd, jac = kernels.closed_loop(x, v, kp, kd, qf)
    want = run(kernels.source("closed_loop_derivatives"), x, v, kp, kd, qf)
    assert np.allclose(qdd, want[:, :, 0], rtol=1e-13, atol=0)
    assert jac.shape == (6, 2 * nv, 2 * nv)
    assert np.array_equal(jac[:, :nv, :nv], np.zeros((6, nv, nv)))
    assert np.array_equal(jac[:, :nv, nv:], np.broadcast_to(np.eye(nv), (6, nv, nv)))
    assert np.allclose(jac[:, nv:], want[:, :, 1:], rtol=1e-13, atol=1e-13 * np.abs(want).max())
    one = kernels.closed_loop_jac(kp[3], kd[3], qf[3])(0.0, np.concatenate((x[3], v[3])))
    assert np.array_equal(one, jac[3])


def test_bad_inputs_are_refused_naming_them(compiled):
    model, kernels = compiled["double_pendulum_continuous"]
    x, v, tau = states(model.nv, n=10)
    bad = v.copy()
    bad[7, 1] = np.nan
    with pytest.raises(InputError, match=r"qd\[7, 1\]=nan"):
        kernels.derivatives(x, bad, tau)
    with pytest.raises(InputError, match=r"q.shape=\(10, 3\).*nv=2"):
        kernels.derivatives(np.zeros((10, 3)), v, tau)
    huge = v.copy()
    huge[3] = 1e200  # finite, but its squares are not
    with pytest.raises(InputError, match=r"Jacobian of double_pendulum_continuous is not finite"):
        kernels.derivatives(x, huge, tau)
    with pytest.raises(InputError, match=r"kp has shape"):
        kernels.closed_loop_jac(np.ones(3), np.ones(2), np.zeros(2))
    with pytest.raises(InputError, match="variant"):
        kernels.derivatives(x, v, tau, variant="lu")
    with pytest.raises(InputError, match="wrt="):
        fds.forward_derivatives_source(model, wrt=("q", "a"))
    with pytest.raises(InputError, match="kind="):
        kernels.source("hessian")
    assert "def kernel(Q, V, KP, KD, QF, out):" in module_source(
        kernels.source("closed_loop_derivatives")
    )


def test_in_40_digit_arithmetic_the_generated_jacobian_is_the_more_accurate():
    """At a state where ∂q̈/∂q̇ nearly cancels (the double pendulum's second joint near 0),
    the generated code run in 40 digits is the reference: the compiled float result follows
    it to 1e-15 of the block's largest entry, where ``computeABADerivatives`` is ~2e-11 off."""
    model = robots.get("double_pendulum").model
    x = np.array([[1.0192025255474686, -7.830346801185328e-06]])
    v = np.array([[-2.633705685715412, -1.1279595452285072]])
    tau = np.array([[-13.357977512060302, 0.024275570254317112]])
    gen = fds.forward_derivatives_source(model)
    with mpmath.workdps(40):
        namespace = {"sin": mpmath.sin, "cos": mpmath.cos}
        exec(gen.function(), namespace)  # noqa: S102 - the generator's own code
        exact = np.empty(gen.shape, dtype=object)
        big = [[mpmath.mpf(float(a)) for a in row[0]] for row in (x, v, tau)]
        namespace[gen.name](*big, exact)
        exact = exact.astype(float)
    _, dq, dv = derivative_kernel_for(model, "double_pendulum").derivatives(x, v, tau)
    for got, want in ((dq[0], exact[:, 1:3]), (dv[0], exact[:, 3:])):
        assert np.abs(got - want).max() <= 1e-15 * np.abs(want).max()
    data = model.createData()
    _, pin_dv, _ = pin.computeABADerivatives(model, data, x[0], v[0], tau[0])
    assert np.abs(pin_dv - exact[:, 3:]).max() > 1e-12 * np.abs(exact[:, 3:]).max()
