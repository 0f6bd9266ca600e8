"""Direct dynamics: the seed's run against a two-method reference, every method, failures."""

import sys

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.errors import DivergenceError, InputError, RrtPinError
from rrt_pin.robot.model import load_urdf_model, rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import SimulationResult, simulate
from rrt_pin.simulate.closed_loop import ClosedLoop
from rrt_pin.simulate.control import as_controller, pd_gravity_controller, seed_controller
from rrt_pin.simulate.methods import names
from rrt_pin.simulate.reference import reference_run, seed_reference
from tests.support import TIGHT, random_states, robot_urdf

ADAPTIVE_METHODS = names(adaptive=True)


def _ClosedLoop(model, controller):
    return ClosedLoop(Robot.from_model(model), as_controller(controller, model.nv))


CHECK_TIMES = (1.0, 2.0, 5.0, 7.5, 10.0, 15.0)  # [s]
MATCH = 1e-7  # |q − reference| at CHECK_TIMES [rad, m]
DEFAULT_ACCURACY = 1e-8  # max |q − reference| of the defaults over the run [rad, m]
CONVERGED = 1e-3  # |q(15 s) − qf| [rad, m]
#: Largest max |q error| of each method at its defaults on the seed's run (dt 0.01 s
#: for the fixed-step ones: 1st, 4th and 2nd order).
METHOD_ACCURACY = {
    **dict.fromkeys(ADAPTIVE_METHODS, DEFAULT_ACCURACY),
    "symplectic_euler": 1e-2,
    "rk4": 1e-8,
    "verlet": 1e-4,
    "leapfrog": 1e-4,
}


@pytest.fixture(scope="module")
def reference():
    ref = seed_reference(cache=False)
    assert ref.t.size == 1501 and ref.t[0] == 0.0 and ref.t[-1] == 15.0
    return ref


@pytest.fixture(scope="module")
def seed_run(seed_model, seed_params, reference):
    return simulate(
        chapter_arm(seed_params),
        seed_controller(seed_params),
        seed_params.q0,
        seed_params.qd0,
        reference.t,
    )


def test_reference_methods_agree(reference):
    assert reference.methods == ("DOP853", "Radau")
    assert reference.difference_q < 1e-11
    assert reference.difference_qd < 1e-10


def test_seed_run_converges_to_qf(seed_run, seed_params):
    assert np.all(np.abs(seed_run.q[-1] - np.array(seed_params.qf)) < CONVERGED)


def test_seed_run_matches_the_reference(seed_run, reference):
    for t in CHECK_TIMES:
        i = int(np.argmin(np.abs(reference.t - t)))
        assert reference.t[i] == pytest.approx(t, abs=1e-12)
        np.testing.assert_allclose(seed_run.q[i], reference.q[i], rtol=0, atol=MATCH)
    assert np.abs(seed_run.q - reference.q).max() <= DEFAULT_ACCURACY
    assert np.abs(seed_run.qd - reference.qd).max() <= 10 * DEFAULT_ACCURACY


def test_result_contract(seed_run, seed_params, reference):
    r = seed_run
    assert isinstance(r, SimulationResult)
    assert r.method == "odepack" and r.backend == "pinocchio"
    from rrt_pin.simulate.methods import tolerances

    assert (r.rtol, r.atol, r.step) == (*tolerances("pinocchio", "odepack"), None)  # calibrated
    assert r.q.shape == r.qd.shape == r.tau.shape == (1501, 3)
    np.testing.assert_array_equal(r.t, reference.t)
    np.testing.assert_array_equal(r.q[0], seed_params.q0)
    assert r.n_evals > 0 and r.wall_time > 0
    assert r.header == ("t", "q1", "q2", "q3", "qd1", "qd2", "qd3", "T01x", "T12y", "F23z")
    assert r.table().shape == (1501, 10)
    with pytest.raises(ValueError):
        r.q[0, 0] = 1.0  # read-only


def test_efforts_are_the_laws_output_at_each_sample(seed_run, seed_params):
    c = seed_controller(seed_params)
    for i in (0, 100, 1500):
        np.testing.assert_allclose(seed_run.tau[i], c(seed_run.q[i], seed_run.qd[i]), rtol=TIGHT)


