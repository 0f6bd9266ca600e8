"""The compiled integrators: exact solutions, SciPy's algorithms, references, orders, batches."""

from __future__ import annotations

import importlib.util
import math

import numpy as np
import pytest

from rrt_pin.core.errors import DivergenceError, InputError
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate.control import SeedController, pd_gravity_controller, seed_controller

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("numba") is None, reason="numba not installed (rrt-pin[fast])"
)

SEED_GRID = np.linspace(0.0, 15.0, 1501)
ADAPTIVE = ("DOP853", "RK45")
FIXED = ("symplectic_euler", "rk4", "verlet")


@pytest.fixture(scope="session")
def compiled():
    """The compiled backend, compiled (or loaded from the disk cache) once per session."""
    from rrt_pin import compiled as backend

    backend.ensure_compiled()
    return backend


@pytest.fixture(scope="session")
def reference():
    """The seed's run at rtol 1e-13 by SciPy + pin.aba (DOP853, cross-checked with Radau)."""
    from rrt_pin.simulate.reference import seed_reference

    ref = seed_reference()
    assert ref.difference_q < 1e-11
    np.testing.assert_array_equal(ref.t, SEED_GRID)
    return ref


def _scipy_run(params, controller, q0, qd0, t, method, rtol, atol):
    """solve_ivp on a plain pin.aba right-hand side (independent of rrt_pin.simulate)."""
    import pinocchio as pin
    from scipy.integrate import solve_ivp

    from rrt_pin.robot.model import rrt_model

    model = rrt_model(params)
    data = model.createData()

    def f(_t, y):
        q, v = y[:3], y[3:]
        return np.concatenate((v, pin.aba(model, data, q, v, controller(q, v))))

    y0 = np.concatenate((q0, qd0))
    return solve_ivp(f, (t[0], t[-1]), y0, method=method, t_eval=t, rtol=rtol, atol=atol)


# --- a problem with a known exact solution --------------------------------------------------
def _oscillator() -> tuple[Params, callable]:
    """Links 1 and 2 held at their targets, the slider a damped oscillator under eq. (31).

    With q1 = q1f, q2 = q2f at rest the Coriolis terms vanish and gravity is
    compensated exactly, so m3·q̈3 = −β23·q̇3 − γ23·(q3 − q3f).
    """
    p = Params(q10=math.pi / 3, q20=math.pi / 3, q30=0.25, q3f=0.3, gamma23=50.0, beta23=20.0)
    omega = math.sqrt(p.gamma23 / p.m3)
    zeta = p.beta23 / (2.0 * math.sqrt(p.m3 * p.gamma23))
    omega_d = omega * math.sqrt(1.0 - zeta**2)
    x0 = p.q30 - p.q3f

    def exact(t: np.ndarray) -> np.ndarray:
        decay = np.exp(-zeta * omega * t)
        return p.q3f + decay * x0 * (
            np.cos(omega_d * t) + zeta * omega / omega_d * np.sin(omega_d * t)
        )

    return p, exact


@pytest.mark.parametrize("method", ADAPTIVE)
def test_adaptive_methods_on_an_exact_solution(compiled, method):
    p, exact = _oscillator()
    t = np.linspace(0.0, 15.0, 301)
    res = compiled.simulate_compiled(
        p, seed_controller(p), p.q0, p.qd0, t, method=method, rtol=1e-10, atol=1e-12
    )
    assert np.abs(res.q[:, 2] - exact(t)).max() < 1e-9
    np.testing.assert_allclose(res.q[:, :2], np.tile(p.qf[:2], (t.size, 1)), atol=1e-12)
    # SciPy's own solve_ivp with the same method and tolerances takes the same steps.
    sol = _scipy_run(p, seed_controller(p), p.q0, p.qd0, t, method, 1e-10, 1e-12)
    assert res.n_evals == sol.nfev
    assert np.abs(res.q - sol.y[:3].T).max() < 1e-11
    assert np.abs(sol.y[2] - exact(t)).max() < 1e-9


