"""DOP853 handing over to Runge–Kutta–Chebyshev in its stiff tail (``method="DOP853-RKC"``).

Every run is checked against an independent computation: the compiled DOP853 at rtol
1e-13 (another method on the same generated dynamics, whose agreement with ``pin.aba``
under SciPy is tested in tests/test_generated_integrators.py). The scenes are PD loops
that settle (the tail is stiff for DOP853: its steps are held by its stability), a
tracking law whose motion stops and starts again (RKC must hand back), and scenes that
never get stiff (DOP853's own steps, bit for bit).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("numba")

import rrt_pin  # noqa: E402
from rrt_pin.core.errors import DivergenceError, InputError  # noqa: E402
from rrt_pin.dynamics.trajectory import Trajectory  # noqa: E402
from rrt_pin.robot.robot import Robot  # noqa: E402
from rrt_pin.simulate import methods  # noqa: E402
from rrt_pin.simulate.control import pd_gravity_controller, tracking_controller  # noqa: E402
from tests.support import robot_urdf  # noqa: E402

#: The law alone (no effort limits, position limits or losses).
LAW_ONLY = {"effort_limits": False, "position_limits": False, "losses": False}
T = np.arange(0.0, 8.0 + 1e-9, 0.01)
QF = {"ur5": [0.0, -1.2, 1.2, -1.0, -1.2, 0.0], "panda": [0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.8]}


@pytest.fixture(scope="module")
def ur5() -> Robot:
    return Robot.from_urdf(robot_urdf("ur5"))


def _scene(robot: Robot, name: str):
    """PD plus gravity critically damped at 10 rad/s on M(qf)'s diagonal, from qf + 0.3 rad."""
    qf = np.zeros(robot.nv)
    qf[: len(QF[name])] = QF[name]
    if robot.nv > len(QF[name]):
        qf[len(QF[name]) :] = 0.02  # Panda's fingers [m]
    diag = np.diag(pin.crba(robot.model, robot.model.createData(), robot.configuration(qf)))
    law = pd_gravity_controller(robot, kp=100.0 * diag, kd=20.0 * diag, qf=qf)
    q0 = qf + np.array([0.01 if u == "m" else 0.3 for u in robot.coordinate_units])
    return law, q0


def _run(robot, law, method, rtol, t=T, q0=None, qd0=None, **options):
    options = {**LAW_ONLY, **options}
    return rrt_pin.simulate(robot, law, q0, qd0, t, backend="compiled", method=method, rtol=rtol,
                            atol=rtol / 100, estimate_error=False, **options)  # fmt: skip


def test_it_is_a_compiled_method_of_any_robot_but_the_arm():
    m = methods.get("DOP853-RKC")
    assert m.adaptive and m.code is not None and m.runs_on("compiled")
    assert m.runs_on("compiled", batch=True) and not m.runs_on("pinocchio")
    with pytest.raises(InputError, match="does not run on backend 'pinocchio'"):
        methods.get("DOP853-RKC", "pinocchio")
    from rrt_pin.robot.robots import chapter_arm

    with pytest.raises(InputError, match="DOP853-RKC"):
        rrt_pin.simulate(chapter_arm(), None, np.zeros(3), None, T[:11], backend="compiled",
                         method="DOP853-RKC")  # fmt: skip


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_a_settled_tail_costs_far_fewer_evaluations_at_the_same_error(ur5, name):
    """At every output the error is DOP853's (within 1.5×, or below rtol), for at most
    60 % of its evaluations: the tail after the loop settles is stiff for DOP853."""
    robot = ur5 if name == "ur5" else Robot.from_urdf(robot_urdf("panda"))
    law, q0 = _scene(robot, name)
    t = np.arange(0.0, 15.0 + 1e-9, 0.01)
    reference = _run(robot, law, "DOP853", 1e-13, t=t, q0=q0)
    for rtol in (1e-6, 1e-8, 1e-10):
        dop = _run(robot, law, "DOP853", rtol, t=t, q0=q0)
        rkc = _run(robot, law, "DOP853-RKC", rtol, t=t, q0=q0)
        assert (rkc.method, rkc.backend) == ("DOP853-RKC", "compiled")
        dop_error = np.abs(dop.q - reference.q).max()
        rkc_error = np.abs(rkc.q - reference.q).max()
        assert rkc_error <= max(1.5 * dop_error, rtol), (rtol, rkc_error, dop_error)
        assert rkc.n_evals <= 0.6 * dop.n_evals, (rtol, rkc.n_evals, dop.n_evals)
        assert np.abs(rkc.qd - reference.qd).max() <= max(
            1.5 * np.abs(dop.qd - reference.qd).max(), 10 * rtol
        )


