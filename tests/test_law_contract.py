"""A user's law is held to its contract, and a run says what really happened.

Each bad law is refused in one line naming the law, what it returned and what
was expected (``ControllerError``, an ``InputError``), never reported as the
integrator's failure; runs that cannot be done are refused before any work.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from rrt_pin import time_grid
from rrt_pin.core.errors import ArgumentTypeError, ControllerError, DivergenceError, InputError
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import EstimateWarning, simulate, simulate_batch
from rrt_pin.simulate.control import Controller, regulator

T = np.linspace(0.0, 0.2, 11)


@pytest.fixture(scope="module")
def arm():
    return chapter_arm()


def _damping(t, q, qd):
    return -10.0 * qd


class _Law:
    """A law whose batch form is given; ``many`` replaces its result."""

    nv = 3

    def __init__(self, many):
        self.many = many

    def efforts(self, t, q, qd):
        return _damping(t, q, qd) + 1.0  # never zero: a zero batch result is caught

    def efforts_many(self, t, q, qd):
        return self.many(self, t, q, qd)


def _one_line(e: BaseException, *words: str) -> None:
    text = str(e)
    assert "\n" not in text and "np.float64" not in text, text
    for w in words:
        assert w in text, text


# --- efforts_many: checked as efforts is, and against it -------------------------------
def test_a_batch_form_of_the_wrong_shape_is_refused(arm):
    law = _Law(lambda self, t, q, qd: np.zeros(3))
    with pytest.raises(ControllerError) as info:
        simulate(arm, law, arm.defaults.q0, None, T, estimate_error=False)
    _one_line(info.value, "_Law", "shape (3,)", "efforts_many", "(11, 3)")
    assert info.value.law == "_Law"


@pytest.mark.parametrize("batch", [False, True])
def test_a_batch_form_that_is_not_the_law_applied_is_refused(arm, batch):
    law = _Law(lambda self, t, q, qd: np.zeros_like(q))
    with pytest.raises(ControllerError) as info:
        if batch:
            q0s = np.tile(arm.defaults.q0, (2, 1))
            simulate_batch(arm, law, q0s, None, T, estimate_error=False)
        else:
            simulate(arm, law, arm.defaults.q0, None, T, estimate_error=False)
    _one_line(info.value, "efforts_many", "the efforts recorded must be the efforts applied")


def test_a_batch_form_that_agrees_records_the_efforts_applied(arm):
    law = _Law(lambda self, t, q, qd: -10.0 * np.asarray(qd) + 1.0)
    run = simulate(arm, law, arm.defaults.q0, None, T, estimate_error=False)
    np.testing.assert_allclose(run.tau, -10.0 * run.qd + 1.0, rtol=0, atol=1e-12)
    assert run.tau.shape == (T.size, 3)


def test_a_batch_form_returning_nan_at_a_finite_state_names_time_and_effort(arm):
    def many(self, t, q, qd):
        tau = -10.0 * np.asarray(qd) + 1.0
        tau[4, 1] = np.nan
        return tau

    with pytest.raises(DivergenceError) as info:
        simulate(arm, _Law(many), arm.defaults.q0, None, T, estimate_error=False)
    assert info.value.coordinate == "T12y" and info.value.t == pytest.approx(T[4])


# --- complex and other non-real results (earlier defect) ---------------------------------
@pytest.mark.parametrize(
    "result, words",
    [
        (lambda t, q, qd: -qd + 1j, "complex numbers (0+1j)"),
        (lambda t, q, qd: ["1", "2", "3"], "returned text"),
        (lambda t, q, qd: None, "returned None"),
        (lambda t, q, qd: [1.0, 2.0], "returned shape (2,)"),
    ],
)
def test_a_law_returning_no_real_efforts_is_refused(arm, result, words):
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no ComplexWarning: refused, not cast
        with pytest.raises(ControllerError) as info:
            simulate(arm, result, arm.defaults.q0, None, T, estimate_error=False)
    _one_line(info.value, "<lambda>", words)


# --- Jacobians (earlier: reported as integrator failures) --------------------------------
class _WithJacobian:
    nv = 3

    def __init__(self, jac):
        self.jac = jac

    def efforts(self, t, q, qd):
        return -10.0 * qd

    def jacobian(self, t, q, qd):
        return self.jac


@pytest.mark.parametrize(
    "jac, words",
    [
        ((np.zeros((2, 2)), np.zeros((2, 2))), "dtau/dq of shape (2, 2)"),
        ((np.full((3, 3), np.nan), np.zeros((3, 3))), "dtau/dq[0, 0] = nan"),
        ((None, None), "returned (None, None)"),
        (np.zeros((3, 3)), "returned an array of float64"),
    ],
)
def test_a_bad_jacobian_is_the_laws_error_not_the_integrators(arm, jac, words):
    with pytest.raises(ControllerError) as info:
        simulate(arm, _WithJacobian(jac), arm.defaults.q0, None, T, method="Radau",
                 estimate_error=False)  # fmt: skip
    _one_line(info.value, "_WithJacobian", "jacobian(t, q, qd)", words, "(3, 3)")
    assert "stopped" not in str(info.value)


def test_an_error_of_the_law_inside_an_implicit_method_is_raised_as_it_is(arm):
    def broken(t, q, qd):
        if t > 0.05:
            raise ValueError("the law's own bug")
        return -qd

    with pytest.raises(ValueError, match="the law's own bug") as info:
        simulate(arm, broken, arm.defaults.q0, None, T, method="Radau", estimate_error=False)
    assert not isinstance(info.value, DivergenceError)


# --- a law that mutates its state --------------------------------------------------------
@pytest.mark.parametrize("method", ["odepack", "RK45", "rk4"])
def test_a_law_that_writes_into_q_is_refused_and_q0_is_untouched(arm, method):
    def mutating(t, q, qd):
        q[0] += 1.0
        return -qd

    q0 = np.array(arm.defaults.q0, dtype=float)
    before = q0.copy()
    with pytest.raises(ControllerError) as info:
        simulate(arm, mutating, q0, None, T, method=method, estimate_error=False)
    _one_line(info.value, "mutating", "writes into its arguments", "q.copy()")
    np.testing.assert_array_equal(q0, before)


def test_a_controller_subclass_is_checked_too(arm):
    class Complex(Controller):
        nv = 3

        def efforts(self, t, q, qd):
            return np.zeros(3, dtype=complex) + 2j

    with pytest.raises(ControllerError, match="Complex's efforts"):
        simulate(arm, Complex(), arm.defaults.q0, None, T, estimate_error=False)


# --- params= that would be ignored, model types (earlier defects) -----------------------
def deprecated_params() -> pytest.WarningsRecorder:
    """``params=`` beside a Robot is deprecated (the Robot carries them): still checked."""
    return pytest.warns(DeprecationWarning, match=r"params=\) is deprecated")


def test_params_as_a_dict_is_refused_as_a_type_error(arm):
    with deprecated_params(), pytest.raises(ArgumentTypeError) as info:
        simulate(arm, None, arm.defaults.q0, None, T, params={"L1": 1}, estimate_error=False)
    assert isinstance(info.value, TypeError) and isinstance(info.value, InputError)
    _one_line(info.value, "params must be a rrt_pin.Params", "dict")


def test_params_of_another_arm_are_refused_not_ignored(arm):
    with deprecated_params(), pytest.raises(InputError) as info:
        simulate(arm, None, arm.defaults.q0, None, T, params=Params(L1=1.0), estimate_error=False)
    _one_line(info.value, "would be ignored", "L1 = 1 vs 0.4", "chapter_arm(params)")
    with deprecated_params():
        run = simulate(arm, None, arm.defaults.q0, None, T, params=Params(), estimate_error=False)
    assert run.q.shape == (T.size, 3)  # the arm's own parameters are fine
    with pytest.raises(InputError, match="runs on backend='compiled' only"):
        simulate_batch(arm, None, np.tile(arm.defaults.q0, (2, 1)), None, T,
                       params=[Params(), Params()], estimate_error=False)  # fmt: skip


def test_inverse_dynamics_names_a_model_of_the_wrong_type(arm):
    z = np.zeros(3)
    with pytest.raises(ArgumentTypeError) as info:
        inverse_dynamics("str", z, z, z)
    assert isinstance(info.value, TypeError) and info.value.argument == "model"
    _one_line(info.value, "model must be a rrt_pin.Robot, a pinocchio.Model", "not str")
    with deprecated_params(), pytest.raises(ArgumentTypeError, match="params must be"):
        inverse_dynamics(arm, z, z, z, params={"L1": 1})
    with deprecated_params(), pytest.raises(InputError, match="would be ignored"):
        inverse_dynamics(arm, z, z, z, params=Params(m3=1.0))
    with deprecated_params():
        assert inverse_dynamics(arm, z, z, z, params=Params()).shape == (3,)


# --- the error estimate's failure is said (earlier: silently None) ----------------------
def test_a_failed_comparison_run_is_said_and_kept_in_the_result(arm):
    """rk4 at step 0.1 s never evaluates at t = 0.025 s; its half-step rerun does."""

    def trap(t, q, qd):
        return np.full(3, np.nan) if abs(t - 0.025) < 1e-12 else -10.0 * qd

    t = np.linspace(0.0, 0.5, 6)
    with pytest.warns(EstimateWarning, match="no error estimate: the comparison run"):
        run = simulate(arm, trap, arm.defaults.q0, None, t, method="rk4", step=0.1)
    assert run.estimate is None
    assert "the comparison run (rk4 at step 0.05 s" in run.estimate_failure
    assert "diverged" in run.estimate_failure


# --- energy: a run that cannot gain energy must not (earlier: success with a warning) --
def test_passive_motion_that_gains_energy_is_a_divergence(arm):
    with pytest.raises(DivergenceError) as info:
        simulate(arm, None, arm.defaults.q0, None, time_grid(20.0, 0.2),
                 method="symplectic_euler", estimate_error=False)  # fmt: skip
    e = info.value
    _one_line(e, "the energy grew from 392 J", "passive motion", "step shorter than 0.2 s")
    assert e.coordinate.startswith("qd") and 0.0 < e.t <= 20.0


def test_a_batch_names_the_variant_that_gained_energy(arm):
    q0s = np.array([arm.defaults.q0, arm.defaults.q0])
    laws = [regulator(arm), None]  # a damped regulator, and passive motion
    with pytest.raises(DivergenceError) as info:
        simulate_batch(arm, laws, q0s, None, time_grid(20.0, 0.2), method="symplectic_euler",
                       estimate_error=False)  # fmt: skip
    assert "(variant 1)" in info.value.coordinate and "energy grew" in str(info.value)


def test_accurate_runs_pass_the_energy_rule(arm):
    for law in (None, regulator(arm), regulator(arm, kd=0.0)):
        run = simulate(arm, law, arm.defaults.q0, None, time_grid(2.0, 0.01), method="rk4",
                       estimate_error=False)  # fmt: skip
        assert np.isfinite(run.q).all()


# --- work bounded up front; messages that say what happened ------------------------------
def test_a_fixed_step_run_beyond_the_step_limit_is_refused_at_once(arm):
    from rrt_pin.simulate.options import MAX_FIXED_STEPS

    with pytest.raises(InputError) as info:
        simulate(arm, None, arm.defaults.q0, None, time_grid(15.0, 0.01), method="rk4",
                 step=1e-9)  # fmt: skip
    _one_line(info.value, "would take 1.5e+10 steps", f"{MAX_FIXED_STEPS['pinocchio']:,}")


def test_odepack_nan_with_success_is_not_called_successful():
    from rrt_pin.simulate.scipy_runs import diagnose

    def f(t, y):
        return -y

    e = diagnose("odepack", f, np.ones(2), np.array([0.0, 1e-300]), 1e-12, 1e-14, ("q", "qd"),
                 "Integration successful.")  # fmt: skip
    _one_line(e, "although it reported success", "1e-300 s")
    assert "stopped: Integration successful" not in str(e)


def test_the_budget_hint_depends_on_the_method_and_measures_stiffness():
    from rrt_pin.simulate.scipy_runs import Counted, too_much_work

    def hint(method, rate, t_stop):
        counted = Counted(lambda t, y: -rate * y, budget=60)
        for k in range(61):
            try:
                counted(t_stop * k / 60, np.ones(2))
            except Exception:
                break
        return str(too_much_work(method, counted, 1.0, ("q", "qd"), 1e-6, 1e-8))

    stiff = hint("RK45", 1e7, 1e-5)  # 10 steps over 1e-5 s: h·rate = 10, past the limit
    assert "the motion is stiff" in stiff and "implicit" in stiff
    smooth = hint("RK45", 1.0, 1e-5)  # the same steps on a slow motion: accuracy-limited
    assert "stiff" not in smooth and "limited by accuracy" in smooth
    for implicit in ("Radau", "odepack"):
        text = hint(implicit, 1e7, 1e-5)
        assert f"{implicit} handles stiff motion" in text and "explicit" not in text


def test_no_numpy_reprs_in_grid_messages():
    with pytest.raises(InputError) as info:
        time_grid(np.float64(1.0), np.float64(2.0))
    _one_line(info.value, "dt=2.0 is larger than tf - t0 = 1.0")


def test_the_summary_says_why_the_estimate_is_missing(arm):
    from rrt_pin.cli.commands.simulate import summary, summary_text

    def trap(t, q, qd):
        return np.full(3, np.nan) if abs(t - 0.025) < 1e-12 else -10.0 * qd

    t = np.linspace(0.0, 0.5, 6)
    with pytest.warns(EstimateWarning):
        run = simulate(arm, trap, arm.defaults.q0, None, t, method="rk4", step=0.1)
    facts = summary(arm, run)
    assert facts["error_estimate"] is None
    assert facts["error_estimate_failure"] == run.estimate_failure
    line = next(s for s in summary_text(facts).splitlines() if "estimated global error" in s)
    assert line.endswith(f"not computed: {run.estimate_failure}")


def test_the_compiled_backend_never_runs_a_subclass_as_the_chapter_law(arm):
    pytest.importorskip("numba")
    from rrt_pin.simulate.control import ChapterController, chapter_controller

    base = chapter_controller()

    class Braking(ChapterController):
        def efforts(self, t, q, qd):
            return -50.0 * np.asarray(qd)

    law = Braking(kp=base.kp, kd=base.kd, qf=base.qf, params=base.params)
    with pytest.raises(InputError, match="not Braking"):
        simulate(arm, law, arm.defaults.q0, None, T, backend="compiled", estimate_error=False)


def test_error_controlled_runs_are_not_charged_the_energy_rule(arm, monkeypatch):
    """Tight adaptive runs are held by their error control; fixed steps are checked."""
    from rrt_pin.simulate import energy

    seen = []
    real = energy.rule_for
    monkeypatch.setattr(energy, "rule_for", lambda robot, law: seen.append(law) or real(robot, law))
    simulate(arm, None, arm.defaults.q0, None, T, estimate_error=False)  # odepack, rtol 1e-12
    simulate(arm, None, arm.defaults.q0, None, T, method="DOP853", rtol=1e-8, estimate_error=False)
    assert seen == []
    simulate(arm, None, arm.defaults.q0, None, T, method="RK45", rtol=1e-4, estimate_error=False)
    simulate(arm, None, arm.defaults.q0, None, T, method="rk4", step=0.01, estimate_error=False)
    assert len(seen) == 2