# --- the seed's run -------------------------------------------------------------------------
@pytest.mark.parametrize(("method", "rtol"), [("DOP853", None), ("RK45", 1e-10)])
def test_seed_run_against_the_tight_reference(compiled, reference, seed_params, method, rtol):
    res = compiled.simulate_compiled(
        seed_params, seed_controller(seed_params), seed_params.q0, seed_params.qd0, SEED_GRID,
        method=method, rtol=rtol,
    )  # fmt: skip
    assert np.abs(res.q - reference.q).max() <= 1e-8
    assert np.abs(res.qd - reference.qd).max() <= 1e-7
    expected_tau = seed_controller(seed_params).efforts(res.q, res.qd)
    np.testing.assert_allclose(res.tau, expected_tau, rtol=1e-13, atol=1e-10)
    assert res.backend == "compiled" and res.method == method and res.wall_time > 0.0


@pytest.mark.parametrize("method", ADAPTIVE + FIXED)
def test_same_trajectories_as_the_pinocchio_backend(compiled, seed_params, seed_model, method):
    from rrt_pin.simulate import simulate

    ctrl = seed_controller(seed_params)
    args = (ctrl, seed_params.q0, seed_params.qd0, SEED_GRID)
    pin_run = simulate(chapter_arm(seed_params), *args, method=method)
    ours = simulate(chapter_arm(seed_params), *args, method=method, backend="compiled")
    assert ours.backend == "compiled"
    assert ours.n_evals == pin_run.n_evals
    tol = 1e-10 if method in ADAPTIVE else 1e-12
    assert np.abs(ours.q - pin_run.q).max() <= tol
    assert np.abs(ours.qd - pin_run.qd).max() <= 10 * tol
    np.testing.assert_allclose(ours.tau, pin_run.tau, rtol=1e-12, atol=1e-9)


def test_controller_built_for_another_arm(compiled, seed_params, seed_model):
    """Eq. (31) with wrong masses (model mismatch): the plant is not fully compensated."""
    from rrt_pin.simulate import simulate

    wrong = seed_controller(seed_params.with_overrides({"m2": 50.0, "m3": 45.0}))
    args = (wrong, seed_params.q0, seed_params.qd0, SEED_GRID)
    pin_run = simulate(chapter_arm(seed_params), *args, method="DOP853")
    ours = simulate(chapter_arm(seed_params), *args, method="DOP853", backend="compiled")
    assert ours.n_evals == pin_run.n_evals
    assert np.abs(ours.q - pin_run.q).max() <= 1e-10
    np.testing.assert_allclose(ours.tau, pin_run.tau, rtol=1e-12, atol=1e-9)
    exact = compiled.simulate_compiled(
        seed_params, seed_controller(seed_params), seed_params.q0, seed_params.qd0, SEED_GRID
    )
    assert np.abs(ours.q[-1] - exact.q[-1]).max() > 1e-4  # the mismatch shows


def test_pd_gravity_controller_equals_eq31_on_the_arm(compiled, seed_params, seed_model):
    seed = compiled.simulate_compiled(
        seed_params, seed_controller(seed_params), seed_params.q0, seed_params.qd0, SEED_GRID
    )
    pd = pd_gravity_controller(
        chapter_arm(seed_params), seed_params.kp, seed_params.kd, seed_params.qf
    )
    other = compiled.simulate_compiled(
        seed_params, pd, seed_params.q0, seed_params.qd0, SEED_GRID, model=seed_model
    )
    assert np.abs(other.q - seed.q).max() < 1e-11
    np.testing.assert_allclose(other.tau, seed.tau, rtol=1e-12, atol=1e-9)


# --- fixed steps ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("method", "order", "steps"),
    [
        ("symplectic_euler", 1, (0.005, 0.0025, 0.00125)),
        ("verlet", 2, (0.01, 0.005, 0.0025)),
        ("rk4", 4, (0.01, 0.005, 0.0025)),
    ],
)
def test_fixed_step_order(compiled, reference, seed_params, method, order, steps):
    errors = []
    for h in steps:
        res = compiled.simulate_compiled(
            seed_params, seed_controller(seed_params), seed_params.q0, seed_params.qd0,
            SEED_GRID, method=method, step=h,
        )  # fmt: skip
        assert res.step == h
        errors.append(np.abs(res.q - reference.q).max())
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert np.all(np.abs(rates - order) < 0.25), (errors, rates)


