"""Any robot's compiled simulations (generated dynamics inside the compiled integrators).

Each run is checked against the Pinocchio backend (``pin.aba`` under SciPy's or
rrt-pin's own integrators, an independent computation of the same method): the
adaptive methods take the same steps up to round-off, the fixed-step ones the
same steps exactly.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

import rrt_pin  # noqa: E402
from rrt_pin.core.errors import DivergenceError, InputError  # noqa: E402
from rrt_pin.dynamics.trajectory import Trajectory  # noqa: E402
from rrt_pin.robot.robot import Robot  # noqa: E402
from rrt_pin.simulate.control import (  # noqa: E402
    OpenLoop,
    pd_gravity_controller,
    tracking_controller,
)
from tests.support import robot_urdf  # noqa: E402
from tests.test_generated_forward import random_tree  # noqa: E402

T = np.linspace(0.0, 1.0, 101)


@pytest.fixture(scope="module")
def ur5() -> Robot:
    return Robot.from_urdf(robot_urdf("ur5"))


@pytest.fixture(scope="module")
def tree() -> Robot:
    """Revolute (oblique axes), prismatic and continuous joints, branches, armature."""
    return Robot.from_model(random_tree(3, joints=4))


#: The law alone (the physical model has its own tests below and in tests/test_limits.py).
LAW_ONLY = {"effort_limits": False, "position_limits": False, "losses": False}


def _both(robot, law, q0, method, t=T, qd0=None, **options):
    options = {**LAW_ONLY, **options}
    runs = [
        rrt_pin.simulate(robot, law, q0, qd0, t, method=method, backend=b, estimate_error=False,
                         **options)
        for b in ("compiled", "pinocchio")
    ]  # fmt: skip
    return runs


def _pd(robot, gain=20.0):
    return pd_gravity_controller(robot, kp=gain, kd=2.0 * np.sqrt(gain), qf=np.zeros(robot.nv))


@pytest.mark.parametrize("method", ["DOP853", "RK45"])
def test_adaptive_runs_take_scipys_steps(ur5, method):
    q0 = np.array([0.3, -1.0, 1.0, 0.3, 0.5, 0.0])
    fast, engine = _both(ur5, _pd(ur5), q0, method, rtol=1e-10, atol=1e-12)
    assert fast.backend == "compiled" and engine.backend == "pinocchio"
    assert abs(fast.n_evals - engine.n_evals) <= 0.02 * engine.n_evals
    assert np.abs(fast.q - engine.q).max() < 1e-9
    assert np.abs(fast.qd - engine.qd).max() < 1e-8
    # efforts: the same law (PD plus G) at nearly the same states
    assert np.abs(fast.tau - engine.tau).max() < 1e-6 * (1.0 + np.abs(engine.tau).max())
    assert not np.allclose(fast.q[-1], q0)  # it moved


@pytest.mark.parametrize("method", ["rk4", "symplectic_euler", "verlet"])
def test_fixed_step_runs_equal_the_python_integrators(tree, method):
    q0 = np.array([0.2, -0.3, 0.05, 0.4])
    fast, engine = _both(tree, _pd(tree), q0, method, step=1e-3)
    assert fast.n_evals == engine.n_evals
    assert np.abs(fast.q - engine.q).max() < 1e-11
    assert np.abs(fast.qd - engine.qd).max() < 1e-10


def test_passive_tree_with_continuous_joints_keeps_angles(tree):
    q0 = np.array([3.0, -0.3, 0.05, 3.1])
    fast, engine = _both(tree, None, q0, "DOP853", t=np.linspace(0, 2, 201), rtol=1e-10, atol=1e-12)
    assert np.abs(fast.q - engine.q).max() < 1e-8
    assert np.abs(fast.q).max() > np.pi  # angles, not wrapped (cos, sin) pairs
    assert np.all(fast.tau == 0.0)


def test_tracking_a_sampled_motion(ur5):
    t = np.linspace(0.0, 1.0, 201)
    q = 0.3 * np.sin(np.outer(t, np.arange(1, 7)))
    qd = 0.3 * np.cos(np.outer(t, np.arange(1, 7))) * np.arange(1, 7)
    qdd = -0.3 * np.sin(np.outer(t, np.arange(1, 7))) * np.arange(1, 7) ** 2
    motion = Trajectory(t=t, q=q, qd=qd, qdd=qdd)
    law = tracking_controller(ur5, motion)
    fast, engine = _both(ur5, law, q[0], "DOP853", t=t, qd0=qd[0], rtol=1e-10, atol=1e-12)
    assert np.abs(fast.q - engine.q).max() < 1e-8
    assert np.abs(fast.tau - engine.tau).max() < 1e-6 * np.abs(engine.tau).max()
    assert np.abs(fast.q - q).max() < 1e-3  # and it tracks


def test_open_loop_efforts(tree):
    t = np.linspace(0.0, 1.0, 11)
    tau = np.column_stack([np.sin(3 * t + k) for k in range(tree.nv)])
    law = OpenLoop(t=t, tau=tau)
    fast, engine = _both(
        tree, law, np.zeros(tree.nv), "DOP853", t=np.linspace(0, 1.5, 151), rtol=1e-10, atol=1e-12
    )
    assert np.abs(fast.q - engine.q).max() < 1e-8
    np.testing.assert_allclose(fast.tau, engine.tau, rtol=0, atol=1e-14)


@pytest.mark.parametrize("keep", ["trajectories", "final", "metrics"])
def test_batches_equal_single_runs_on_any_thread_count(ur5, keep):
    rng = np.random.default_rng(5)
    q0s = rng.uniform(-1.0, 1.0, (6, 6))
    laws = [_pd(ur5, gain) for gain in (5.0, 10.0, 20.0, 5.0, 10.0, 20.0)]
    runs = [
        rrt_pin.simulate_batch(ur5, laws, q0s, None, T, backend="compiled", keep=keep,
                               threads=k, estimate_error=False)
        for k in (1, 2)
    ]  # fmt: skip
    assert np.array_equal(runs[0].q, runs[1].q) and np.array_equal(runs[0].tau, runs[1].tau)
    # a variant's bits do not depend on the variants beside it in the lanes
    order = [5, 2, 0]
    alone = rrt_pin.simulate_batch(ur5, [laws[b] for b in order], q0s[order], None, T,
                                   backend="compiled", keep=keep, estimate_error=False)  # fmt: skip
    assert np.array_equal(alone.q, runs[0].q[order])
    for b in (0, 4):
        one = rrt_pin.simulate(ur5, laws[b], q0s[b], None, T, backend="compiled",
                               estimate_error=False)  # fmt: skip
        kept = one.q if keep == "trajectories" else one.q[-1:]
        # the same steps (the lanes' polynomial sines and cosines against libm's in a
        # single run); "final" skips the dense output: its state is the last step's
        np.testing.assert_allclose(runs[0].q[b], kept, rtol=0, atol=1e-10)
    if keep == "metrics":
        engine = rrt_pin.simulate_batch(ur5, laws, q0s, None, T, keep="metrics",
                                        method="DOP853", estimate_error=False)  # fmt: skip
        for name, column in runs[0].metrics.items():
            np.testing.assert_allclose(column, engine.metrics[name], rtol=1e-6, atol=1e-9,
                                       err_msg=name)  # fmt: skip
        assert len(runs[0].metrics) == 8 * 6 + 1  # 8 columns a joint (limits too), the energy


def test_other_laws_are_refused_with_the_backend_that_runs_them(ur5):
    with pytest.raises(InputError, match="use backend 'pinocchio'"):
        rrt_pin.simulate(ur5, lambda t, q, qd: np.zeros(6), np.zeros(6), None, T,
                         backend="compiled")  # fmt: skip
    with pytest.raises(InputError, match="function of time runs on backend 'pinocchio'"):
        law = tracking_controller(ur5, lambda t: None)
        rrt_pin.simulate(ur5, law, np.zeros(6), None, T, backend="compiled")


def test_a_diverging_run_names_the_robots_coordinate(tree):
    law = pd_gravity_controller(tree, kp=1e9, kd=0.0, qf=np.zeros(tree.nv))
    with pytest.raises(DivergenceError) as e:
        rrt_pin.simulate(tree, law, np.full(tree.nv, 0.1), None, T, method="rk4", step=0.01,
                         backend="compiled", estimate_error=False, **LAW_ONLY)  # fmt: skip
    assert any(name in str(e.value) for name in (*tree.q_names, *tree.qd_names))


def test_lanes_leave_gravity_out_only_where_it_cannot_saturate(ur5):
    """Lanes that fold G(q) (PD within its room, no limit crossed) and lanes that saturate,
    side by side: each variant as the Pinocchio backend runs it, whatever its neighbours."""
    rng = np.random.default_rng(8)
    q0s = rng.uniform(-1.0, 1.0, (5, 6))
    laws = [_pd(ur5, gain) for gain in (10.0, 900.0, 10.0, 20.0, 900.0)]  # 900: saturates
    run = rrt_pin.simulate_batch(ur5, laws, q0s, None, T, backend="compiled",
                                 estimate_error=False)  # fmt: skip
    engine = rrt_pin.simulate_batch(ur5, laws, q0s, None, T, method="DOP853", rtol=1e-12,
                                    atol=1e-14, estimate_error=False)  # fmt: skip
    np.testing.assert_allclose(run.q, engine.q, rtol=0, atol=1e-7)
    assert (np.abs(run.tau[1]) >= ur5.model.effortLimit - 1e-9).any()  # saturated somewhere
    assert (np.abs(run.tau[0]) < 0.5 * ur5.model.effortLimit).all()  # never near the limit
    for group in ([0, 2], [1, 4, 3]):
        part = rrt_pin.simulate_batch(ur5, [laws[b] for b in group], q0s[group], None, T,
                                      backend="compiled", estimate_error=False)  # fmt: skip
        assert np.array_equal(part.q, run.q[group])


@pytest.mark.parametrize("keep", ["final", "metrics"])
def test_failures_recorded_leave_the_other_variants_as_they_were(ur5, keep):
    rng = np.random.default_rng(9)
    q0s = rng.uniform(-1.0, 1.0, (5, 6))
    laws = [_pd(ur5, g) for g in (5.0, 10.0, 1e300, 20.0, 5.0)]  # variant 2 overflows
    run = rrt_pin.simulate_batch(ur5, laws, q0s, None, T, backend="compiled", keep=keep,
                                 failures="record", estimate_error=False, **LAW_ONLY)  # fmt: skip
    assert [f is None for f in run.failures] == [True, True, False, True, True]
    assert isinstance(run.failures[2], DivergenceError)
    assert np.isnan(run.q[2]).all() and run.estimate_failure is None
    ok = [0, 1, 3, 4]
    others = rrt_pin.simulate_batch(ur5, [laws[i] for i in ok], q0s[ok], None, T,
                                    backend="compiled", keep=keep, estimate_error=False, **LAW_ONLY)  # fmt: skip
    assert np.array_equal(run.q[ok], others.q)  # the lanes keep each variant's bits
    assert run.evaluations.shape == (5,) and (run.evaluations[ok] > 0).all()
    if keep == "metrics":
        for name, column in others.metrics.items():
            assert np.array_equal(run.metrics[name][ok], column, equal_nan=True)
            assert np.isnan(run.metrics[name][2])
    with pytest.raises(DivergenceError, match=r"variant 2"):
        rrt_pin.simulate_batch(ur5, laws, q0s, None, T, backend="compiled", keep=keep,
                               estimate_error=False, **LAW_ONLY)  # fmt: skip


def test_failures_recorded_on_the_pinocchio_backend_one_variant_at_a_time(tree):
    q0s = np.array([[0.1, 0.2, 0.01, 0.3], [0.2, 0.1, 0.02, 0.1], [0.3, 0.0, 0.0, 0.2]])
    laws = [_pd(tree, 5.0), _pd(tree, 1e300), _pd(tree, 10.0)]
    run = rrt_pin.simulate_batch(tree, laws, q0s, None, T, method="DOP853", keep="final",
                                 failures="record", **LAW_ONLY)  # fmt: skip
    assert [f is None for f in run.failures] == [True, False, True]
    assert run.estimate_failure == "a variant failed" and np.isnan(run.q[1]).all()
    for i in (0, 2):
        one = rrt_pin.simulate(tree, laws[i], q0s[i], None, T, method="DOP853",
                               estimate_error=False, **LAW_ONLY)  # fmt: skip
        np.testing.assert_allclose(run.q[i, 0], one.q[-1], rtol=0, atol=1e-8)
    with pytest.raises(InputError, match="failures"):
        rrt_pin.simulate_batch(tree, laws, q0s, None, T, failures="ignore")


# --- the physical model (limits, damping, friction) in the compiled integrators ----------
def _physical_reference(robot, law, p, q0, t):
    """SciPy's DOP853 over pin.aba under applied_efforts (the model's numpy definition)."""
    import pinocchio as pin
    from scipy.integrate import solve_ivp

    from rrt_pin.robot.limits import applied_efforts

    model, data, nv = robot.model, robot.model.createData(), robot.nv

    def f(_t, y):
        q, v = y[:nv], y[nv:]
        tau = applied_efforts(law.efforts(0.0, q, v), q, v, p)
        return np.concatenate([v, pin.aba(model, data, robot.configuration(q), v, tau)])

    y0 = np.concatenate([q0, np.zeros(nv)])
    s = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", t_eval=t, rtol=1e-12, atol=1e-14)
    return s.y[:nv].T


@pytest.fixture(scope="module")
def ur5_physics(ur5):
    import dataclasses

    import pinocchio as pin

    from rrt_pin.robot.limits import physical_model

    q0 = np.array([0.0, -1.0, 2.9, 0.3, 0.5, 0.0])
    qf = np.array([0.5, -1.5, 3.6, 0.0, 0.0, 0.0])  # the elbow's target beyond its π limit
    law = pd_gravity_controller(ur5, kp=[400.0, 400.0, 400.0, 40.0, 40.0, 40.0], kd=40.0, qf=qf)
    p = physical_model(ur5)
    p = dataclasses.replace(p, damping=np.full(6, 0.5), friction=np.full(6, 0.8))
    M = pin.crba(ur5.model, ur5.model.createData(), q0)
    p = p.at(np.diag(M))
    t = np.linspace(0.0, 1.0, 201)
    return law, p, q0, t, _physical_reference(ur5, law, p, q0, t)


def test_the_compiled_runs_apply_limits_damping_and_friction(ur5, ur5_physics):
    from rrt_pin.compiled import robot_runs
    from rrt_pin.robot.limits import applied_efforts
    from rrt_pin.simulate.options import resolve

    law, p, q0, t, reference = ur5_physics
    options = resolve(t, backend="compiled", method="DOP853", rtol=1e-12, atol=1e-14)
    one = robot_runs.run_one(ur5, law, q0, np.zeros(6), t, options, physical=p)
    assert np.abs(one.q - reference).max() < 1e-8
    assert one.q[:, 2].max() > np.pi and one.q[:, 2].max() < np.pi + 0.02  # held at the limit
    demanded = np.array([law.efforts(0.0, q, v) for q, v in zip(one.q, one.qd, strict=True)])
    assert np.abs(demanded[:, 0]).max() > 150.0  # the law asks for more than the limit …
    np.testing.assert_allclose(one.tau, np.clip(demanded, -p.effort, p.effort), rtol=1e-12)
    free = robot_runs.run_one(ur5, law, q0, np.zeros(6), t, options)  # … and without the model
    assert free.q[:, 2].max() > np.pi + 0.1
    # the same in the lanes of a batch, with the variants beside it
    q0s = np.vstack([q0, q0 + 0.01, q0 - 0.01])
    batch = robot_runs.run_batch(ur5, [law] * 3, q0s, np.zeros((3, 6)), t, options, physical=p)
    assert np.abs(batch.q[0] - reference).max() < 1e-8
    assert np.abs(applied_efforts(demanded, one.q, one.qd, p) - demanded).max() > 1.0


def test_the_front_door_gives_both_backends_the_physical_model(ur5, ur5_physics):
    """simulate(..., backend=...) with the URDF's limits on: compiled and Pinocchio agree."""
    law, _, q0, t, _ = ur5_physics
    fast, engine = _both(ur5, law, q0, "DOP853", t=t, rtol=1e-11, atol=1e-13,
                         effort_limits=True, position_limits=True)  # fmt: skip
    assert np.abs(fast.q - engine.q).max() < 1e-8
    assert fast.q[:, 2].max() < np.pi + 0.02 and fast.q[:, 2].max() > np.pi  # held at π
    np.testing.assert_allclose(fast.tau, engine.tau, rtol=1e-6, atol=1e-6)
    assert np.abs(fast.tau[:, 0]).max() == pytest.approx(150.0)  # saturated


