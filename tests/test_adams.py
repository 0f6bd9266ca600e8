"""Shampine and Gordon's Adams method in any robot's compiled integrators (``method="adams"``).

Its runs are checked against an independent computation: the compiled DOP853 at rtol
1e-13 (another method, the same generated dynamics, whose agreement with ``pin.aba``
under SciPy is tested in tests/test_generated_integrators.py). One robot (UR5) keeps
the module's compilation to once.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

import rrt_pin  # noqa: E402
from rrt_pin.core.errors import DivergenceError, InputError  # noqa: E402
from rrt_pin.dynamics.trajectory import Trajectory  # noqa: E402
from rrt_pin.robot.robot import Robot  # noqa: E402
from rrt_pin.simulate import methods  # noqa: E402
from rrt_pin.simulate.control import (  # noqa: E402
    OpenLoop,
    pd_gravity_controller,
    tracking_controller,
)
from tests.support import robot_urdf  # noqa: E402

T = np.linspace(0.0, 2.0, 201)
Q0 = np.array([0.3, -1.0, 1.0, 0.3, 0.5, 0.0])
#: The law alone (no effort limits, position limits or losses).
LAW_ONLY = {"effort_limits": False, "position_limits": False, "losses": False}


@pytest.fixture(scope="module")
def ur5() -> Robot:
    return Robot.from_urdf(robot_urdf("ur5"))


def _pd(robot: Robot, gain: float = 20.0):
    return pd_gravity_controller(robot, kp=gain, kd=2.0 * np.sqrt(gain), qf=np.zeros(robot.nv))


def _run(robot, law, method, rtol, t=T, q0=Q0, qd0=None, **options):
    options = {**LAW_ONLY, **options}
    return rrt_pin.simulate(robot, law, q0, qd0, t, backend="compiled", method=method, rtol=rtol,
                            atol=rtol / 100, estimate_error=False, **options)  # fmt: skip


def _error(robot, law, rtol, **kw):
    fast = _run(robot, law, "adams", rtol, **kw)
    reference = _run(robot, law, "DOP853", 1e-13, **kw)
    return np.abs(fast.q - reference.q).max(), fast, reference


@pytest.fixture(scope="module")
def pd_errors(ur5):
    law = _pd(ur5)
    return {r: _error(ur5, law, r)[0] for r in (1e-5, 1e-7, 1e-9, 1e-11)}


def test_adams_is_a_compiled_method_only():
    m = methods.get("adams")
    assert m.adaptive and m.code is not None and m.runs_on("compiled")
    assert not m.runs_on("pinocchio") and m.runs_on("compiled", batch=True)
    with pytest.raises(InputError, match="does not run on backend 'pinocchio'"):
        methods.get("adams", "pinocchio")


def test_adams_meets_its_tolerances_and_converges(pd_errors):
    """The error at each rtol is of the order of rtol (or below) and shrinks with it."""
    for rtol, error in pd_errors.items():
        assert error <= 10.0 * rtol, (rtol, error)
    errors = list(pd_errors.values())
    assert all(tight < loose / 5.0 for loose, tight in zip(errors, errors[1:-1], strict=False))
    assert errors[-1] < 1e-10


def test_the_accuracy_asked_chooses_tolerances_that_keep_it(ur5):
    law = _pd(ur5)
    reference = _run(ur5, law, "DOP853", 1e-13)
    for accuracy in (1e-6, 1e-8):
        run = rrt_pin.simulate(ur5, law, Q0, None, T, backend="compiled", method="adams",
                               accuracy=accuracy, estimate_error=False, **LAW_ONLY)  # fmt: skip
        assert (run.method, run.backend) == ("adams", "compiled")
        assert np.abs(run.q - reference.q).max() <= accuracy


def test_the_error_estimate_brackets_the_error(ur5):
    """The default run's estimate (its calibrated companion) is within 0.3–3× of the error."""
    law = _pd(ur5, 50.0)
    run = rrt_pin.simulate(ur5, law, Q0, None, T, backend="compiled", method="adams",
                           **LAW_ONLY)  # fmt: skip
    error = np.abs(run.q - _run(ur5, law, "DOP853", 1e-13).q).max()
    assert run.rtol == methods.get("adams").rtol and error <= methods.ACCURACY
    assert 0.3 * max(error, 1e-11) <= max(run.error_estimate, 1e-11) <= 3.0 * max(error, 1e-11)


def test_fewer_evaluations_than_dop853_at_the_same_error(ur5):
    law = _pd(ur5)
    error, adams, _ = _error(ur5, law, 1e-8)
    dop = _run(ur5, law, "DOP853", 1e-8)
    dop_error = np.abs(dop.q - _run(ur5, law, "DOP853", 1e-13).q).max()
    assert error <= dop_error and adams.n_evals < dop.n_evals


def test_the_outputs_are_interpolated_not_stepped_to(ur5):
    """The steps do not depend on the output times: the same states, bit for bit, at the
    outputs two grids share (and the same final state without any output in between)."""
    law = _pd(ur5)
    fine = _run(ur5, law, "adams", 1e-8)
    coarse = _run(ur5, law, "adams", 1e-8, t=T[::10])
    ends = _run(ur5, law, "adams", 1e-8, t=T[[0, -1]])
    assert np.array_equal(fine.q[::10], coarse.q) and np.array_equal(fine.qd[::10], coarse.qd)
    assert np.array_equal(ends.q[-1], fine.q[-1])
    assert fine.n_evals == coarse.n_evals == ends.n_evals
    assert np.array_equal(fine.q[0], Q0)