# --- dense output ---------------------------------------------------------------------------
def test_dense_output_at_arbitrary_times_matches_scipy(compiled, seed_params, rng):
    t = np.concatenate(([0.0], np.sort(rng.uniform(0.0, 15.0, 400)), [15.0]))
    ctrl = seed_controller(seed_params)
    res = compiled.simulate_compiled(
        seed_params, ctrl, seed_params.q0, seed_params.qd0, t, rtol=1e-10, atol=1e-12
    )
    sol = _scipy_run(seed_params, ctrl, seed_params.q0, seed_params.qd0, t, "DOP853", 1e-10, 1e-12)
    assert res.n_evals == sol.nfev
    assert np.abs(res.q - sol.y[:3].T).max() < 1e-11
    assert np.abs(res.qd - sol.y[3:].T).max() < 1e-10


@pytest.mark.parametrize("method", ADAPTIVE)
def test_output_times_do_not_change_the_steps(compiled, seed_params, method):
    ctrl = seed_controller(seed_params)
    fine = compiled.simulate_compiled(
        seed_params, ctrl, seed_params.q0, seed_params.qd0, SEED_GRID, method=method
    )
    coarse_t = SEED_GRID[::50]
    coarse = compiled.simulate_compiled(
        seed_params, ctrl, seed_params.q0, seed_params.qd0, coarse_t, method=method
    )
    np.testing.assert_array_equal(coarse.q, fine.q[::50])
    np.testing.assert_array_equal(coarse.tau, fine.tau[::50])
    assert coarse.n_evals <= fine.n_evals


# --- batches --------------------------------------------------------------------------------
def _variants(rng, count: int):
    base = Params()
    plants = [
        base.with_overrides({"m1": m1, "m2": m2, "m3": m3, "L2": l2})
        for m1, m2, m3, l2 in zip(
            rng.uniform(60, 120, count), rng.uniform(40, 80, count), rng.uniform(20, 60, count),
            rng.uniform(0.5, 0.9, count), strict=True,
        )
    ]  # fmt: skip
    controllers = [
        SeedController(
            kp=tuple(np.array(plant.kp) * rng.uniform(0.8, 1.25, 3)),
            kd=tuple(np.array(plant.kd) * rng.uniform(0.8, 1.25, 3)),
            qf=plant.qf,
            params=plant,
        )
        for plant in plants
    ]
    q0s = np.array(base.q0) + rng.uniform(-0.1, 0.1, (count, 3))
    qd0s = rng.normal(0.0, 0.1, (count, 3))
    return plants, controllers, q0s, qd0s


@pytest.mark.parametrize("method", ("DOP853", "rk4"))
def test_batch_equals_single_runs(compiled, rng, method):

    plants, controllers, q0s, qd0s = _variants(rng, 5)
    # One variant compensates gravity through the kernel (pd_gravity on its own arm).
    controllers[3] = pd_gravity_controller(
        chapter_arm(plants[3]), (200, 250, 40), (400, 200, 120), plants[3].qf
    )
    t = SEED_GRID[::10]
    batch = compiled.simulate_batch_compiled(plants, controllers, q0s, qd0s, t, method=method)
    assert batch.q.shape == (5, t.size, 3) and batch.tau.shape == (5, t.size, 3)
    total = 0
    for b in range(5):
        one = compiled.simulate_compiled(
            plants[b], controllers[b], q0s[b], qd0s[b], t, method=method
        )
        np.testing.assert_array_equal(batch.q[b], one.q)
        np.testing.assert_array_equal(batch.qd[b], one.qd)
        np.testing.assert_array_equal(batch.tau[b], one.tau)
        total += one.n_evals
    assert batch.n_evals == total
    # The variants differ: masses and gains matter.
    assert np.abs(batch.q[0] - batch.q[1]).max() > 1e-3


def test_batch_shares_one_params_and_controller(compiled, seed_params):
    q0s = np.array([seed_params.q0, seed_params.q0])
    qd0s = np.zeros((2, 3))
    batch = compiled.simulate_batch_compiled(
        seed_params, seed_controller(seed_params), q0s, qd0s, SEED_GRID[::100], efforts=False
    )
    assert batch.tau is None
    np.testing.assert_array_equal(batch.q[0], batch.q[1])