def test_a_robots_first_use_compiles_only_the_entry_it_runs(ur5, monkeypatch):
    """A batch of adaptive PD variants needs the lanes alone; a single run one entry alone:
    under PD plus gravity its law-bound copy, else the general one; an adaptive method's
    without the fixed-step integrators (``run_adaptive``), a fixed step's ``run_many``."""
    from rrt_pin.compiled import robot_code, robot_runs
    from rrt_pin.simulate.options import resolve

    asked = []

    class Code:  # stands for a robot's code not compiled yet: records what is compiled
        def entry(self, name):
            asked.append(name)

    monkeypatch.setattr(robot_code, "integrators_for", lambda model, name=None: Code())
    pd = _pd(ur5)
    t = np.linspace(0.0, 1.0, 11)
    dop853 = resolve(t, backend="compiled", method="DOP853", rtol=1e-9, atol=1e-11)
    rk4 = resolve(t, backend="compiled", method="rk4", step=1e-3)
    robot_runs.prepare(ur5, [pd, pd], dop853)
    robot_runs.prepare(ur5, [pd], dop853)
    robot_runs.prepare(ur5, [pd, pd], rk4)
    robot_runs.prepare(ur5, [pd, None], dop853)
    assert asked == ["run_lanes", "run_adaptive_pd", "run_many_pd", "run_adaptive"]
    with pytest.raises(InputError):  # refused before anything is compiled
        robot_runs.prepare(ur5, [lambda t, q, qd: q], dop853)
    assert len(asked) == 4
    # a robot's code object compiles nothing until an entry is asked for
    code = robot_code.RobotCode("r", 1, 0, object(), None, "")
    assert code._entries == {}


