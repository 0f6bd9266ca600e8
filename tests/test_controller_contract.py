"""The controller contract: time reaches the law, any law runs in simulate and simulate_batch,
and a computed-torque law tracks eq. (30)."""

from __future__ import annotations

import numpy as np
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.trajectory import RestToRest, rest_to_rest
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import simulate, simulate_batch
from rrt_pin.simulate.control import (
    Controller,
    TrackingController,
    as_controller,
    chapter_controller,
    regulator,
    tracking_controller,
)
from rrt_pin.simulate.reference import reference_run
from tests.support import robot_urdf

TRACKED = 1e-6  # max |q − q_d(t)| of computed torque along eq. (30) [rad, m]


@pytest.fixture(scope="module")
def arm():
    return chapter_arm()


class Disturbed(Controller):
    """Eq. (31) plus a time-varying disturbance d(t) = a·sin(ω·t) on joint 1 [N·m]."""

    def __init__(self, arm, amplitude=40.0, omega=2.0):
        self.law = chapter_controller(arm.params)
        self.amplitude, self.omega = amplitude, omega

    @property
    def nv(self):
        return 3

    def efforts(self, t, q, qd):
        tau = self.law.efforts(t, q, qd)
        tau[0] += self.amplitude * np.sin(self.omega * t)
        return tau


def test_time_reaches_the_law(arm):
    """A disturbance that depends on t alone changes the run, exactly as an independent solver says."""
    t = time_grid(5.0, 0.05)
    law = Disturbed(arm)
    run = simulate(arm, law, arm.defaults.q0, arm.defaults.qd0, t, rtol=1e-11, atol=1e-13)
    ref = reference_run(arm.model, law, arm.defaults.q0, arm.defaults.qd0, t, methods=("DOP853",))
    assert np.abs(run.q - ref.q).max() < 1e-8
    calm = simulate(arm, chapter_controller(arm.params), arm.defaults.q0, arm.defaults.qd0, t)
    assert np.abs(run.q[:, 0] - calm.q[:, 0]).max() > 1e-3  # the disturbance did something
    # the efforts reported are the law's at each output time, disturbance included
    expected = np.array([law.efforts(s, q, v) for s, q, v in zip(t, run.q, run.qd, strict=True)])
    np.testing.assert_allclose(run.tau, expected, rtol=1e-12, atol=1e-9)


@pytest.mark.parametrize("form", ["function", "object", "subclass"])
def test_any_law_following_the_contract_runs_in_a_batch(arm, form):
    """Functions f(t, q, qd), duck-typed objects and subclasses: batch variants equal single runs."""
    base = Disturbed(arm)
    if form == "function":
        law = base.efforts
    elif form == "object":

        class Duck:
            nv = 3

            def efforts(self, t, q, qd):
                return list(base.efforts(t, q, qd))  # a list is accepted and converted

        law = Duck()
    else:
        law = base
    t = time_grid(2.0, 0.1)
    q0s = np.array(arm.defaults.q0) + np.array([[0.0, 0.0, 0.0], [0.05, -0.05, 0.02]])
    batch = simulate_batch(arm, law, q0s, None, t, rtol=1e-11, atol=1e-13)
    for i in range(2):
        one = simulate(arm, law, q0s[i], None, t, rtol=1e-11, atol=1e-13)
        np.testing.assert_allclose(batch.q[i], one.q, rtol=0, atol=1e-8)
        np.testing.assert_allclose(batch.tau[i], one.tau, rtol=1e-8, atol=1e-6)


def test_computed_torque_tracks_eq30(arm):
    """Tracking the chapter's motion from its start: q(t) stays on q_d(t) to 1e-6."""
    d = arm.defaults
    motion = RestToRest(d.q0, d.qf, d.Tp)
    law = tracking_controller(arm, motion, kp=400.0, kd=40.0)
    t = time_grid(d.Tp, 0.05)
    run = simulate(arm, law, d.q0, d.qd0, t)
    planned = rest_to_rest(d.q0, d.qf, d.Tp, t)
    assert np.abs(run.q - planned.q).max() <= TRACKED
    assert np.abs(run.qd - planned.qd).max() <= 10 * TRACKED
    # feed-forward: on the motion, the efforts are the inverse dynamics of the motion
    from rrt_pin.dynamics.inverse import inverse_dynamics

    tau = inverse_dynamics(arm, planned.q, planned.qd, planned.qdd)
    assert np.abs(run.tau - tau).max() <= 1e-3 * np.abs(tau).max()