# --- failures are reported, never NaN -------------------------------------------------------
def test_nonfinite_state_is_reported_with_time_and_coordinate(compiled, seed_params):
    with pytest.raises(DivergenceError, match="non-finite") as info:
        compiled.simulate_compiled(
            seed_params, seed_controller(seed_params), seed_params.q0, (1e160, 0.0, 0.0),
            SEED_GRID,
        )  # fmt: skip
    # q̈2 holds the centrifugal q̇1²·sin q2·(…): inf; q̈1 = (τ1 − 2 q̇1 (q̇3 x15 − q̇2 x19)) / M11
    # stays finite with q̇2 = q̇3 = 0 (M is diagonal: no inf leaks into it through a solve).
    assert info.value.t == 0.0 and info.value.coordinate == "qd2"


def test_step_size_underflow_is_reported(compiled, seed_params):
    with pytest.raises(DivergenceError, match="step size fell below 10 ulp") as info:
        compiled.simulate_compiled(
            seed_params, seed_controller(seed_params), seed_params.q0, (1e120, 0.0, 0.0),
            SEED_GRID,
        )  # fmt: skip
    assert info.value.coordinate in ("q1", "q2", "q3", "qd1", "qd2", "qd3")
    assert 0.0 <= info.value.t <= 15.0


@pytest.mark.parametrize("method", FIXED)
def test_unstable_fixed_step_is_reported(compiled, method):
    stiff = Params(gamma23=1e6, beta23=0.0, m3=1.0)
    t = np.linspace(0.0, 100.0, 1001)
    with pytest.raises(DivergenceError) as info:
        compiled.simulate_compiled(
            stiff, seed_controller(stiff), stiff.q0, stiff.qd0, t, method=method
        )
    assert 0.0 < info.value.t <= 100.0
    assert info.value.coordinate in ("q1", "q2", "q3", "qd1", "qd2", "qd3")


def test_step_budget_is_reported(compiled, seed_params):
    with pytest.raises(DivergenceError, match="its budget of 10 steps"):
        compiled.simulate_compiled(
            seed_params, seed_controller(seed_params), seed_params.q0, seed_params.qd0,
            SEED_GRID, max_steps=10,
        )  # fmt: skip


def test_batch_names_the_failing_variant(compiled, seed_params):
    q0s = np.tile(seed_params.q0, (3, 1))
    qd0s = np.zeros((3, 3))
    qd0s[2, 0] = 1e160
    with pytest.raises(DivergenceError, match=r"qd2 \(variant 2\)"):  # q̈2 ∋ q̇1² = inf
        compiled.simulate_batch_compiled(
            seed_params, seed_controller(seed_params), q0s, qd0s, SEED_GRID[::100]
        )


# --- boundary -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"method": "odepack"}, "does not run on backend 'compiled'"),
        ({"t_eval": [0.0]}, "at least 2 times"),
        ({"t_eval": [0.0, 1.0, 1.0]}, "t_eval must increase"),
        ({"q0": (0.0, float("nan"), 0.0)}, r"q0\[1\]=nan must be finite"),
        ({"rtol": -1.0}, "rtol=-1.0 must be > 0"),
        ({"controller": lambda q, qd: q}, "not function"),
        ({"params": "seed"}, "params must be a Params"),
    ],
)
def test_bad_inputs_are_refused(compiled, seed_params, kwargs, match):
    args = {
        "params": seed_params,
        "controller": seed_controller(seed_params),
        "q0": seed_params.q0,
        "qd0": seed_params.qd0,
        "t_eval": SEED_GRID,
    }
    args.update(kwargs)
    with pytest.raises(InputError, match=match):
        compiled.simulate_compiled(**args)


