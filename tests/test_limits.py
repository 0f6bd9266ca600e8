"""A robot's limits, damping and friction: applied as its URDF says, and every crossing reported."""

import json
import math
from dataclasses import replace

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.robot.limits import (
    LIMIT_OMEGA,
    LimitWarning,
    applied_efforts,
    applied_jacobian,
    applier,
    gravity_bound,
    losses,
    physical_model,
    within,
)
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm, get
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import pd_gravity_controller, seed_controller
from rrt_pin.simulate.crossings import limit_events
from rrt_pin.simulate.symplectic import mechanical_energy

G = 9.81
#: The slider's fall to its lower limit [m].
DROP = 0.2

_LINK = (
    '<link name="{name}"><inertial><origin xyz="{com}"/><mass value="{m}"/>'
    '<inertia ixx="{i}" iyy="{i}" izz="{i}" ixy="0" ixz="0" iyz="0"/></inertial></link>'
)


def _joint(name, kind, parent, child, xyz, axis, limit, dynamics=""):
    return (
        f'<joint name="{name}" type="{kind}"><parent link="{parent}"/><child link="{child}"/>'
        f'<origin xyz="{xyz}"/><axis xyz="{axis}"/><limit {limit}/>{dynamics}</joint>'
    )


def slider(lower=-DROP, upper=1.0, damping=0.0, friction=0.0, effort=100.0):
    """A 2 kg body on a vertical prismatic joint (gravity along −z)."""
    dyn = f'<dynamics damping="{damping}" friction="{friction}"/>'
    xml = (
        '<robot name="slider"><link name="base"/>'
        + _LINK.format(name="body", com="0 0 0", m=2.0, i=0.01)
        + _joint("slide", "prismatic", "base", "body", "0 0 0", "0 0 1",
                 f'lower="{lower}" upper="{upper}" effort="{effort}" velocity="10"', dyn)
        + "</robot>"
    )  # fmt: skip
    return Robot.from_model(pin.buildModelFromXML(xml))


def pendulum2(damping=(0.3, 0.2), limit=100.0, effort=1000.0):
    """Two revolute joints about y, links 0.5 m, 1 kg each."""
    lim = f'lower="-{limit}" upper="{limit}" effort="{effort}" velocity="1000"'
    xml = (
        '<robot name="p2"><link name="base"/>'
        + _LINK.format(name="l1", com="0 0 -0.25", m=1.0, i=0.02)
        + _LINK.format(name="l2", com="0 0 -0.25", m=1.0, i=0.02)
        + _joint("j1", "revolute", "base", "l1", "0 0 0", "0 1 0", lim,
                 f'<dynamics damping="{damping[0]}"/>')
        + _joint("j2", "revolute", "l1", "l2", "0 0 -0.5", "0 1 0", lim,
                 f'<dynamics damping="{damping[1]}"/>')
        + "</robot>"
    )  # fmt: skip
    return Robot.from_model(pin.buildModelFromXML(xml))


def test_applier_equals_the_definition():
    rng = np.random.default_rng(3)
    robot = pendulum2(limit=0.5, effort=3.0)
    p = physical_model(robot).at(np.array([0.4, 0.1]))
    for _ in range(20):
        tau, q, qd = rng.normal(0, 5, 2), rng.normal(0, 1, 2), rng.normal(0, 2, 2)
        np.testing.assert_array_equal(applier(p)(tau, q, qd), applied_efforts(tau, q, qd, p))