@pytest.mark.filterwarnings("ignore::rrt_pin.robot.limits.LimitWarning")  # qf past a limit
@pytest.mark.parametrize("law_name", ["pd_gravity", "tracking", "open_loop", "none", "physical"])
def test_every_built_in_law(ur5, law_name):
    t, q0, qd0, extra = T, Q0, None, {}
    if law_name == "pd_gravity":
        law = _pd(ur5)
    elif law_name == "tracking":
        t = np.linspace(0.0, 1.0, 201)
        k = np.arange(1, 7)
        q = 0.3 * np.sin(np.outer(t, k))
        motion = Trajectory(t=t, q=q, qd=0.3 * np.cos(np.outer(t, k)) * k,
                            qdd=-0.3 * np.sin(np.outer(t, k)) * k**2)  # fmt: skip
        law, q0, qd0 = tracking_controller(ur5, motion), q[0], motion.qd[0]
    elif law_name == "open_loop":
        ts = np.linspace(0.0, 1.0, 11)
        law = OpenLoop(t=ts, tau=np.column_stack([np.sin(3 * ts + k) for k in range(6)]))
    elif law_name == "none":
        law = None
    else:  # PD towards the elbow's limit, with effort and position limits and losses
        law = pd_gravity_controller(ur5, kp=[400.0] * 3 + [40.0] * 3, kd=40.0,
                                    qf=[0.5, -1.5, 3.6, 0.0, 0.0, 0.0])  # fmt: skip
        q0 = np.array([0.0, -1.0, 2.9, 0.3, 0.5, 0.0])
        extra = {"effort_limits": True, "position_limits": True, "losses": True}
    error, fast, reference = _error(ur5, law, 1e-10, t=t, q0=q0, qd0=qd0, **extra)
    assert error < 1e-8, error
    scale = 1.0 + np.abs(reference.tau).max()
    assert np.abs(fast.tau - reference.tau).max() < 1e-6 * scale  # efforts at the outputs
    assert np.abs(fast.q[-1] - q0).max() > 1e-3  # it moved
    if law_name == "physical":
        assert fast.q[:, 2].max() < np.pi + 0.02  # held near the elbow's limit


def test_a_nonfinite_law_is_reported(ur5):
    """Efforts of 1e308 N·m: q̈ overflows at the first evaluation."""
    law = pd_gravity_controller(ur5, kp=1e308, kd=0.0, qf=Q0 - 1.0)
    with pytest.raises(DivergenceError) as e:
        _run(ur5, law, "adams", 1e-8)
    assert e.value.t == 0.0
    assert any(name in str(e.value) for name in (*ur5.q_names, *ur5.qd_names))


def test_a_diverging_run_is_reported_with_the_coordinate(ur5):
    law = pd_gravity_controller(ur5, kp=1e12, kd=0.0, qf=np.zeros(6))
    with pytest.raises(DivergenceError) as e:
        _run(ur5, law, "adams", 1e-8, t=np.linspace(0.0, 100.0, 11))
    assert 0.0 <= e.value.t < 100.0
    assert any(name in str(e.value) for name in (*ur5.q_names, *ur5.qd_names))


@pytest.mark.parametrize("rtol", [-1e-6, 0.0, 1e-16, float("nan")])
def test_bad_rtol_is_refused(ur5, rtol):
    with pytest.raises(InputError, match="rtol"):
        rrt_pin.simulate(ur5, _pd(ur5), Q0, None, T, backend="compiled", method="adams",
                         rtol=rtol, atol=1e-12)  # fmt: skip


@pytest.mark.parametrize("keep", ["trajectories", "final", "metrics"])
def test_batch_rows_equal_single_runs(ur5, keep):
    laws = [_pd(ur5, g) for g in (5.0, 20.0, 50.0)]
    q0s = Q0 + np.linspace(-0.1, 0.1, 3)[:, None]
    batch = rrt_pin.simulate_batch(ur5, laws, q0s, None, T, backend="compiled", method="adams",
                                   keep=keep, rtol=1e-9, atol=1e-9 / 100, estimate_error=False,
                                   threads=2, **LAW_ONLY)  # fmt: skip
    assert batch.method == "adams"
    for b in range(3):
        one = _run(ur5, laws[b], "adams", 1e-9, q0=q0s[b])
        assert np.array_equal(batch.q[b], one.q if keep == "trajectories" else one.q[-1:])


def test_the_chapters_arm_refuses_it():
    from rrt_pin.robot.robots import chapter_arm

    arm = chapter_arm()
    with pytest.raises(InputError, match="adams"):
        rrt_pin.simulate(arm, None, np.zeros(3), None, T, backend="compiled", method="adams")


def test_an_adams_run_compiles_its_entry_alone(ur5, monkeypatch):
    """A single run or a batch with method='adams' asks for its own entry only (not
    run_many): under PD plus gravity its law-bound copy, else the general one."""
    from rrt_pin.compiled import robot_code, robot_runs
    from rrt_pin.simulate.options import resolve

    asked = []

    class Code:  # stands for a robot's code not compiled yet: records what is compiled
        def entry(self, name):
            asked.append(name)

    monkeypatch.setattr(robot_code, "integrators_for", lambda model, name=None: Code())
    options = resolve(T, backend="compiled", method="adams", rtol=1e-9, atol=1e-11)
    robot_runs.prepare(ur5, [_pd(ur5)], options)
    robot_runs.prepare(ur5, [_pd(ur5), _pd(ur5)], options)
    robot_runs.prepare(ur5, [_pd(ur5), None], options)
    assert asked == ["run_adams_pd", "run_adams_pd", "run_adams"]
