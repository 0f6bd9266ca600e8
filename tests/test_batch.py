"""Batches: N variants as one vectorized state with pin.abaInParallel equal N single runs."""

import numpy as np
import pinocchio as pin
import pytest
from scipy.integrate import solve_ivp

from rrt_pin.core.errors import DivergenceError, InputError
from rrt_pin.dynamics.inverse import default_num_threads
from rrt_pin.robot.model import rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import BatchResult, simulate, simulate_batch
from rrt_pin.simulate.control import (
    ChapterController,
    SeedController,
    chapter_controller,
    pd_gravity_controller,
    seed_controller,
)

T = np.linspace(0.0, 15.0, 301)  # [s]
ACCURACY = 1e-8  # max |q error| of the batch defaults against tight single references
B = 5


def tight_reference(model, controller, q0, qd0, t):
    """A single run at rtol 1e-13 (scipy DOP853 on pin.aba; nothing from rrt_pin.simulate)."""
    data = model.createData()

    def f(_t, y):
        q, v = y[:3], y[3:]
        return np.concatenate((v, pin.aba(model, data, q, v, controller(q, v))))

    sol = solve_ivp(f, (t[0], t[-1]), np.r_[q0, qd0], "DOP853", t_eval=t, rtol=1e-13, atol=1e-15)
    assert sol.status == 0
    return sol.y[:3].T


@pytest.fixture(scope="module")
def variants():
    """B seed variants: other gains, targets and initial states."""
    p = Params()
    rng = np.random.default_rng(11)
    controllers = [
        SeedController(
            kp=tuple(np.array(p.kp) * rng.uniform(0.5, 2.0, 3)),
            kd=tuple(np.array(p.kd) * rng.uniform(0.5, 2.0, 3)),
            qf=tuple(np.array(p.qf) + rng.uniform(-0.2, 0.2, 3)),
            params=p,
        )
        for _ in range(B)
    ]
    q0s = np.array(p.q0) + rng.uniform(-0.2, 0.2, (B, 3))
    qd0s = rng.uniform(-0.1, 0.1, (B, 3))
    return rrt_model(p), controllers, q0s, qd0s


@pytest.fixture(scope="module")
def batch(variants):
    model, controllers, q0s, qd0s = variants
    return simulate_batch(Robot.from_model(model), controllers, q0s, qd0s, T)


def test_batch_result_contract(batch, variants):
    _, controllers, q0s, qd0s = variants
    assert isinstance(batch, BatchResult) and len(batch) == B
    assert batch.q.shape == batch.qd.shape == batch.tau.shape == (B, T.size, 3)
    from rrt_pin.simulate.methods import tolerances

    assert batch.method == "odepack"
    assert (batch.rtol, batch.atol) == tolerances("pinocchio", "odepack")  # calibrated
    np.testing.assert_array_equal(batch.q[:, 0], q0s)
    np.testing.assert_array_equal(batch.qd[:, 0], qd0s)
    assert batch.n_evals > 0 and batch.wall_time > 0 and 1 <= batch.threads <= default_num_threads()
    one = batch.variant(2)
    assert one.header[:4] == ("t", "q1", "q2", "q3")
    np.testing.assert_array_equal(one.q, batch.q[2])


def test_batch_matches_tight_single_references(batch, variants):
    model, controllers, q0s, qd0s = variants
    for i in range(B):
        ref = tight_reference(model, controllers[i], q0s[i], qd0s[i], T)
        assert np.abs(batch.q[i] - ref).max() <= ACCURACY, i


def test_batch_equals_single_runs(batch, variants):
    model, controllers, q0s, qd0s = variants
    for i in range(B):
        single = simulate(Robot.from_model(model), controllers[i], q0s[i], qd0s[i], T)
        np.testing.assert_allclose(batch.q[i], single.q, rtol=0, atol=2 * ACCURACY)
        np.testing.assert_allclose(batch.qd[i], single.qd, rtol=0, atol=20 * ACCURACY)


def test_batch_efforts_are_each_laws_output(batch, variants):
    _, controllers, _, _ = variants
    for i in range(B):
        expected = controllers[i].efforts(batch.q[i], batch.qd[i])
        np.testing.assert_allclose(batch.tau[i], expected, rtol=1e-13, atol=1e-10)