def test_the_lanes_call_pd_copies_that_name_no_other_laws_dynamics(ur5):
    """The lanes' first step and metrics reach PD plus gravity alone: a batch's first use
    compiles no tracking (M, bias) or open-loop (forward under given efforts) dynamics."""
    import re

    from rrt_pin.compiled.robot_code import module_source

    source, _ = module_source(ur5.model)

    def body(name):
        return re.search(rf"\ndef {name}\(.*?(?=\n@jit|\Z)", source, flags=re.DOTALL).group(0)

    lanes = body("run_lanes")
    assert "first_steps(" in lanes and "metrics_of_pd(" in lanes  # first steps in lanes too
    assert not re.search(r"\b(first_step|first_step_pd|metrics_of|rhs|efforts)\(", lanes)
    assert "stage_lanes(" in body("first_steps") and not re.search(
        r"\brhs\w*\(", body("first_steps")
    )
    assert "efforts_pd_law(" in body("metrics_of_pd")
    assert not re.search(r"\befforts\(", body("metrics_of_pd"))
    pd_law = body("efforts_pd_law") + body("rhs_pd_law")
    assert not re.search(r"\b(mass_matrix|bias|forward)\(", pd_law)


@pytest.mark.parametrize(
    "entry",
    ["run_many_pd", "run_adaptive_pd", "run_adaptive_rkc_pd", "run_adams_pd", "run_bdf_pd",
     "run_lanes", "run_lanes_rkc"],
)  # fmt: skip
def test_the_pd_entries_reach_no_other_laws_dynamics(ur5, entry):
    """Everything a PD entry calls, however deep, is PD plus gravity's: its first use
    compiles no tracking law (M, bias), open-loop or general law dispatch; the general
    entries do reach them (the walk sees through the calls)."""
    from rrt_pin.compiled.robot_code import module_source
    from tests.support import call_graph, reaches

    calls = call_graph(module_source(ur5.model)[0])

    def reached(name):
        return reaches(calls, name)

    other_laws = {"rhs", "efforts", "mass_matrix", "bias", "forward", "interp_at", "metrics_of"}
    assert reached(entry) & other_laws == set()
    if not entry.startswith("run_lanes"):  # the lanes have dynamics of their own
        assert "rhs_pd_law" in reached(entry)
        assert {"mass_matrix", "bias", "forward"} <= reached(entry.removesuffix("_pd"))
        # only the fixed-step methods' entry compiles their integrators
        general = entry.removesuffix("_pd")
        assert (
            ("fixed_pd" in reached(entry))
            == ("fixed" in reached(general))
            == (entry == "run_many_pd")
        )