def test_the_motion_starting_again_hands_back_to_dop853(ur5):
    """Tracking a motion that rests, moves from 4 to 6 s, and rests again, with stiff
    gains: the rest is DOP853's stiff tail, then the move needs accuracy. RKC (order 2)
    through the move at rtol 1e-10 would take thousands of short steps (local error ~h³):
    it hands back, so the run costs no more than DOP853's and keeps its error."""
    t = np.arange(0.0, 10.0 + 1e-9, 0.05)
    s = np.clip((t - 4.0) / 2.0, 0.0, 1.0)
    shape = s**3 * (10 - 15 * s + 6 * s**2)  # rest to rest
    rate = 30 * s**2 * (1 - s) ** 2 / 2.0
    accel = 60 * s * (1 - s) * (1 - 2 * s) / 4.0
    q_start = np.array(QF["ur5"])
    step = np.full(6, 0.8)
    motion = Trajectory(t=t, q=q_start + np.outer(shape, step), qd=np.outer(rate, step),
                        qdd=np.outer(accel, step))  # fmt: skip
    law = tracking_controller(ur5, motion, kp=2500.0, kd=100.0)
    out = np.arange(0.0, 10.0 + 1e-9, 0.01)
    q0 = q_start + 0.1
    reference = _run(ur5, law, "DOP853", 1e-13, t=out, q0=q0)
    for rtol in (1e-8, 1e-10):
        dop = _run(ur5, law, "DOP853", rtol, t=out, q0=q0)
        rkc = _run(ur5, law, "DOP853-RKC", rtol, t=out, q0=q0)
        dop_error = np.abs(dop.q - reference.q).max()
        rkc_error = np.abs(rkc.q - reference.q).max()
        assert rkc_error <= max(2.0 * dop_error, rtol), (rtol, rkc_error, dop_error)
        assert rkc.n_evals <= dop.n_evals, (rtol, rkc.n_evals, dop.n_evals)
        assert np.abs(rkc.q[-1] - (q_start + step)).max() < 1e-6  # it followed the motion


@pytest.mark.parametrize("law_name", ["light_pd", "none"])
def test_a_run_that_never_gets_stiff_is_dop853_bit_for_bit(ur5, law_name):
    """No step at the edge of DOP853's stability, no handover: DOP853's steps and bits."""
    if law_name == "light_pd":
        law = pd_gravity_controller(ur5, kp=4.0, kd=0.5, qf=np.array(QF["ur5"]))
    else:
        law = None
    t = T[:301]
    q0 = np.array(QF["ur5"]) + 0.3
    dop = _run(ur5, law, "DOP853", 1e-9, t=t, q0=q0)
    rkc = _run(ur5, law, "DOP853-RKC", 1e-9, t=t, q0=q0)
    assert np.array_equal(dop.q, rkc.q) and np.array_equal(dop.qd, rkc.qd)
    assert dop.n_evals == rkc.n_evals
    assert np.abs(rkc.q[-1] - q0).max() > 1e-3  # it moved


@pytest.mark.filterwarnings("ignore::rrt_pin.robot.limits.LimitWarning")
def test_the_physical_model_is_applied_in_the_tail(ur5):
    """Limits, damping and friction (the default): the tail still hands over and the
    error stays DOP853's, the efforts at the outputs too."""
    law, q0 = _scene(ur5, "ur5")
    physical = {"effort_limits": True, "position_limits": True, "losses": True}
    reference = _run(ur5, law, "DOP853", 1e-13, q0=q0, **physical)
    dop = _run(ur5, law, "DOP853", 1e-9, q0=q0, **physical)
    rkc = _run(ur5, law, "DOP853-RKC", 1e-9, q0=q0, **physical)
    dop_error = np.abs(dop.q - reference.q).max()
    assert np.abs(rkc.q - reference.q).max() <= max(1.5 * dop_error, 1e-9)
    scale = 1.0 + np.abs(reference.tau).max()
    assert np.abs(rkc.tau - reference.tau).max() < 1e-6 * scale
    assert rkc.n_evals < 0.8 * dop.n_evals


@pytest.mark.parametrize("keep", ["trajectories", "final", "metrics"])
def test_batch_rows_equal_single_runs_bit_for_bit(ur5, keep):
    """In lanes, each variant hands over (and back) on its own: 19 variants whose gains
    and offsets spread their handovers, so that lanes in DOP853 and in RKC run side by
    side; every row is its single run's, on one thread and on two."""
    law, q0 = _scene(ur5, "ur5")
    rng = np.random.default_rng(7)
    scale = np.exp(rng.uniform(np.log(0.2), np.log(5.0), 19))
    laws = [pd_gravity_controller(ur5, kp=k * np.array(law.kp), kd=np.sqrt(k) * np.array(law.kd),
                                 qf=law.qf)
            for k in scale]  # fmt: skip
    q0s = q0 + rng.uniform(-0.2, 0.2, (19, 6))
    singles = [_run(ur5, laws[b], "DOP853-RKC", 1e-9, q0=q0s[b]) for b in range(19)]
    dop = [_run(ur5, laws[b], "DOP853", 1e-9, q0=q0s[b]).n_evals for b in range(19)]
    assert sum(one.n_evals for one in singles) < 0.7 * sum(dop)  # they did hand over
    metrics = []
    for threads in (1, 2):
        batch = rrt_pin.simulate_batch(ur5, laws, q0s, None, T, backend="compiled",
                                       method="DOP853-RKC", keep=keep, rtol=1e-9,
                                       atol=1e-9 / 100, estimate_error=False, threads=threads,
                                       **LAW_ONLY)  # fmt: skip
        assert batch.method == "DOP853-RKC"
        for b, one in enumerate(singles):
            assert np.array_equal(batch.q[b], one.q if keep == "trajectories" else one.q[-1:])
            assert np.array_equal(batch.qd[b], one.qd if keep == "trajectories" else one.qd[-1:])
        if keep == "metrics":
            metrics.append(batch.metrics)
    if keep == "metrics":  # measured on the rows above: the same on any thread count
        assert metrics[0].keys() == metrics[1].keys()
        for name, column in metrics[0].items():
            assert np.array_equal(column, metrics[1][name], equal_nan=True), name