def test_foreign_models_are_refused(compiled, seed_params):
    from rrt_pin.robot.model import rrt_model

    other = rrt_model(seed_params.with_overrides({"m3": 10.0}))
    pd = pd_gravity_controller(Robot.from_model(other), 1.0, 1.0, seed_params.qf)
    with pytest.raises(InputError, match="compensates the gravity of the RRT arm only"):
        compiled.simulate_compiled(seed_params, pd, seed_params.q0, seed_params.qd0, SEED_GRID)
    with pytest.raises(InputError, match="use backend 'pinocchio'"):
        compiled.simulate_compiled(
            seed_params, None, seed_params.q0, seed_params.qd0, SEED_GRID, model=other
        )


def test_rtol_below_the_floor_is_refused_and_at_it_honoured(compiled, seed_params):
    with pytest.raises(InputError, match="below DOP853's floor of 2.22e-14"):
        compiled.simulate_compiled(
            seed_params, None, seed_params.q0, seed_params.qd0, [0.0, 0.5], rtol=1e-17
        )
    floor = 100 * np.finfo(float).eps
    res = compiled.simulate_compiled(
        seed_params, None, seed_params.q0, seed_params.qd0, [0.0, 0.5], rtol=floor
    )
    assert res.rtol == floor and res.atol == pytest.approx(floor / 100)


def test_runs_start_at_the_first_output_time(compiled, seed_params):
    ctrl = seed_controller(seed_params)
    whole = compiled.simulate_compiled(
        seed_params, ctrl, seed_params.q0, seed_params.qd0, SEED_GRID
    )
    later = compiled.simulate_compiled(
        seed_params, ctrl, whole.q[500], whole.qd[500], SEED_GRID[500:], rtol=1e-12, atol=1e-14
    )
    assert later.t[0] == 5.0
    assert np.abs(later.q - whole.q[500:]).max() < 1e-8


def test_gains_other_than_the_plants_keep_the_folded_gravity(compiled, seed_params, seed_model):
    from rrt_pin.simulate import simulate

    retuned = seed_controller(seed_params.with_overrides({"gamma01": 500.0, "beta23": 90.0}))
    args = (retuned, seed_params.q0, seed_params.qd0, SEED_GRID)
    pin_run = simulate(chapter_arm(seed_params), *args, method="RK45")
    ours = simulate(chapter_arm(seed_params), *args, method="RK45", backend="compiled")
    assert ours.n_evals == pin_run.n_evals
    assert np.abs(ours.q - pin_run.q).max() <= 1e-12
    np.testing.assert_allclose(ours.tau, retuned.efforts(ours.q, ours.qd), rtol=1e-13, atol=1e-10)


def test_passive_motion_keeps_its_energy(compiled, seed_params):
    """τ = 0: T + V is conserved to the integration tolerance (gravity V from the seed's facts)."""
    t = np.linspace(0.0, 5.0, 51)
    res = compiled.simulate_compiled(
        seed_params, None, seed_params.q0, (0.5, 0.0, 0.0), t, rtol=1e-12, atol=1e-14
    )
    M = compiled.mass_matrix(res.q, seed_params)
    kinetic = 0.5 * np.einsum("ni,nij,nj->n", res.qd, M, res.qd)
    p = seed_params
    s2 = np.sin(res.q[:, 1])
    potential = p.g * (p.m2 * p.L2 * s2 + p.m3 * (p.L2 + res.q[:, 2]) * s2)
    energy = kinetic + potential
    assert np.ptp(energy) < 1e-8 * np.abs(energy).max()
    np.testing.assert_array_equal(res.tau, 0.0)


def test_samples_until_is_the_scan_it_replaces(compiled):
    # The dense output's binary search must give what the scan gave: the first
    # index >= start whose time is after t (len when none), on any increasing grid.
    from rrt_pin.compiled._jit_integrators import samples_until

    rng = np.random.default_rng(5)
    for size in (1, 2, 3, 8, 31, 1501):
        grid = np.cumsum(rng.uniform(0.001, 0.1, size))
        grid[size // 2 :] = np.round(grid[size // 2 :], 2)  # some ties with t below
        grid = np.unique(grid)
        for _ in range(40):
            start = int(rng.integers(0, grid.size + 1))
            t = float(rng.choice([*grid, *rng.uniform(grid[0] - 0.1, grid[-1] + 0.1, 3)]))
            end = start
            while end < grid.size and grid[end] <= t:
                end += 1
            assert samples_until(grid, start, t) == end, (size, start, t)