def test_applied_jacobian_matches_finite_differences():
    robot = pendulum2(limit=0.5, effort=3.0)
    p = physical_model(robot).at(np.array([0.4, 0.1]))
    kp, kd = np.diag([2.0, 50.0]), np.diag([0.5, 0.7])
    q, qd = np.array([0.2, 0.6]), np.array([-0.3, 0.4])  # joint 2 past its limit, law saturated

    def law(q, qd):
        return -kp @ q - kd @ qd

    dq, dv = applied_jacobian(law(q, qd), -kp, -kd, q, qd, p)
    h = 1e-7
    for j in range(2):
        e = np.eye(2)[j] * h
        fq = (applied_efforts(law(q + e, qd), q + e, qd, p)
              - applied_efforts(law(q - e, qd), q - e, qd, p)) / (2 * h)  # fmt: skip
        fv = (applied_efforts(law(q, qd + e), q, qd + e, p)
              - applied_efforts(law(q, qd - e), q, qd - e, p)) / (2 * h)  # fmt: skip
        np.testing.assert_allclose(dq[:, j], fq, rtol=1e-6, atol=1e-6)
        np.testing.assert_allclose(dv[:, j], fv, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("dt", [0.01, 0.001])
def test_a_slider_falls_onto_its_limit_at_the_closed_form_time(dt):
    robot = slider()
    t = time_grid(0.4, dt)
    r = simulate(robot, None, [0.0], None, t, estimate_error=False)
    contact = math.sqrt(2 * DROP / G)
    (event,) = [e for e in r.limits if e.kind == "position"]
    assert event.joint == "slide" and event.unit == "m" and event.count >= 1
    assert contact <= event.first_time <= contact + dt
    # the compliant limit holds it within millimetres (v/(e·ω) for a critically damped stop)
    v = math.sqrt(2 * G * DROP)
    assert 0.0 < event.extent <= 1.2 * v / (math.e * LIMIT_OMEGA)
    free = simulate(robot, None, [0.0], None, t, estimate_error=False, position_limits=False)
    assert free.q.min() < -DROP - 0.3  # without the limit it falls through


def test_a_pendulum_released_onto_its_limit_at_the_closed_form_time():
    """A physical pendulum released at rest from θ0 reaches its limit −a at t = (K + F(φ))/ω0."""
    from scipy.special import ellipk, ellipkinc

    m, length, i_com, theta0, a = 1.5, 0.4, 0.01, 2.0, 1.0
    xml = (
        '<robot name="pendulum"><link name="base"/>'
        + _LINK.format(name="bob", com=f"0 0 {-length}", m=m, i=i_com)
        + _joint("swing", "revolute", "base", "bob", "0 0 0", "0 1 0",
                 f'lower="{-a}" upper="3" effort="100" velocity="100"')
        + "</robot>"
    )  # fmt: skip
    robot = Robot.from_model(pin.buildModelFromXML(xml))
    # θ'' = −ω0²·sin θ (θ from the hanging position); released at rest from θ0:
    # t(θ) = (K(k) + F(φ, k)) / ω0 on the far side, k = sin(θ0/2), sin φ = sin(a/2) / k
    omega0 = math.sqrt(m * G * length / (i_com + m * length**2))
    k2 = math.sin(theta0 / 2) ** 2
    phi = math.asin(math.sin(a / 2) / math.sqrt(k2))
    contact = (ellipk(k2) + ellipkinc(phi, k2)) / omega0
    dt = 1e-3
    t = time_grid(1.5, dt)
    r = simulate(robot, None, [theta0], None, t, rtol=1e-12, atol=1e-14, estimate_error=False)
    (event,) = [e for e in r.limits if e.kind == "position"]
    assert event.joint == "swing" and event.unit == "rad"
    assert contact <= event.first_time <= contact + dt
    # before the contact the run is the free pendulum: its energy is kept to the tolerance
    before = t < contact
    q, qd = r.q[before, 0], r.qd[before, 0]
    energy = 0.5 * (i_com + m * length**2) * qd**2 - m * G * length * np.cos(q)
    assert np.abs(energy - energy[0]).max() <= 1e-9 * m * G * length
    free = simulate(robot, None, [theta0], None, t, estimate_error=False, position_limits=False)
    assert free.q[:, 0].min() < -a - 0.5  # without the limit it swings on


def test_viscous_damping_dissipates_exactly_what_it_removes():
    robot = pendulum2()
    d = physical_model(robot).damping
    t = time_grid(0.4, 2e-5)
    r = simulate(robot, None, [1.0, -0.5], [0.0, 2.0], t, rtol=1e-13, atol=1e-15,
                 estimate_error=False)  # fmt: skip
    energy = mechanical_energy(robot.model, r.q, r.qd)
    power = (d * r.qd**2).sum(axis=1)
    dissipated = np.concatenate(([0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))))
    assert dissipated[-1] > 0.1  # a real loss
    assert np.abs(energy - energy[0] + dissipated).max() <= 1e-8 * dissipated[-1]
    undamped = simulate(robot, None, [1.0, -0.5], [0.0, 2.0], t[:2001], rtol=1e-13,
                        atol=1e-15, estimate_error=False, losses=False)  # fmt: skip
    drift = mechanical_energy(robot.model, undamped.q, undamped.qd)
    assert np.abs(drift - drift[0]).max() < 1e-9 * dissipated[-1]