def test_aba_equals_crba_rnea(seed_model, rng):
    """Forward dynamics: ABA = M⁻¹·(τ − b), M from CRBA, b = RNEA(q, q̇, 0)."""
    data = seed_model.createData()
    q, qd, _ = random_states(rng, 100)
    taus = rng.normal(0, 100, (100, 3))
    for a, b, tau in zip(q, qd, taus, strict=True):
        M = pin.crba(seed_model, data, a)
        M = np.triu(M) + np.triu(M, 1).T
        bias = pin.rnea(seed_model, data, a, b, np.zeros(3))
        expected = np.linalg.solve(M, tau - bias)
        got = pin.aba(seed_model, data, a, b, tau)
        np.testing.assert_allclose(got, expected, rtol=0, atol=TIGHT * np.abs(expected).max())


def test_gravity_folding_is_exact(seed_model, seed_params, rng):
    """ABA(q, q̇, τ_PD + G) equals ABA without gravity on τ_PD: the fast path's identity."""
    c = seed_controller(seed_params)
    loop = _ClosedLoop(seed_model, c)
    assert loop.folded
    data = seed_model.createData()
    q, qd, _ = random_states(rng, 100)
    acc = loop.acceleration()
    for a, b in zip(q, qd, strict=True):
        expected = pin.aba(seed_model, data, a, b, c.efforts(0.0, a, b))
        np.testing.assert_allclose(
            acc(0.0, a, b), expected, rtol=0, atol=TIGHT * np.abs(expected).max()
        )