@pytest.mark.parametrize("method", ["rk4", "verlet", "symplectic_euler"])
def test_fixed_step_batch_equals_single_runs_step_for_step(method, variants):
    model, controllers, q0s, qd0s = variants
    t = np.linspace(0.0, 2.0, 101)
    batch = simulate_batch(Robot.from_model(model), controllers, q0s, qd0s, t, method=method)
    assert batch.step == pytest.approx(0.02)
    for i in range(B):
        single = simulate(
            Robot.from_model(model), controllers[i], q0s[i], qd0s[i], t, method=method
        )
        np.testing.assert_allclose(batch.q[i], single.q, rtol=0, atol=1e-12)
        np.testing.assert_allclose(batch.qd[i], single.qd, rtol=0, atol=1e-11)


@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_scipy_methods_on_a_batch(method, variants):
    model, controllers, q0s, qd0s = variants
    t = np.linspace(0.0, 2.0, 21)
    batch = simulate_batch(
        Robot.from_model(model), controllers[:2], q0s[:2], qd0s[:2], t, method=method, rtol=1e-10
    )
    for i in range(2):
        ref = tight_reference(model, controllers[i], q0s[i], qd0s[i], t)
        assert np.abs(batch.q[i] - ref).max() <= ACCURACY


def test_two_threads_give_the_same_numbers(variants):
    model, controllers, q0s, qd0s = variants
    t = np.linspace(0.0, 1.0, 11)
    one = simulate_batch(Robot.from_model(model), controllers, q0s, qd0s, t, threads=1)
    two = simulate_batch(Robot.from_model(model), controllers, q0s, qd0s, t, threads=2)
    np.testing.assert_array_equal(one.q, two.q)


def test_pd_gravity_batch_on_a_mismatched_law_and_one_controller_for_all(variants):
    """PD + gravity variants (folded), and a seed law whose m3 differs from the model's."""
    model, controllers, q0s, qd0s = variants
    t = np.linspace(0.0, 3.0, 31)
    pdg = [pd_gravity_controller(Robot.from_model(model), c.kp, c.kd, c.qf) for c in controllers]
    batch = simulate_batch(Robot.from_model(model), pdg, q0s, qd0s, t)
    for i in (0, B - 1):
        ref = tight_reference(model, pdg[i], q0s[i], qd0s[i], t)
        assert np.abs(batch.q[i] - ref).max() <= ACCURACY
    wrong = seed_controller(Params(m3=44.0))  # compensates a heavier slider than the model's
    batch = simulate_batch(Robot.from_model(model), wrong, q0s, qd0s, t)
    for i in (0, B - 1):
        ref = tight_reference(model, wrong, q0s[i], qd0s[i], t)
        assert np.abs(batch.q[i] - ref).max() <= ACCURACY
    np.testing.assert_allclose(batch.tau[1], wrong.efforts(batch.q[1], batch.qd[1]), rtol=1e-13)


def test_efforts_can_be_skipped(variants):
    model, controllers, q0s, qd0s = variants
    r = simulate_batch(Robot.from_model(model), controllers, q0s, qd0s, [0.0, 0.1], efforts=False)
    assert r.tau is None
    with pytest.raises(InputError, match="efforts=False"):
        r.variant(0)


# --- bad input and failure -------------------------------------------------------------
@pytest.mark.parametrize(
    "change, words",
    [
        ({"q0s": np.zeros((B, 2))}, "q0s has shape (5, 2) but needs (B, 3)"),
        ({"q0s": np.full((B, 3), np.nan)}, "q0s[0, 0]=nan must be finite"),
        ({"qd0s": np.zeros((B + 1, 3))}, "q0s has 5 rows but qd0s has 6"),
        ({"method": "Radau"}, "method='Radau' does not run on backend 'pinocchio' in a batch"),
        ({"threads": 0}, "threads=0 must be an integer >= 1"),
        ({"t_eval": [1.0, 0.0]}, "t_eval must increase"),
    ],
)
def test_bad_input_is_refused(variants, change, words):
    model, controllers, q0s, qd0s = variants
    kwargs = {"q0s": q0s, "qd0s": qd0s, "t_eval": [0.0, 1.0], **change}
    with pytest.raises(InputError) as info:
        simulate_batch(Robot.from_model(model), controllers, **kwargs)
    assert words in str(info.value)