def test_a_compliant_limit_never_adds_energy():
    robot = slider()
    p = physical_model(robot).at(np.array([2.0]))
    t = time_grid(0.4, 1e-4)
    r = simulate(robot, None, [0.0], None, t, rtol=1e-12, atol=1e-14, estimate_error=False)
    depth = np.maximum(-DROP - r.q[:, 0], 0.0)
    total = mechanical_energy(robot.model, r.q, r.qd) + 0.5 * p.stiffness[0] * depth**2
    scale = 2.0 * G * DROP
    assert (np.diff(total) <= 1e-9 * scale).all()
    before = total[t <= math.sqrt(2 * DROP / G)][-1]
    assert total[-1] < before - 0.5 * scale  # the stop took most of the energy


def test_efforts_are_saturated_and_the_demand_reported():
    robot = pendulum2(effort=2.0, damping=(0.0, 0.0))
    law = pd_gravity_controller(robot, 100.0, 10.0, [1.0, 0.0])
    t = time_grid(1.0, 0.01)
    r = simulate(robot, law, [0.0, 0.0], None, t, estimate_error=False)
    assert np.abs(r.tau).max() == 2.0
    demanded = law.efforts_many(t, r.q, r.qd)
    np.testing.assert_array_equal(r.tau, np.clip(demanded, -2.0, 2.0))
    (event,) = [e for e in r.limits if e.kind == "effort" and e.joint == "j1"]
    assert event.extent == np.abs(demanded[:, 0]).max() > 2.0
    assert event.first_time == 0.0 and 0.0 < event.saturated_time <= 1.0
    assert event.unit == "N·m"
    free = simulate(robot, law, [0.0, 0.0], None, t, estimate_error=False, effort_limits=False)
    assert np.abs(free.tau).max() > 50.0


def test_the_chapter_arm_is_bit_identical_with_and_without_the_switches():
    p = Params()
    t = time_grid(1.0, 0.01)
    off = {"effort_limits": False, "position_limits": False, "losses": False}
    for robot in (chapter_arm(p), Robot.from_model(chapter_arm(p).model)):
        a = simulate(robot, seed_controller(p), p.q0, p.qd0, t, estimate_error=False)
        b = simulate(robot, seed_controller(p), p.q0, p.qd0, t, estimate_error=False, **off)
        assert np.array_equal(a.table(), b.table()) and a.n_evals == b.n_evals
        assert a.limits == ()


def test_a_passive_ur5_stops_at_its_elbow_limit():
    robot = get("ur5")
    q0 = [0.0, -1.0, 1.0, 0.3, 0.5, 0.0]
    t = time_grid(1.6, 0.01)
    held = simulate(robot, None, q0, None, t, estimate_error=False)
    assert np.abs(held.q[:, 2]).max() <= math.pi + 0.02
    assert any(e.joint == "elbow_joint" and e.kind == "position" for e in held.limits)
    free = simulate(robot, None, q0, None, t, estimate_error=False, position_limits=False)
    assert np.abs(free.q[:, 2]).max() > math.pi + 0.5


def test_a_start_outside_the_limits_warns():
    robot = pendulum2(limit=1.0)
    with pytest.warns(
        LimitWarning, match=r"q0 of joint 'j1' is 90 rad, outside \[-1, 1\]: given in degrees\?"
    ):  # noqa: E501
        simulate(robot, None, [90.0, 0.0], None, time_grid(0.001, 0.001), estimate_error=False)


def test_a_fixed_step_too_long_for_the_limits_is_refused():
    robot = slider()
    t = time_grid(0.3, 0.01)
    with pytest.raises(InputError, match="step=0.01 s is too long .* joint 'slide'.* 0.0025 s"):
        simulate(robot, None, [0.05], None, t, method="rk4")
    r = simulate(robot, None, [0.05], None, t, method="rk4", step=0.0025, estimate_error=False)
    assert -DROP - 0.01 < r.q[-1, 0] < -DROP  # held at the limit
    free = simulate(robot, None, [0.05], None, t, method="rk4", position_limits=False,
                    estimate_error=False)  # fmt: skip
    assert free.q[-1, 0] < -DROP - 0.1


