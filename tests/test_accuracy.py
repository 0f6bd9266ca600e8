"""Accuracy the user can rely on: the defaults keep 1e-8 on the catalogue, and every
run's error estimate brackets its true error.

References are computed here at rtol 1e-13 (the compiled DOP853 where it runs, scipy's
DOP853 on ``pin.aba`` otherwise), and cross-checked against a second, independent
integration on a few problems.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from rrt_pin.cli.app import main
from rrt_pin.compiled import available
from rrt_pin.simulate import AccuracyWarning, methods, simulate, simulate_batch
from rrt_pin.simulate.accuracy import ACCURACY, PROBLEMS, max_error, reference

#: The bracket the estimate keeps at the defaults: 0.3·true <= estimate <= 3·true.
LOW, HIGH = 0.3, 3.0
#: The bracket away from the calibrated defaults (explicit tolerances, fixed steps).
BRACKET = 10.0
#: Below this the references themselves disagree (5e-12 over the 1,000 s problem between
#: the compiled and scipy's DOP853, 5e-11 between odepack and DOP853 on light-joint3):
#: errors and estimates are compared as max(value, FLOOR) [rad or m].
FLOOR = 1e-11
#: Old defaults (rtol 1e-9, atol 1e-11): larger errors, so the bracket is tested where
#: the references resolve them well.
OLD = {"rtol": 1e-9, "atol": 1e-11}

needs_compiled = pytest.mark.skipif(not available(), reason="numba is not installed")

_REFS: dict[str, np.ndarray] = {}


def ref(name: str) -> np.ndarray:
    """The problem's reference q (computed once per session)."""
    if name not in _REFS:
        _REFS[name] = reference(PROBLEMS[name]).q
    return _REFS[name]


def assert_brackets(estimate: float, error: float, what: str, low=1 / BRACKET, high=BRACKET):
    e, t = max(estimate, FLOOR), max(error, FLOOR)
    assert low * t <= e <= high * t, f"{what}: estimate {estimate:.2e}, error {error:.2e}"


#: Problems where odepack's default estimate over-estimates by more than HIGH (4.4× on the
#: fast oscillation, whose error sits near odepack's own floor there, 1.6e-10): held to
#: LOW..BRACKET (never an under-estimate) here, and to LOW..HIGH by a strict xfail below.
ODEPACK_OVER = {"fast-oscillation"}


def assert_default_brackets(estimate: float, error: float, what: str, high=HIGH) -> None:
    assert_brackets(estimate, error, what, LOW, high)