def test_controllers_of_any_kind_share_one_batch(variants):
    """Laws that do not share one gravity term run variant by variant, each as its single run."""
    model, controllers, q0s, qd0s = variants
    mixed = [*controllers[:-2], pd_gravity_controller(Robot.from_model(model), 1.0, 1.0, [0, 0, 0])]
    mixed.append(seed_controller(Params(m2=61.0)))  # eq. (31) of a heavier arm: not folded
    t = np.linspace(0.0, 1.0, 11)
    batch = simulate_batch(Robot.from_model(model), mixed, q0s, qd0s, t, rtol=1e-11, atol=1e-12)
    for i in (0, B - 2, B - 1):
        one = simulate(
            Robot.from_model(model), mixed[i], q0s[i], qd0s[i], t, rtol=1e-11, atol=1e-12
        )
        np.testing.assert_allclose(batch.q[i], one.q, rtol=0, atol=1e-8)
        np.testing.assert_allclose(batch.tau[i], one.tau, rtol=1e-8, atol=1e-6)


def test_a_diverging_variant_is_named():
    """Variant 2 has a 1e7 N/m slider spring: explicit Euler at 10 ms blows it up."""
    p = Params(m3=1e-3)
    model = rrt_model(p)
    base = seed_controller(p)
    stiff = SeedController(kp=(300.0, 300.0, 1e7), kd=(450.0, 200.0, 0.0), qf=p.qf, params=p)
    controllers = [base, base, stiff, base]
    q0s = np.tile(p.q0, (4, 1))
    with pytest.raises(DivergenceError) as info:
        simulate_batch(
            Robot.from_model(model),
            controllers,
            q0s,
            np.zeros((4, 3)),
            np.linspace(0, 1, 101),
            method="symplectic_euler",
        )
    assert info.value.coordinate == "qd3 (variant 2)"
    assert 0.0 < info.value.t <= 1.0


def test_default_threads_follow_the_free_cpus_during_the_run(monkeypatch):
    from rrt_pin.core import cpus
    from rrt_pin.simulate.closed_loop import Threads

    monkeypatch.setattr(cpus, "available", lambda: 2)
    busy = [0]
    monkeypatch.setattr(cpus, "busy", lambda: busy[0])
    clock = [0.0]
    monkeypatch.setattr("rrt_pin.simulate.closed_loop.time.monotonic", lambda: clock[0])
    adaptive = Threads(None, 1000)
    assert adaptive() == 2
    busy[0] = 1  # a job starts beside the run: seen at the next look, not before
    assert adaptive() == 2
    clock[0] += Threads.RECHECK
    assert adaptive() == 1 and adaptive.most == 2
    assert Threads(None, 40)() == 1  # 40 variants: not worth a second thread
    assert Threads(2, 1000)() == 2  # asked for: kept whatever the load


def test_a_batch_under_contention_runs_on_the_free_cpu_and_gives_the_same_states(monkeypatch):
    from rrt_pin.core import cpus

    arm = chapter_arm()
    d = arm.defaults
    law = chapter_controller(arm.params)
    laws = [ChapterController(kp=np.asarray(law.kp) * s, kd=law.kd, qf=law.qf, params=law.params)
            for s in np.linspace(0.8, 1.25, 64)]  # fmt: skip
    q0s, t = np.tile(d.q0, (64, 1)), np.linspace(0, 1, 11)
    monkeypatch.setattr(cpus, "available", lambda: 2)
    monkeypatch.setattr(cpus, "busy", lambda: 1)
    busy = simulate_batch(arm, laws, q0s, None, t, estimate_error=False)
    monkeypatch.setattr(cpus, "busy", lambda: 0)
    quiet = simulate_batch(arm, laws, q0s, None, t, estimate_error=False)
    assert (busy.threads, quiet.threads) == (1, 2)
    np.testing.assert_array_equal(busy.q, quiet.q)