def test_crossings_count_separate_runs_past_a_limit():
    robot = pendulum2(limit=1.0, effort=5.0)
    p = physical_model(robot)
    t = np.arange(6) * 0.5
    q = np.array([[0, 0], [1.5, 0], [0.5, 0], [1.2, 0], [1.1, 0], [0, -1.3]], dtype=float)
    qd = np.zeros_like(q)
    demanded = np.array([[6, 0], [6, 0], [0, 0], [0, 0], [0, 0], [0, 0]], dtype=float)
    events = limit_events(t, q, qd, demanded, p, ["j1", "j2"], ["rad", "rad"])
    by = {(e.joint, e.kind): e for e in events}
    assert by["j1", "position"].count == 2 and by["j1", "position"].first_time == 0.5
    assert by["j1", "position"].extent == 0.5
    assert (
        by["j2", "position"].first_time == 2.5
        and by["j2", "position"].extent == 0.30000000000000004
    )
    effort = by["j1", "effort"]
    assert (effort.extent, effort.count, effort.saturated_time) == (6.0, 1, 0.75)
    assert ("j1", "velocity") not in by


def test_the_cli_flags_and_summary(tmp_path, capsys):
    urdf = tmp_path / "slider.urdf"
    urdf.write_text(
        '<robot name="slider"><link name="base"/>'
        + _LINK.format(name="body", com="0 0 0", m=2.0, i=0.01)
        + _joint("slide", "prismatic", "base", "body", "0 0 0", "0 0 1",
                 f'lower="{-DROP}" upper="1" effort="100" velocity="10"',
                 '<dynamics damping="0.1" friction="0.2"/>')
        + "</robot>"
    )  # fmt: skip
    base = ["simulate", "--urdf", str(urdf), "--passive", "--q0", "0", "--tf", "0.4",
            "--no-error-estimate"]  # fmt: skip
    assert main([*base, "--json", str(tmp_path / "s.json")]) == 0
    out, err = capsys.readouterr()
    line = next(x for x in out.splitlines() if x.startswith("slide") and "position" in x)
    assert "past by" in line and " m " in line
    doc = json.loads((tmp_path / "s.json").read_text())
    physical = doc["metadata"]["physical"]
    assert physical["omega"] == LIMIT_OMEGA and physical["friction_coefficient"] == [0.2]
    assert doc["summary"]["limits"][0]["kind"] == "position"
    assert main([*base, "--no-position-limits", "--no-losses"]) == 0
    out, _ = capsys.readouterr()
    free = next(x for x in out.splitlines() if x.startswith("slide") and "position" in x)
    assert free != line
    assert main(["simulate", "--urdf", str(urdf), "--passive", "--q0", "-0.5", "--tf", "0.01",
                 "--no-error-estimate"]) == 0  # fmt: skip
    _, err = capsys.readouterr()
    assert "warning: q0 of joint 'slide' is -0.5 m, outside [-0.2, 1]" in err
    assert main(["simulate", "--urdf", str(urdf), "--passive", "--q0", "-0.5", "--tf", "0.01",
                 "--no-error-estimate", "-q"]) == 0  # fmt: skip
    assert capsys.readouterr().err == ""
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "omega = 200 rad/s" in text and "v = 0.001 rad/s or m/s" in text


# --------------------------------------------------------------------------
# The Pinocchio backend's shortcuts: the same model, at less cost
# --------------------------------------------------------------------------
def _states_within(p, rng, count):
    """``count`` random coordinates inside the position limits (±π where there are none)."""
    lo = np.where(np.isfinite(p.lower), p.lower, -math.pi)
    hi = np.where(np.isfinite(p.upper), p.upper, math.pi)
    return lo + (hi - lo) * rng.random((count, p.nv))


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_the_gravity_bound_holds_over_the_joints_ranges(name):
    robot = get(name)
    p = physical_model(robot)
    bound = gravity_bound(robot.model, p)
    data = robot.model.createData()
    q = _states_within(p, np.random.default_rng(5), 3000)
    seen = np.array([np.abs(pin.computeGeneralizedGravity(robot.model, data, x)) for x in q])
    assert np.isfinite(bound).all()
    assert (seen.max(axis=0) <= bound).all()
    heaviest = int(np.argmax(seen.max(axis=0)))
    assert bound[heaviest] <= 1.3 * seen[:, heaviest].max()  # a useful bound, not a huge one