def test_a_pd_run_on_its_own_entry_equals_the_general_entry(ur5, monkeypatch):
    """The PD-bound copies of the tail (rkc_tail_pd and its helpers) give the general
    entry's bits."""
    from rrt_pin.compiled import robot_entries

    law, q0 = _scene(ur5, "ur5")
    pd = _run(ur5, law, "DOP853-RKC", 1e-8, q0=q0)
    assert robot_entries.entry(methods.get("DOP853-RKC").code, 1, True) == "run_adaptive_rkc_pd"
    monkeypatch.setattr(
        robot_entries, "entry", lambda method, count, pd, numeric: "run_adaptive_rkc"
    )
    general = _run(ur5, law, "DOP853-RKC", 1e-8, q0=q0)
    assert np.array_equal(pd.q, general.q) and pd.n_evals == general.n_evals


def test_a_diverging_run_is_reported_with_the_coordinate(ur5):
    law = pd_gravity_controller(ur5, kp=1e12, kd=0.0, qf=np.zeros(6))
    with pytest.raises(DivergenceError) as e:
        _run(ur5, law, "DOP853-RKC", 1e-8, t=np.linspace(0.0, 100.0, 11), q0=np.full(6, 0.3))
    assert 0.0 <= e.value.t < 100.0
    assert any(name in str(e.value) for name in (*ur5.q_names, *ur5.qd_names))


def test_dop853s_entries_compile_none_of_rkcs_code(ur5):
    """DOP853's and RK45's entries reach a stub where DOP853-RKC's reach rkc_tail: a plain
    DOP853 run or batch compiles none of RKC's code (its first use is not longer for it)."""
    from rrt_pin.compiled.robot_code import module_source
    from tests.support import call_graph
    from tests.support import reaches as reached

    calls = call_graph(module_source(ur5.model)[0])

    def reaches(entry):
        return reached(calls, entry)

    for entry in ("run_adaptive", "run_adaptive_pd", "run_many", "run_lanes"):
        assert not reaches(entry) & {"rkc_tail", "rkc_tail_pd", "rkc_prepare", "rkc_consume"}
    assert "rkc_tail" in reaches("run_adaptive_rkc")
    assert "rkc_tail_pd" in reaches("run_adaptive_rkc_pd")
    assert {"rkc_prepare", "rkc_consume"} <= reaches("run_lanes_rkc")


@pytest.mark.parametrize("accuracy", [1e-4, 1e-6, 1e-8])
def test_it_takes_dop853s_tolerances_for_the_accuracy_asked_and_keeps_it(accuracy):
    """Calibrated as DOP853, whose steps it takes until it hands over (the catalogue's hardest
    problems then bind it too): the tolerances DOP853's calibration gives for the accuracy
    asked. On the calibration's UR5 problem, which hands over, the run keeps the accuracy
    and its estimate (DOP853's companion) stays within 0.3–3× of the true error."""
    from rrt_pin.simulate.accuracy import ROBOT_PROBLEMS, max_error, reference

    chosen = methods.tolerances("compiled", "DOP853-RKC", accuracy)
    assert chosen == methods.tolerances("compiled", "DOP853", accuracy)
    assert methods.calibration_key("compiled", "DOP853-RKC") == ("compiled", "DOP853")
    problem = ROBOT_PROBLEMS["ur5"]
    run = problem.run(backend="compiled", method="DOP853-RKC", accuracy=accuracy)
    assert (run.rtol, run.atol) == chosen
    dop853 = problem.run(backend="compiled", method="DOP853", accuracy=accuracy,
                         estimate_error=False)  # fmt: skip
    assert run.n_evals < dop853.n_evals  # it handed over
    error = max_error(run.q, reference(problem).q)
    assert error <= accuracy
    assert 0.3 <= max(run.error_estimate, 1e-11) / max(error, 1e-11) <= 3.0
