"""The ``limits`` metric group: how far past its position limits and how long saturated.

One small robot (two revolute joints, its URDF written here) serves every test, so that
its generated integrators are compiled once. Its variants: PD plus gravity from rest to
a target near the first joint's upper or lower limit (the demand exceeds both joints'
effort limits at first and the first joint overshoots its limit) or to a modest one
(nothing crossed). The columns are checked against an independent computation from the
kept trajectories (numpy, Pinocchio's gravity for the law's demand), across backends
and against each single run's ``result.limits``.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.grid import time_grid
from rrt_pin.robot.limits import physical_model
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import simulate, simulate_batch
from rrt_pin.simulate.control import pd_gravity_controller
from rrt_pin.simulate.metrics import batch_metrics
from rrt_pin.sweeps.compute import metric_names, plan, run_chunk
from rrt_pin.sweeps.spec import spec_from_dict

pytestmark = [
    pytest.mark.filterwarnings("ignore::rrt_pin.robot.limits.LimitWarning"),
    pytest.mark.usefixtures("auto_backend"),  # sweeps choose their backend
]

HAS_NUMBA = importlib.util.find_spec("numba") is not None
needs_numba = pytest.mark.skipif(not HAS_NUMBA, reason="numba not installed (rrt-pin[fast])")

#: The first joint's position limits [rad] and both joints' effort limits [N·m].
LOWER, UPPER = -0.5, 0.5
EFFORT = (8.0, 5.0)
KP, KD = (40.0, 40.0), (2.0, 2.0)
#: The first joint's targets [rad]: past-the-lower-limit overshoot, nothing crossed, upper.
TARGETS = (-0.45, 0.15, 0.45)
LOW, QUIET, HIGH = range(3)
TF, DT = 1.0, 0.01
#: Two runs of the same variant by different integrators (or step controls) agree to
#: about their accuracy (1e-8 rad by default); a depth past a limit likewise.
RUNS = 1e-6

_LINK = (
    '<link name="{name}"><inertial><origin xyz="0 0 -0.25"/><mass value="1"/>'
    '<inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)


def _joint(name: str, parent: str, child: str, xyz: str, limit: str) -> str:
    return (
        f'<joint name="{name}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}"/><axis xyz="0 1 0"/><limit {limit}/></joint>'
    )


def urdf_text(j1: str | None = None, j2: str | None = None) -> str:
    """Two 0.5 m, 1 kg links swinging about y; ``j1``, ``j2``: their ``<limit>`` attributes."""
    j1 = j1 or f'lower="{LOWER}" upper="{UPPER}" effort="{EFFORT[0]}" velocity="100"'
    j2 = j2 or f'lower="-1.5" upper="1.5" effort="{EFFORT[1]}" velocity="100"'
    return (
        '<robot name="limits2"><link name="base"/>'
        + _LINK.format(name="l1")
        + _LINK.format(name="l2")
        + _joint("j1", "base", "l1", "0 0 0", j1)
        + _joint("j2", "l1", "l2", "0 0 -0.5", j2)
        + "</robot>"
    )


@pytest.fixture(scope="module")
def urdf(tmp_path_factory):
    path = tmp_path_factory.mktemp("limit_metrics") / "limits2.urdf"
    path.write_text(urdf_text(), encoding="utf-8")
    return path


@pytest.fixture(scope="module")
def robot(urdf):
    return Robot.from_urdf(urdf)


def _laws(robot):
    return [pd_gravity_controller(robot, kp=KP, kd=KD, qf=[qf, 0.0]) for qf in TARGETS]


def _q0s():
    return np.zeros((len(TARGETS), 2))


def expected(robot, t, q, qd, qf):
    """The ``limits`` columns of one run from its samples, computed apart (loops, Pinocchio)."""
    model, data = robot.model, robot.model.createData()
    lower, upper = np.array([LOWER, -1.5]), np.array([UPPER, 1.5])
    depth = np.maximum(0.0, np.maximum(q - upper, lower - q).max(axis=0))
    over = np.zeros((t.size, 2))
    peak = np.zeros(2)
    for i in range(t.size):
        g = pin.computeGeneralizedGravity(model, data, robot.configuration(q[i]))
        demand = np.array(KP) * (qf - q[i]) - np.array(KD) * qd[i] + g
        over[i] = np.abs(demand) > np.array(EFFORT)
        peak = np.maximum(peak, np.abs(demand))
    time = np.zeros(2)
    for i in range(1, t.size):
        time += 0.5 * (over[i] + over[i - 1]) * (t[i] - t[i - 1])
    return {
        "limit_violation_q_j1": depth[0],
        "limit_violation_q_j2": depth[1],
        "saturation_time_tau_j1": time[0],
        "saturation_time_tau_j2": time[1],
        "peak_demand_tau_j1": peak[0],
        "peak_demand_tau_j2": peak[1],
    }


LIMIT_COLUMNS = (
    "limit_violation_q_j1", "limit_violation_q_j2", "saturation_time_tau_j1",
    "saturation_time_tau_j2", "peak_demand_tau_j1", "peak_demand_tau_j2",
)  # fmt: skip


def _close(name: str, got: float, want: float) -> bool:
    """Depths and demands agree to the runs' accuracy; saturated times exactly (no sample near
    the limit)."""
    if name.startswith("peak_demand"):
        return abs(got - want) <= RUNS * max(KP) * 10
    tol = RUNS if name.startswith("limit_violation") else 1e-12
    return abs(got - want) <= tol


@pytest.fixture(scope="module", params=[None, "odepack"])
def sweep(urdf, request):
    # the default method: the compiled backend's lanes (with numba); odepack: Pinocchio's batch
    method = {} if request.param is None else {"method": request.param}
    source = {
        "sweep": {"task": "simulate", "urdf": str(urdf), "tf": TF, "dt": DT, **method},
        "base": {"q0": [0.0, 0.0], "qf": [0.0, 0.0], "kp": list(KP), "kd": list(KD)},
        "vary": {"qf_1": list(TARGETS)},
        "keep": {"metrics": ["limits", "final_error"], "trajectories": [0, 1, 2]},
    }
    return source, run_chunk(source, 0, len(TARGETS))


def test_a_urdf_sweep_keeps_the_limits_columns_as_its_trajectories_say(sweep, robot):
    source, chunk = sweep
    if "method" not in source["sweep"]:
        assert plan(spec_from_dict(source)).backend == ("compiled" if HAS_NUMBA else "pinocchio")
    else:
        assert plan(spec_from_dict(source)).backend == "pinocchio"
    cols = chunk["columns"]
    assert set(LIMIT_COLUMNS) <= set(cols)
    for i, qf1 in enumerate(TARGETS):
        t, q, qd, _ = chunk["trajectories"][i]
        want = expected(robot, t, q, qd, np.array([qf1, 0.0]))
        for name in LIMIT_COLUMNS:
            assert _close(name, cols[name][i], want[name]), (i, name, cols[name][i], want[name])
    # the variants that overshoot cross their limit and saturate; the quiet one does neither
    assert cols["limit_violation_q_j1"][HIGH] > 5e-4 and cols["limit_violation_q_j1"][LOW] > 5e-4
    assert cols["saturation_time_tau_j1"][HIGH] > 0.1 and cols["saturation_time_tau_j2"][HIGH] > 0.0
    assert all(cols[name][QUIET] == 0.0 for name in LIMIT_COLUMNS if "demand" not in name)
    assert 0.0 < cols["peak_demand_tau_j1"][QUIET] <= EFFORT[0]  # it asked, within the limit
    assert cols["peak_demand_tau_j1"][HIGH] > EFFORT[0]  # it asked for more than it got
    assert cols["limit_violation_q_j2"][HIGH] == 0.0  # inside its limits


def test_the_limits_group_is_a_urdf_sweep_s_default_not_the_arm_s(urdf):
    urdf_spec = spec_from_dict(
        {"sweep": {"urdf": str(urdf), "tf": TF}, "base": {"q0": 0, "qf": 0, "kp": 1, "kd": 1}}
    )
    arm_spec = spec_from_dict({"sweep": {"tf": TF}})
    assert "limits" in urdf_spec.metrics and "limits" not in arm_spec.metrics
    inverse = spec_from_dict({"sweep": {"task": "inverse", "urdf": str(urdf), "tf": TF}})
    assert "limits" in inverse.metrics
    assert set(LIMIT_COLUMNS) <= set(metric_names(plan(urdf_spec)))


@needs_numba
@pytest.mark.parametrize("method", ["DOP853", "rk4"])
def test_compiled_limits_equal_pinocchio_s(robot, method):
    # DOP853: the compiled lanes (each variant its own steps) against Pinocchio's batch;
    # rk4: the compiled run_many's metrics against Pinocchio's, the same steps.
    t = time_grid(TF, DT)
    step = 1e-3 if method == "rk4" else None
    rows = {
        backend: simulate_batch(
            robot, _laws(robot), _q0s(), None, t, method=method, step=step, backend=backend,
            keep="metrics", estimate_error=False,
        ).metrics
        for backend in ("compiled", "pinocchio")
    }  # fmt: skip
    assert set(rows["compiled"]) == set(rows["pinocchio"])
    for name in LIMIT_COLUMNS:
        # depths and demands to the runs' accuracy (demand: the gains times it), times exactly
        tol = {"l": RUNS, "p": RUNS * max(KP) * 10}.get(name[0], 1e-12)
        np.testing.assert_allclose(
            rows["compiled"][name], rows["pinocchio"][name], rtol=0, atol=tol, err_msg=name
        )
    assert rows["compiled"]["saturation_time_tau_j1"][HIGH] > 0.1
    for name in (
        "final_error_q_j1",
        "peak_effort_tau_j1",
        "control_energy",
    ):  # the others still agree
        np.testing.assert_allclose(rows["compiled"][name], rows["pinocchio"][name], rtol=1e-5,
                                   atol=1e-6, err_msg=name)  # fmt: skip


@pytest.mark.parametrize("backend", ["pinocchio", pytest.param("compiled", marks=needs_numba)])
def test_a_batch_row_agrees_with_each_single_run_s_limit_events(robot, backend):
    t = time_grid(TF, DT)
    laws = _laws(robot)
    batch = simulate_batch(robot, laws, _q0s(), None, t, backend=backend, keep="metrics",
                           estimate_error=False).metrics  # fmt: skip
    for i, law in enumerate(laws):
        run = simulate(robot, law, _q0s()[i], None, t, backend=backend, estimate_error=False)
        found = dict.fromkeys(LIMIT_COLUMNS, 0.0)
        for e in run.limits:
            if e.kind == "position":
                found[f"limit_violation_q_{e.joint}"] = e.extent
            elif e.kind == "effort":
                found[f"saturation_time_tau_{e.joint}"] = e.saturated_time
                found[f"peak_demand_tau_{e.joint}"] = e.extent
        for k, name in enumerate(LIMIT_COLUMNS):
            if name.startswith("peak_demand") and found[name] == 0.0:  # no effort event:
                assert batch[name][i] <= EFFORT[k - 4]  # its demand stayed within the limit
                continue
            assert _close(name, batch[name][i], found[name]), (i, name, batch[name][i], found[name])
    assert batch["limit_violation_q_j1"][HIGH] > 0.0


@pytest.mark.parametrize("backend", ["pinocchio", pytest.param("compiled", marks=needs_numba)])
def test_limits_not_enforced_are_still_measured_against_the_urdf(robot, backend):
    t = time_grid(TF, DT)
    laws = _laws(robot)
    off = {"effort_limits": False, "position_limits": False, "backend": backend,
           "estimate_error": False}  # fmt: skip
    rows = simulate_batch(robot, laws, _q0s(), None, t, keep="metrics", **off).metrics
    full = simulate_batch(robot, laws, _q0s(), None, t, **off)
    # nothing saturated: the efforts kept are the law's demand; no stop: it goes further
    for i, qf1 in enumerate(TARGETS):
        want = expected(robot, t, full.q[i], full.qd[i], np.array([qf1, 0.0]))
        for name in LIMIT_COLUMNS:
            assert _close(name, rows[name][i], want[name]), (i, name, rows[name][i], want[name])
    assert np.abs(full.tau[HIGH, :, 0]).max() > EFFORT[0]  # the demand was not cut
    assert rows["limit_violation_q_j1"][HIGH] > 5e-3  # no compliant stop: well past the limit


def test_limits_not_given_and_continuous_measure_zero():
    # lower = upper = 0 and effort = 0: "not given"; the second joint continuous (no
    # position limit) with no effort limit
    xml = urdf_text(
        j1='lower="0" upper="0" effort="0" velocity="0"', j2='effort="0" velocity="0"'
    ).replace('<joint name="j2" type="revolute"', '<joint name="j2" type="continuous"')
    model = pin.buildModelFromXML(xml)
    robot = Robot.from_model(model)
    stated = physical_model(robot)
    rng = np.random.default_rng(5)
    t = time_grid(0.5, 0.05)
    q = rng.normal(0.0, 5.0, (2, t.size, 2))  # far from any range a limit would have
    tau = rng.normal(0.0, 1e3, q.shape)
    names = (("q_j1", "q_j2"), ("tau_j1", "tau_j2"))
    cols = batch_metrics(("limits",), t, q, q, tau, None, *names, stated=stated)
    assert set(cols) == set(LIMIT_COLUMNS)
    assert all((cols[name] == 0.0).all() for name in LIMIT_COLUMNS if "demand" not in name)
    for k, name in enumerate(names[1]):  # the demand is measured with or without a limit
        np.testing.assert_array_equal(cols[f"peak_demand_{name}"], np.abs(tau[:, :, k]).max(1))
    # the same samples against the robot's stated limits do cross
    limited = Robot.from_model(pin.buildModelFromXML(urdf_text()))
    crossed = batch_metrics(("limits",), t, q, q, tau, None, *names, stated=physical_model(limited))
    assert (crossed["limit_violation_q_j1"] > 0).all()
    assert (crossed["saturation_time_tau_j2"] > 0).all()


@needs_numba
def test_the_arm_has_the_columns_and_they_are_zero():
    # its URDF states no binding limit; its compiled metrics row fills them with 0
    source = {"sweep": {"tf": 0.5, "dt": 0.05}, "vary": {"m3": [30.0, 50.0]},
              "keep": {"metrics": ["limits", "final_error"]}}  # fmt: skip
    cols = run_chunk(source, 0, 2)["columns"]
    arm = chapter_arm()
    for name in [*(f"limit_violation_{q}" for q in arm.q_names),
                 *(f"saturation_time_{e}" for e in arm.effort_names)]:  # fmt: skip
        assert (cols[name] == 0.0).all(), name
    for e in arm.effort_names:  # nothing saturates: the demand is the effort applied
        assert (cols[f"peak_demand_{e}"] > 0).all(), e
    assert (cols["final_error_q1"] > 0).all()