def test_the_gravity_bound_of_a_prismatic_joint_is_its_weight_and_needs_limits_below():
    robot = slider()
    bound = gravity_bound(robot.model, physical_model(robot))
    weight = pin.computeGeneralizedGravity(robot.model, robot.model.createData(), np.zeros(1))
    assert bound[0] == pytest.approx(abs(weight[0]), rel=1e-8) and bound[0] >= abs(weight[0])
    panda = get("panda")
    free = gravity_bound(panda.model, physical_model(panda, position_limits=False))
    assert np.isinf(free[:7]).all()  # the fingers' travel is unknown: no bound above them
    assert np.isfinite(free[7:]).all()


def test_within_says_where_only_the_losses_act():
    rng = np.random.default_rng(4)
    robot = pendulum2(limit=0.5, effort=3.0, damping=(0.3, 0.0))
    p = replace(physical_model(robot), friction=np.array([0.0, 0.2])).at(np.array([0.4, 0.1]))
    inside, lose = within(p), losses(p)
    answers = set()
    for _ in range(200):
        tau, q, qd = rng.normal(0, 3, 2), rng.normal(0, 0.5, 2), rng.normal(0, 2, 2)
        expected = bool((np.abs(tau) <= 3.0).all() and (np.abs(q) <= 0.5).all())
        answers.add(expected)
        assert inside(tau, q) is expected
        if expected:
            np.testing.assert_array_equal(lose(tau, qd), applied_efforts(tau, q, qd, p))
        np.testing.assert_array_equal(applier(p)(tau, q, qd), applied_efforts(tau, q, qd, p))
    assert answers == {True, False}
    assert not inside(np.array([np.nan, 0.0]), np.zeros(2))
    assert not inside(np.zeros(2), np.array([0.0, np.nan]))
    assert losses(physical_model(robot, losses=False)) is None


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_gravity_folded_where_it_cannot_saturate_changes_nothing_but_rounding(name):
    from rrt_pin.simulate.closed_loop import BatchLoop, ClosedLoop

    robot = get(name)
    model, data = robot.model, robot.model.createData()
    qf = _states_within(physical_model(robot), np.random.default_rng(0), 1)[0]
    mass = np.diag(pin.crba(model, data, qf))
    law = pd_gravity_controller(robot, kp=100.0 * mass, kd=20.0 * mass, qf=qf)
    p = physical_model(robot).at(mass)
    rng = np.random.default_rng(6)
    # near the target (folded), far from it (saturated), past a limit (the stops push)
    offsets = np.concatenate([rng.normal(0, s, (20, robot.nv)) for s in (0.01, 1.0, 3.0)])
    q, qd = qf + offsets, rng.normal(0, 0.5, offsets.shape)
    expected = np.array([
        pin.aba(model, data, x, v, applied_efforts(law.efforts(0.0, x, v), x, v, p))
        for x, v in zip(q, qd, strict=True)
    ])  # fmt: skip
    loop = ClosedLoop(robot, law, p)
    one = loop.acceleration()
    folded = [
        loop.unsaturated(-loop.kd * v - loop.kp * (x - qf), x) for x, v in zip(q, qd, strict=True)
    ]
    assert 0 < sum(folded) < len(folded)  # both ways taken
    scale = np.abs(expected).max(axis=1, keepdims=True) + 1.0
    got = np.array([one(0.0, x, v) for x, v in zip(q, qd, strict=True)])
    assert (np.abs(got - expected) <= 1e-10 * scale).all()
    batch = BatchLoop(robot, [law] * len(q), 1, p).acceleration()(0.0, q, qd)
    assert (np.abs(batch - expected) <= 1e-10 * scale).all()


def test_a_ur5_run_that_hits_no_limit_is_the_law_alone_to_rounding():
    robot = get("ur5")
    qf = np.array([0.0, -1.2, 1.2, -1.0, -1.2, 0.0])
    mass = np.diag(pin.crba(robot.model, robot.model.createData(), qf))
    law = pd_gravity_controller(robot, kp=100.0 * mass, kd=20.0 * mass, qf=qf)
    t = time_grid(2.0, 0.01)
    off = {"effort_limits": False, "position_limits": False, "losses": False}
    runs = [
        simulate(robot, law, qf + 0.3, None, t, method="DOP853", rtol=1e-10, atol=1e-12,
                 estimate_error=False, **switches)
        for switches in ({}, off)
    ]  # fmt: skip
    assert runs[0].limits == () and np.abs(runs[0].tau).max() > 50.0  # real efforts, none clipped
    assert np.abs(runs[0].q - runs[1].q).max() <= 1e-9