def test_a_pd_run_on_its_own_entry_equals_the_general_entry_bit_for_bit(ur5, monkeypatch):
    """run_many_pd is run_many with the law's dispatch bound: the same bits."""
    from rrt_pin.compiled import robot_entries

    law = _pd(ur5)
    q0 = np.full(6, 0.2)
    own = rrt_pin.simulate(ur5, law, q0, None, T, backend="compiled", estimate_error=False)
    monkeypatch.setattr(robot_entries, "entry", lambda method, count, pd, numeric: "run_many")
    general = rrt_pin.simulate(ur5, law, q0, None, T, backend="compiled", estimate_error=False)
    for name in ("q", "qd", "tau"):
        np.testing.assert_array_equal(getattr(own, name), getattr(general, name))
    assert own.n_evals == general.n_evals


def test_the_cli_compiles_only_the_entry_its_run_takes(ur5, tmp_path, monkeypatch):
    """`rrt-pin simulate --backend compiled` loads the robot's code before the run, to report
    its cost apart: it compiles the entry the run then takes (DOP853 under PD plus gravity,
    here), and no other (it compiled the general `run_many` too, twice the first use)."""
    from rrt_pin.cli.app import main
    from rrt_pin.compiled import robot_code

    asked = []
    entry = robot_code.RobotCode.entry

    def recording(self, name):
        asked.append(name)
        return entry(self, name)

    monkeypatch.setattr(robot_code.RobotCode, "entry", recording)
    out = tmp_path / "run.csv"
    main(["simulate", "--robot", "ur5", "--backend", "compiled", "--tf", "0.1",
          "--q0", "0.3,-0.9,1.5,-0.7,-0.9,0.3", "--qf", "0,-1.2,1.2,-1,-1.2,0",
          "--kp", "184,311,85,24,25,1.7", "--kd", "37,62,17,4.8,5.1,0.34",
          "--csv", str(out)])  # fmt: skip
    assert out.stat().st_size > 0
    assert set(asked) == {"run_adaptive_pd"}