def test_plain_callable_controller_takes_the_general_path(seed_model, seed_params, seed_run):
    c = seed_controller(seed_params)
    plain = lambda q, qd: c.efforts(0.0, q, qd)  # noqa: E731  (no feedback(): no folding)
    assert not _ClosedLoop(seed_model, plain).folded
    r = simulate(chapter_arm(seed_params), plain, seed_params.q0, seed_params.qd0, seed_run.t)
    np.testing.assert_allclose(r.q, seed_run.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(r.tau, seed_run.tau, rtol=0, atol=1e-6)


def test_mismatched_law_is_not_folded(seed_params, reference):
    """The law's masses differ from the model's: gravity is not cancelled exactly."""
    model = rrt_model(seed_params.with_overrides({"m3": 45.0}))
    c = seed_controller(seed_params)
    assert not _ClosedLoop(model, c).folded
    r = simulate(Robot.from_model(model), c, seed_params.q0, seed_params.qd0, reference.t)
    ref = reference_run(model, c, seed_params.q0, seed_params.qd0, reference.t, methods=("DOP853",))
    assert np.abs(r.q - ref.q).max() <= DEFAULT_ACCURACY


def test_pd_gravity_controller_matches_the_seed_run(seed_model, seed_params, seed_run):
    c = pd_gravity_controller(
        chapter_arm(seed_params), seed_params.kp, seed_params.kd, seed_params.qf
    )
    r = simulate(chapter_arm(seed_params), c, seed_params.q0, seed_params.qd0, seed_run.t)
    np.testing.assert_allclose(r.q, seed_run.q, rtol=0, atol=1e-12)


@pytest.mark.parametrize("method", names("pinocchio"))  # the arm on the engine of record
def test_each_method_runs_and_converges(method, seed_model, seed_params, reference):
    r = simulate(
        chapter_arm(seed_params),
        seed_controller(seed_params),
        seed_params.q0,
        seed_params.qd0,
        reference.t,
        method=method,
    )
    assert r.method == method
    assert np.all(np.abs(r.q[-1] - np.array(seed_params.qf)) < CONVERGED)
    assert np.abs(r.q - reference.q).max() <= METHOD_ACCURACY[method]
    if method in ADAPTIVE_METHODS:
        from rrt_pin.simulate.methods import tolerances

        assert r.rtol == tolerances("pinocchio", method)[0] and r.step is None
    else:
        assert r.rtol is None and r.step == pytest.approx(0.01)


@pytest.mark.parametrize(
    "method, order", [("symplectic_euler", 1), ("rk4", 4), ("verlet", 2), ("leapfrog", 2)]
)
def test_fixed_step_methods_have_their_order(method, order, seed_model, seed_params):
    t = np.linspace(0.0, 1.0, 11)
    c = seed_controller(seed_params)
    ref = reference_run(seed_model, c, seed_params.q0, seed_params.qd0, t, methods=("DOP853",)).q
    errors = [
        np.abs(
            simulate(
                chapter_arm(seed_params),
                c,
                seed_params.q0,
                seed_params.qd0,
                t,
                method=method,
                step=h,
            ).q
            - ref
        ).max()
        for h in (0.02, 0.01)
    ]
    assert errors[0] / errors[1] == pytest.approx(2.0**order, rel=0.25)


@pytest.mark.parametrize("folded", [True, False])
def test_analytic_jacobian_matches_finite_differences(folded, seed_model, seed_params, rng):
    c = seed_controller(seed_params)

    class Plain:
        """The same law without feedback(): the general path, with its own Jacobian."""

        nv = 3

        def efforts(self, t, q, qd):
            return c.efforts(t, q, qd)

        def jacobian(self, t, q, qd):
            return c.jacobian(t, q, qd)

    controller = c if folded else Plain()
    loop = _ClosedLoop(seed_model, controller)
    assert loop.folded is folded
    acc = loop.acceleration()
    q, qd, _ = random_states(rng, 5)
    h = 1e-6
    for a, b in zip(q, qd, strict=True):
        J = loop.jacobian(0.0, a, b)
        y = np.concatenate((a, b))
        f = lambda y: np.concatenate((y[3:], acc(0.0, y[:3], y[3:])))  # noqa: E731
        for k in range(6):
            e = np.eye(6)[k] * h
            fd = (f(y + e) - f(y - e)) / (2 * h)
            np.testing.assert_allclose(J[:, k], fd, rtol=1e-6, atol=1e-5)


def test_any_urdf_with_pd_gravity_converges():
    model = load_urdf_model(robot_urdf("ur5"))
    qf = np.array([0.5, -1.0, 1.0, 0.0, 0.3, 0.0])
    c = pd_gravity_controller(Robot.from_model(model), 100.0, 20.0, qf)
    t = np.linspace(0.0, 5.0, 51)
    r = simulate(Robot.from_model(model), c, np.zeros(6), np.zeros(6), t, effort_limits=False)
    assert np.abs(r.q[-1] - qf).max() < 1e-4
    assert r.q_names[0] == "q_shoulder_pan_joint" and r.qd_names[0] == "qd_shoulder_pan_joint"
    assert r.tau_names[-1] == "tau_wrist_3_joint"
    ref = reference_run(model, c, np.zeros(6), np.zeros(6), t, methods=("DOP853",))
    assert np.abs(r.q - ref.q).max() <= DEFAULT_ACCURACY


def test_names_of_the_rrt_arm(seed_model):
    robot = Robot.from_model(seed_model)
    assert (robot.q_names, robot.qd_names) == (("q1", "q2", "q3"), ("qd1", "qd2", "qd3"))
    assert robot.effort_names == ("T01x", "T12y", "F23z")


# --- bad input -------------------------------------------------------------------------
@pytest.fixture
def args(seed_params):
    return {
        "model": chapter_arm(seed_params),
        "controller": seed_controller(seed_params),
        "q0": list(seed_params.q0),
        "qd0": [0.0, 0.0, 0.0],
        "t_eval": np.linspace(0.0, 1.0, 11),
    }


@pytest.mark.parametrize(
    "change, words",
    [
        ({"q0": [0.1, float("nan"), 0.2]}, "q0[1]=nan must be finite"),
        ({"qd0": [0.0, 0.0, float("inf")]}, "qd0[2]=inf must be finite"),
        ({"q0": [0.1, 0.2]}, "q0 has shape (2,) but needs (3,)"),
        ({"t_eval": [0.0, 1.0, 1.0]}, "t_eval must increase"),
        ({"t_eval": [0.0, float("nan")]}, "t_eval[1]=nan must be finite"),
        ({"t_eval": [0.0]}, "at least 2 times"),
        ({"method": "Euler"}, "method='Euler' is not one of odepack, RK45"),
        ({"rtol": -1e-6}, "rtol=-1e-06 must be > 0"),
        ({"rtol": True}, "rtol=True must be a real number"),
        ({"rtol": 1e300}, "rtol=1e+300 must be < 1"),
        ({"atol": float("nan")}, "atol=nan must be finite"),
        ({"method": "rk4", "step": 0.0}, "step=0.0 must be > 0"),
        ({"method": "odepack", "backend": "compiled"}, "method='odepack' does not run on"),
        ({"backend": "gpu"}, "backend='gpu' is not one of pinocchio, compiled"),
        ({"jacobian": "exact"}, "jacobian='exact' is not one of"),
        ({"controller": 3.0}, "controller must be a Controller"),
        ({"model": "arm.urdf"}, "model must be a pinocchio.Model"),
    ],
)
def test_bad_input_is_refused(args, change, words):
    with pytest.raises(InputError) as info:
        simulate(**{**args, **change})
    assert words in str(info.value)
    assert "\n" not in str(info.value)


def test_unsupported_joints_are_refused():
    model = pin.Model()
    model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    with pytest.raises(RrtPinError, match="joint 'ball'"):
        simulate(
            Robot.from_model(model), lambda q, v: np.zeros(3), [1, 0, 0, 0], [0, 0, 0], [0.0, 1.0]
        )


# --- divergence ------------------------------------------------------------------------
def _inf_past(c, q1):
    """A controller that returns an infinite T01x once q1 > q1 [rad]."""

    def law(q, qd):
        tau = c(q, qd)
        if q[0] > q1:
            tau[0] = np.inf
        return tau

    return law


@pytest.mark.parametrize("method", names("pinocchio"))  # the arm on the engine of record
def test_a_non_finite_effort_is_reported_with_time_and_coordinate(
    method, seed_model, seed_params, reference
):
    crossing = reference.t[np.argmax(reference.q[:, 0] > 0.5)]  # q1 passes 0.5 rad here
    law = _inf_past(seed_controller(seed_params), 0.5)
    with pytest.raises(DivergenceError) as info:
        simulate(
            chapter_arm(seed_params),
            law,
            seed_params.q0,
            seed_params.qd0,
            reference.t,
            method=method,
        )
    e = info.value
    assert e.coordinate == "qd1"
    assert abs(e.t - crossing) < 0.02
    assert f"simulation diverged at t={e.t:.6g} s in qd1" in str(e)


@pytest.mark.parametrize("method", ["symplectic_euler", "rk4", "verlet"])
def test_an_unstable_explicit_step_is_reported(method):
    """A 1 g slider on a 1e7 N/m spring, undamped: ω·dt = 1000, far past stability."""
    p = Params(m3=1e-3, gamma23=1e7, beta23=0.0)
    with pytest.raises(DivergenceError) as info:
        simulate(
            chapter_arm(p), seed_controller(p), p.q0, p.qd0, np.linspace(0, 1, 101), method=method
        )
    assert info.value.coordinate == "qd3"
    assert 0.0 < info.value.t <= 1.0


def test_step_size_underflow_is_reported(seed_model, seed_params):
    """A noisy law that no error test accepts: RK45's step shrinks below the spacing of t."""
    c = seed_controller(seed_params)
    rng = np.random.default_rng(0)

    def noisy(q, qd):
        tau = c(q, qd)
        if q[0] > 0.3:
            tau[2] += 1e12 * rng.normal()
        return tau

    with pytest.raises(DivergenceError) as info:
        simulate(
            chapter_arm(seed_params),
            noisy,
            seed_params.q0,
            seed_params.qd0,
            np.linspace(0, 2, 21),
            method="RK45",
        )
    assert "spacing between numbers" in str(info.value)
    assert info.value.coordinate in ("q3", "qd3")
    assert 0.3 < info.value.t < 2.0


def test_a_law_that_returns_nan_at_an_output_time_is_caught(seed_model, seed_params):
    """Even if the integration succeeds, non-finite efforts never come back quietly."""
    from rrt_pin.simulate.control import Controller

    class Flaky(Controller):
        nv = 3

        def __init__(self):
            self.c = seed_controller(seed_params)

        def efforts(self, t, q, qd):
            return self.c.efforts(t, q, qd)

        def efforts_many(self, t, q, qd):
            tau = self.c.efforts_many(t, q, qd)
            tau[7, 2] = np.nan
            return tau

    with pytest.raises(DivergenceError, match="in F23z: the controller returned nan"):
        simulate(
            chapter_arm(seed_params),
            Flaky(),
            seed_params.q0,
            seed_params.qd0,
            np.linspace(0, 1, 11),
        )


# --- compiled backend dispatch ---------------------------------------------------------
def test_compiled_backend_is_dispatched_lazily(monkeypatch, seed_model, seed_params, seed_run):
    from rrt_pin.core import backends

    calls, checked = [], []

    def run_one(params, controller, q0, qd0, t, options, max_steps=None, start=None):
        o = options
        calls.append(
            (params, o.method.name, o.rtol, o.atol, o.step, checked.pop() if checked else None)
        )
        return seed_run

    def check_model(model, params):  # the model given is checked against the params used
        checked.append(model)

    from rrt_pin.compiled import integrate, runs

    monkeypatch.setattr(integrate, "run_one", run_one)  # the arm's kernel, reached through
    monkeypatch.setattr(integrate, "check_model", check_model)  # the backend's runs
    monkeypatch.setattr(runs, "prepare", lambda *args: None)  # nothing loaded
    c = seed_controller(seed_params)
    r = simulate(
        chapter_arm(seed_params), c, seed_params.q0, seed_params.qd0, seed_run.t, backend="compiled"
    )
    np.testing.assert_array_equal(r.q, seed_run.q)
    # the backend's default method and the registry's default tolerances, named in the
    # result, then the error estimate's run at tolerances ten times tighter
    # a Robot that carries its Params is not checked again
    from rrt_pin.simulate.methods import tolerances

    assert calls[0] == (seed_params, "DOP853", *tolerances("compiled", "DOP853"), None, None)
    assert calls[1][:2] == (seed_params, "DOP853") and len(calls) == 2
    assert calls[1][2:4] == pytest.approx((1e-11, 1e-13), rel=1e-12)
    assert r.error_estimate == 0.0  # the fake returned the same run twice
    with pytest.warns(DeprecationWarning, match="pinocchio.Model is deprecated"):
        simulate(seed_model, c, seed_params.q0, seed_params.qd0, seed_run.t, method="rk4",
                 backend="compiled", step=0.1)  # fmt: skip
    # a bare model (deprecated) is checked against the law's Params before each run
    assert calls[-2:] == [(seed_params, "rk4", None, None, 0.1, seed_model),
                          (seed_params, "rk4", None, None, 0.05, None)]  # fmt: skip
    monkeypatch.setattr(backends.Backend, "available", lambda self: False)
    monkeypatch.undo()
    monkeypatch.setattr(backends.Backend, "available", lambda self: self.name != "compiled")
    from rrt_pin.core.extras import MissingExtra

    with pytest.raises(MissingExtra, match=r"numba not found .*\[fast\]"):
        simulate(chapter_arm(seed_params), c, seed_params.q0, seed_params.qd0, seed_run.t,
                 backend="compiled")  # fmt: skip


def test_compiled_backend_refuses_a_law_it_cannot_run(seed_model, seed_params):
    """The arm's model without its Params is any robot: its generated code runs built-in laws."""
    c = seed_controller(seed_params)
    with pytest.raises(InputError, match="not function; use backend 'pinocchio'"):
        simulate(
            Robot.from_model(seed_model),
            lambda q, v: c(q, v),
            seed_params.q0,
            seed_params.qd0,
            [0.0, 1.0],
            backend="compiled",
        )


def test_rrt_pin_simulate_is_callable_even_after_the_package_was_imported():
    """``rrt_pin.simulate`` is the package and calls ``simulate()``, however it was imported."""
    import subprocess

    code = (
        "import rrt_pin.simulate.results, rrt_pin; p = rrt_pin.Params(); "
        "r = rrt_pin.simulate(rrt_pin.rrt_model(p), rrt_pin.seed_controller(p), p.q0, p.qd0, "
        "[0.0, 0.1]); print(r.q.shape, r.method)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "(2, 3) odepack"


def test_seed_reference_cache_round_trip(tmp_path, seed_params):
    first = seed_reference(tf=1.0, dt=0.1, cache_dir=tmp_path)
    files = list(tmp_path.iterdir())
    assert len(files) == 1 and files[0].suffix == ".npz"
    again = seed_reference(tf=1.0, dt=0.1, cache_dir=tmp_path)
    np.testing.assert_array_equal(again.q, first.q)
    np.testing.assert_array_equal(again.qd, first.qd)
    assert again.difference_q == first.difference_q
    other = seed_reference(
        seed_params.with_overrides({"m3": 41.0}), tf=1.0, dt=0.1, cache_dir=tmp_path
    )
    assert len(list(tmp_path.iterdir())) == 2 and not np.array_equal(other.q, first.q)
    files[0].write_bytes(b"not an npz")  # a broken cache is recomputed, not an error
    np.testing.assert_array_equal(seed_reference(tf=1.0, dt=0.1, cache_dir=tmp_path).q, first.q)