@pytest.mark.parametrize("seed", range(6))
def test_crossings_are_measured_as_the_samples_say(seed):
    """The extremes-first shortcut of ``crossings.measure`` changes nothing: every mask,
    extent and time equals the sample-by-sample definition, NaN samples included."""
    from rrt_pin.robot.limits import Physical
    from rrt_pin.simulate.crossings import measure

    rng = np.random.default_rng(seed)
    B, T, n = 3, 40, 4
    t = np.linspace(0.0, 2.0, T)
    reach = [0.0, 0.9, 1.2][seed % 3]  # none, some, most samples past the limits
    q = rng.uniform(-1.0, 1.0, (B, T, n)) * (1.0 + reach)
    qd = rng.uniform(-2.0, 2.0, (B, T, n)) * (1.0 + reach)
    tau = rng.uniform(-10.0, 10.0, (B, T, n)) * (1.0 + reach)
    if seed >= 3:  # NaN samples, and a column all NaN
        for a in (q, qd, tau):
            a[rng.random(a.shape) < 0.1] = np.nan
            a[0, :, 1] = np.nan
    p = Physical(np.full(n, -1.5), np.array([1.5, 1.5, np.inf, 1.8]), np.full(n, 12.0),
                 np.full(n, 2.5), np.zeros(n), np.zeros(n))  # fmt: skip
    got = measure(t, q, qd, tau, p)
    with np.errstate(invalid="ignore"):
        past = (q < p.lower) | (q > p.upper)
        depth = np.maximum(p.lower - q, q - p.upper)
    depth = np.maximum(np.nan_to_num(depth, nan=0.0, neginf=0.0).max(axis=1), 0.0)
    over = np.abs(tau) > p.effort
    s = over.astype(float)
    time = (0.5 * (s[:, 1:] + s[:, :-1]) * np.diff(t)[None, :, None]).sum(axis=1)
    np.testing.assert_array_equal(got["position"]["mask"], past)
    np.testing.assert_array_equal(got["position"]["extent"], depth)
    np.testing.assert_array_equal(got["effort"]["mask"], over)
    np.testing.assert_array_equal(got["effort"]["time"], time)
    np.testing.assert_array_equal(got["effort"]["extent"], np.abs(tau).max(axis=1))
    np.testing.assert_array_equal(got["velocity"]["mask"], np.abs(qd) > p.velocity)
    np.testing.assert_array_equal(got["velocity"]["extent"], np.abs(qd).max(axis=1))
    assert past.any() == (reach > 0.0)  # both branches are taken across the seeds