def test_computed_torque_recovers_from_an_offset_in_a_batch(arm):
    """Started off the motion, the error decays as ë + kd·ė + kp·e = 0 (critically damped)."""
    d = arm.defaults
    law = TrackingController(arm, RestToRest(d.q0, d.qf, d.Tp), kp=100.0, kd=20.0)
    t = time_grid(3.0, 0.01)
    offsets = np.array([[0.0, 0.0, 0.0], [0.02, -0.01, 0.005]])
    batch = simulate_batch(arm, law, np.array(d.q0) + offsets, None, t)
    planned = rest_to_rest(d.q0, d.qf, d.Tp, t).q
    e0 = offsets[1]
    expected = e0 * ((1 + 10 * t) * np.exp(-10 * t))[:, None]  # critically damped, ω = 10 rad/s
    np.testing.assert_allclose(batch.q[1] - planned, expected, rtol=0, atol=1e-6)
    assert np.abs(batch.q[0] - planned).max() <= TRACKED


def test_tracking_a_sampled_trajectory_on_another_robot():
    from rrt_pin.robot.robot import Robot

    robot = Robot.from_urdf(robot_urdf("ur5"))
    q0, qf = np.zeros(6), np.array([0.3, -0.4, 0.5, 0.0, 0.2, 0.1])
    t = time_grid(2.0, 0.01)
    samples = rest_to_rest(q0, qf, 2.0, time_grid(2.0, 0.001))
    run = simulate(robot, tracking_controller(robot, samples), q0, None, t)
    # linear interpolation of 1 ms samples: the reference itself is off by ~1e-6
    assert np.abs(run.q - rest_to_rest(q0, qf, 2.0, t).q).max() < 1e-5


def test_regulator_of_a_robot_is_its_default_law(arm):
    law = regulator(arm)
    assert law.kind == "chapter" and law.kp == arm.defaults.kp
    from rrt_pin.robot.robot import Robot

    ur5 = Robot.from_urdf(robot_urdf("ur5"))
    with pytest.raises(InputError, match="no default kp, kd, qf"):
        regulator(ur5)
    assert regulator(ur5, kp=1.0, kd=1.0, qf=np.zeros(6)).kind == "pd_gravity"


@pytest.mark.parametrize(
    "obj, words",
    [
        (3.0, "controller must be a Controller"),
        (lambda q: q, "must take (t, q, qd)"),
        (lambda t, q, qd: None, "returned None"),
        (lambda t, q, qd: [1.0, 2.0], "returned shape (2,)"),
    ],
)
def test_bad_laws_are_refused_in_one_line(arm, obj, words):
    with pytest.raises(InputError) as info:
        law = as_controller(obj, 3)
        simulate(arm, law, arm.defaults.q0, None, [0.0, 0.1])
    assert words in str(info.value) and "\n" not in str(info.value)


def test_a_law_for_another_robot_is_refused(arm):
    class Two(Controller):
        nv = 2

        def efforts(self, t, q, qd):
            return np.zeros(2)

    with pytest.raises(InputError, match="drives 2 joints but the robot has 3"):
        simulate(arm, Two(), arm.defaults.q0, None, [0.0, 0.1])


def test_passive_motion_without_a_controller(arm):
    """controller=None: no effort; energy is conserved (no damping, no input)."""
    from rrt_pin.simulate.symplectic import mechanical_energy

    t = time_grid(1.0, 0.01)
    run = simulate(arm, None, arm.defaults.q0, None, t, rtol=1e-12, atol=1e-14)
    assert (run.tau == 0).all()
    energy = mechanical_energy(arm.model, run.q, run.qd)
    assert np.abs(energy - energy[0]).max() <= 1e-8 * np.abs(energy).max()