def quiet_run(name: str, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        return PROBLEMS[name].run(**kw)


def test_the_catalogue_covers_the_hard_cases():
    names = set(PROBLEMS)
    assert {"chapter", "slider-150s", "long-1000s", "stiff-x100", "stiff-x1e4"} <= names
    assert {"light-joint1", "light-joint2", "light-joint3"} <= names
    assert {"fast-motion", "small-masses", "large-masses"} <= names
    assert max(s.tf for s in PROBLEMS.values()) >= 1000.0
    slider = PROBLEMS["slider-150s"]
    assert (slider.arm.params.beta23, slider.arm.params.gamma23, slider.tf) == (0.5, 400.0, 150.0)
    assert PROBLEMS["fast-motion"].backends == ("pinocchio",)


# --- references -----------------------------------------------------------------------
@needs_compiled
def test_compiled_reference_agrees_with_scipy_dop853_and_radau():
    from rrt_pin.simulate.reference import chapter_reference

    chapter = chapter_reference()  # DOP853 and Radau on pin.aba at rtol 1e-13, cached
    assert chapter.difference_q < 1e-12
    assert max_error(ref("chapter"), chapter.q) < 1e-12
    fast = PROBLEMS["fast-oscillation"]
    assert max_error(ref(fast.name), reference(fast, backend="pinocchio").q) < 1e-12


# --- the defaults keep their promise ---------------------------------------------------
COMPILED_PROBLEMS = [n for n, s in PROBLEMS.items() if "compiled" in s.backends]


@needs_compiled
@pytest.mark.parametrize("name", COMPILED_PROBLEMS)
def test_compiled_default_keeps_the_promise_and_its_estimate_brackets(name):
    run = PROBLEMS[name].run(backend="compiled")
    assert run.method == "DOP853"
    assert (run.rtol, run.atol) == methods.tolerances("compiled", "DOP853", ACCURACY)
    error = max_error(run.q, ref(name))
    assert error <= ACCURACY
    assert run.estimate is not None and not run.estimate.exceeded
    assert_default_brackets(run.error_estimate, error, f"{name} compiled default")
    old = quiet_run(name, backend="compiled", **OLD)
    assert_brackets(old.error_estimate, max_error(old.q, ref(name)), f"{name} compiled rtol 1e-9")


@pytest.mark.parametrize("name", list(PROBLEMS))
def test_pinocchio_default_keeps_the_promise_and_its_estimate_brackets(name):
    run = PROBLEMS[name].run()
    assert run.method == "odepack" and run.backend == "pinocchio"
    error = max_error(run.q, ref(name))
    assert error <= ACCURACY
    assert not run.estimate.exceeded
    high = BRACKET if name in ODEPACK_OVER else HIGH
    assert_default_brackets(run.error_estimate, error, f"{name} pinocchio default", high)
    per = np.abs(run.q - ref(name)).max(axis=0)
    assert run.error_estimate_q.shape == per.shape == (3,)
    assert run.error_estimate == pytest.approx(run.error_estimate_q.max())


@pytest.mark.xfail(strict=True, reason="odepack over-estimates its fast-oscillation error 4.4×")
@pytest.mark.parametrize("name", sorted(ODEPACK_OVER))
def test_pinocchio_default_estimate_within_3x_where_it_over_estimates(name):
    run = PROBLEMS[name].run()
    assert_default_brackets(run.error_estimate, max_error(run.q, ref(name)), name)


@pytest.mark.parametrize("name", ["slider-150s", "light-joint3", "fast-oscillation", "chapter"])
def test_pinocchio_estimate_brackets_at_the_old_defaults(name):
    run = quiet_run(name, **OLD)
    assert_brackets(run.error_estimate, max_error(run.q, ref(name)), f"{name} odepack 1e-9")


@pytest.mark.parametrize(
    "names",
    [
        ["chapter", "stiff-x100", "fast-oscillation"],
        ["slider-150s", "light-joint1", "light-joint2", "light-joint3"],
    ],
)
def test_batch_default_keeps_the_promise_on_pinocchio(names):
    """Problems that differ in gains only share the arm: one Pinocchio batch of them.

    (One thread: OpenMP's threads wait for each other on a busy machine.)
    """
    problems = [PROBLEMS[n] for n in names]
    arm = problems[0].arm
    laws = [s.controller(s.arm) for s in problems]
    q0s = np.array([s.arm.defaults.q0 for s in problems])
    batch = simulate_batch(arm, laws, q0s, None, problems[0].times(), threads=1)
    assert batch.method == "odepack" and batch.estimate.variants.shape == (len(names), 3)
    for i, name in enumerate(names):
        error = max_error(batch.q[i], ref(name))
        assert error <= ACCURACY
        high = BRACKET if name in ODEPACK_OVER else HIGH
        est = float(batch.estimate.variants[i].max())
        assert_default_brackets(est, error, f"batch {name}", high)
        assert batch.variant(i).error_estimate == pytest.approx(batch.estimate.variants[i].max())


@needs_compiled
@pytest.mark.parametrize("tf", [15.0, 150.0, 1000.0])
def test_batch_default_keeps_the_promise_compiled(tf):
    names = [n for n in COMPILED_PROBLEMS if PROBLEMS[n].tf == tf]
    problems = [PROBLEMS[n] for n in names]
    arms = [s.arm for s in problems]
    batch = simulate_batch(
        arms[0],
        [s.controller(a) for s, a in zip(problems, arms, strict=True)],
        np.array([a.defaults.q0 for a in arms]),
        None,
        problems[0].times(),
        backend="compiled",
        params=[a.params for a in arms],
    )
    for i, name in enumerate(names):
        error = max_error(batch.q[i], ref(name))
        assert error <= ACCURACY
        assert_default_brackets(float(batch.estimate.variants[i].max()), error, f"batch {name}")
    assert batch.error_estimate == pytest.approx(batch.estimate.variants.max())


# --- fixed steps, other robots ---------------------------------------------------------
FIXED_STEP = [m for m in methods.METHODS.values() if not m.adaptive]


def test_every_fixed_step_method_has_an_order():
    assert FIXED_STEP and all(m.order in (1, 2, 4) for m in FIXED_STEP)


@pytest.mark.parametrize("method", [m.name for m in FIXED_STEP])
def test_fixed_step_estimate_is_richardsons(method):
    compiled = available() and methods.get(method).runs_on("compiled")
    step = 0.002 if method == "verlet" else 0.01
    run = quiet_run("chapter", backend="compiled" if compiled else "pinocchio", method=method,
                    step=step)  # fmt: skip
    assert "Richardson" in run.estimate.how
    assert_brackets(run.error_estimate, max_error(run.q, ref("chapter")), method)


def test_any_urdf_robot_gets_an_estimate(tmp_path):
    """A generic robot (the arm's URDF, PD plus Pinocchio's gravity compensation)."""
    from rrt_pin.robot.robot import Robot
    from rrt_pin.robot.urdf import urdf_xml
    from rrt_pin.simulate.control import regulator
    from rrt_pin.simulate.reference import reference_run

    path = tmp_path / "arm.urdf"
    path.write_text(urdf_xml())
    robot = Robot.from_urdf(path)
    law = regulator(robot, kp=[300.0, 300.0, 400.0], kd=[5.0, 5.0, 0.5], qf=[1.0, 1.0, 0.3])
    t = np.linspace(0.0, 20.0, 2001)
    q0 = np.array([0.2, 0.5, 0.25])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        runs = [simulate(robot, law, q0, None, t, **kw) for kw in ({}, OLD)]
    exact = reference_run(robot.model, law, q0, np.zeros(3), t, methods=("DOP853",)).q
    for run in runs:
        assert_brackets(run.error_estimate, max_error(run.q, exact), f"URDF rtol {run.rtol}")
    assert max_error(runs[0].q, exact) <= ACCURACY


# --- the estimate's switches and warnings ----------------------------------------------
def test_estimate_can_be_skipped():
    problem = PROBLEMS["chapter"]
    run = problem.run(estimate_error=False)
    assert run.estimate is None and run.error_estimate is None and run.error_estimate_q is None
    arm = problem.arm
    batch = simulate_batch(
        arm, problem.controller(arm), np.array([arm.defaults.q0]), None, problem.times()[:101],
        estimate_error=False,
    )  # fmt: skip
    assert batch.estimate is None and batch.variant(0).error_estimate is None


def test_a_run_beyond_its_accuracy_warns():
    backend = "compiled" if available() else "pinocchio"
    with pytest.warns(AccuracyWarning, match=r"estimated global error of q .* \(q3\) exceeds"):
        run = PROBLEMS["slider-150s"].run(backend=backend, method="rk4", step=0.01)
    assert run.estimate.exceeded and run.estimate.accuracy == ACCURACY
    with warnings.catch_warnings():
        warnings.simplefilter("error", AccuracyWarning)
        loose = PROBLEMS["chapter"].run(backend=backend, rtol=1e-6, atol=1e-8)
    assert loose.estimate.accuracy == 1e-6  # asks for no better than its tolerance


def test_cli_reports_the_estimate_and_warns(capsys):
    slider = ["--set", "beta23=0.5", "--set", "gamma23=400", "--tf", "150"]
    assert main(["simulate", *slider, "--rtol", "1e-9", "--atol", "1e-11"]) == 0
    out, err = capsys.readouterr()
    assert "estimated global error of q(t), max over t:" in out and "exceeds" in out
    assert "warning: estimated global error of q(t)" in err and "(q3)" in err
    assert err.count("\n") == 1
    assert main(["simulate", *slider]) == 0
    out, err = capsys.readouterr()
    assert "within the accuracy asked for, 1e-08" in out and err == ""
    assert main(["simulate", "--no-error-estimate"]) == 0
    out, err = capsys.readouterr()
    assert "estimated global error of q(t): not computed" in out and err == ""