@pytest.mark.parametrize("seed", range(8))
def test_a_quiet_run_is_one_with_no_sample_past_a_limit(seed):
    """``crossings.quiet`` (one pass, the single run's shortcut to no events) says exactly
    whether the sample-by-sample definition finds nothing past a limit and no NaN; and
    ``limit_events`` gives, through it or not, the events ``measure`` finds."""
    from rrt_pin.robot.limits import Physical
    from rrt_pin.simulate.crossings import _events, measure, quiet

    rng = np.random.default_rng(100 + seed)
    T, n = 50, 3
    t = np.linspace(0.0, 1.0, T)
    p = Physical(np.array([-1.0, -np.inf, -2.0]), np.array([1.0, 2.0, np.inf]),
                 np.array([5.0, np.inf, 3.0]), np.array([4.0, 4.0, np.inf]), np.zeros(n),
                 np.zeros(n))  # fmt: skip
    q = rng.uniform(-0.9, 0.9, (T, n))
    qd = rng.uniform(-3.9, 3.9, (T, n))
    tau = rng.uniform(-2.9, 2.9, (T, n))
    kind = seed % 4  # 0: inside every limit; 1: a position past; 2: a demand; 3: a NaN
    if kind == 1:
        q[rng.integers(T), 0] = [-1.0 - 1e-12, 1.0 + 1e-12][seed // 4]  # just past
    elif kind == 2:
        tau[rng.integers(T), 2] = [3.0 + 1e-12, -3.5][seed // 4]
    elif kind == 3:
        [qd, tau][seed // 4][rng.integers(T), 1] = np.nan
    past = (q < p.lower) | (q > p.upper) | (np.abs(qd) > p.velocity) | (np.abs(tau) > p.effort)
    nan = np.isnan(q).any() or np.isnan(qd).any() or np.isnan(tau).any()
    assert quiet(q, qd, tau, p) == (not past.any() and not nan) == (kind == 0)
    assert quiet(q, qd, None, p) == (kind in (0, 2) or (kind == 3 and seed // 4 == 1))
    full = _events(t, measure(t, q[None], qd[None], tau[None], p), 0, ["a", "b", "c"], ["rad"] * 3)
    got = limit_events(t, q, qd, tau, p, ["a", "b", "c"], ["rad"] * 3)
    assert repr(got) == repr(full)  # (repr: a NaN extent equals itself there)
    assert (full == ()) == (kind in (0, 3))  # a NaN sample is not an event: only not quiet


@pytest.mark.parametrize("name", ["ur5", "panda"])
def test_a_limits_effective_inertia_is_one_over_the_inverse_mass_matrixs_diagonal(name):
    """limit_inertia reads M⁻¹'s diagonal from Pinocchio's computeMinverse; the same as
    inverting the CRBA mass matrix, at random configurations."""
    import pinocchio as pin

    from rrt_pin.robot import robots
    from rrt_pin.simulate.physical_runs import limit_inertia

    robot = robots.get(name)
    rng = np.random.default_rng(7)
    for _ in range(5):
        q = rng.uniform(-2.0, 2.0, robot.nv)
        upper = np.triu(pin.crba(robot.model, robot.model.createData(), robot.configuration(q)))
        mass = upper + np.triu(upper, 1).T
        expected = 1.0 / np.diag(np.linalg.inv(mass))
        np.testing.assert_allclose(limit_inertia(robot, q), expected, rtol=1e-10)


def test_a_compiled_batch_without_efforts_reports_its_limit_events_from_its_own(monkeypatch):
    """``efforts=False`` drops the efforts from the result, not from the limit events: a
    compiled batch makes them in its kernels, so the events come from those (no law is
    evaluated again in Python) and equal the events of the same batch with its efforts."""
    from rrt_pin.simulate import physical_runs, simulate_batch

    robot = get("ur5")
    qf = np.array([0.0, -1.2, 1.2, -1.0, -1.2, 0.0])
    law = pd_gravity_controller(robot, kp=2e4, kd=400.0, qf=qf)  # saturates 150 and 28 N·m
    t = time_grid(0.5, 0.01)
    q0s = qf + np.array([[0.3] * 6, [-0.2] * 6, [0.1] * 6])
    kw = {"backend": "compiled", "method": "DOP853", "rtol": 1e-8, "atol": 1e-10,
          "estimate_error": False, "threads": 1}  # fmt: skip
    full = simulate_batch(robot, law, q0s, None, t, **kw)

    def again(*args, **kwargs):
        raise AssertionError("the law's efforts were computed again")

    monkeypatch.setattr(physical_runs, "_demanded", again)
    bare = simulate_batch(robot, law, q0s, None, t, efforts=False, **kw)
    assert bare.tau is None and full.tau is not None
    np.testing.assert_array_equal(bare.q, full.q)
    assert bare.limits == full.limits
    assert all(any(e.kind == "effort" for e in events) for events in full.limits)


def test_a_change_to_the_models_limits_between_runs_is_read():
    """The physical model is kept per robot, but keyed by the model's values: a user's
    change to them after a first run applies to the next, as it did when read each time."""
    robot = slider(effort=100.0, damping=0.5)
    first = physical_model(robot)
    assert physical_model(robot) is first  # read once while nothing changes
    robot.model.effortLimit[0] = 7.0
    robot.model.damping[0] = 0.0
    robot.model.lowerPositionLimit[0] = -0.5
    now = physical_model(robot)
    assert (first.effort[0], first.damping[0], first.lower[0]) == (100.0, 0.5, -DROP)
    assert (now.effort[0], now.damping[0], now.lower[0]) == (7.0, 0.0, -0.5)
    off = physical_model(robot, effort_limits=False, losses=False)
    assert off.effort[0] == math.inf and off.lower[0] == -0.5
    robot.model.damping[0] = -1.0  # a bad value is refused again, not served from before
    with pytest.raises(InputError, match="damping of joint 'slide' is -1"):
        physical_model(robot)
