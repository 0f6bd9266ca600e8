"""Continuous joints: Pinocchio stores (cos θ, sin θ), rrt-pin integrates and reports θ."""

from __future__ import annotations

import numpy as np
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.grid import time_grid
from rrt_pin.io.csvio import read_csv
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import example_robot_data_dir, get
from rrt_pin.simulate import simulate, simulate_batch
from rrt_pin.simulate.control import pd_gravity_controller

ARM = """<?xml version="1.0"?>
<robot name="swing">
  <link name="base"/>
  <joint name="shoulder" type="{kind}"><parent link="base"/><child link="upper"/>
    <axis xyz="0 1 0"/>{limit}</joint>
  <link name="upper"><inertial><origin xyz="0 0 -0.4"/><mass value="3"/>
    <inertia ixx="0.16" ixy="0" ixz="0" iyy="0.16" iyz="0" izz="0.01"/></inertial></link>
  <joint name="elbow" type="{kind}"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0 -0.8"/><axis xyz="0 1 0"/>{limit}</joint>
  <link name="lower"><inertial><origin xyz="0 0 -0.3"/><mass value="2"/>
    <inertia ixx="0.06" ixy="0" ixz="0" iyy="0.06" iyz="0" izz="0.01"/></inertial></link>
</robot>
"""
LIMIT = '<limit lower="-100" upper="100" effort="1000" velocity="100"/>'
TIGHT_RUN = {"rtol": 1e-12, "atol": 1e-14}


def _robot(tmp_path, kind):
    path = tmp_path / f"{kind}.urdf"
    path.write_text(ARM.format(kind=kind, limit=LIMIT if kind == "revolute" else ""))
    return Robot.from_urdf(path)


def test_coordinates_and_configurations_round_trip(tmp_path):
    robot = _robot(tmp_path, "continuous")
    assert (robot.nq, robot.nv) == (4, 2) and robot.has_continuous_joints
    theta = np.array([[0.3, -2.0], [3.0, 1.0]])
    q = robot.configuration(theta)
    np.testing.assert_allclose(q[:, 0::2], np.cos(theta)) and np.testing.assert_allclose(
        q[:, 1::2], np.sin(theta)
    )
    np.testing.assert_allclose(robot.coordinates(q), theta, rtol=0, atol=1e-15)
    assert robot.units["q_shoulder"] == "rad" and robot.units["tau_elbow"] == "N·m"


@pytest.mark.parametrize("method", ["odepack", "DOP853", "Radau", "rk4", "leapfrog"])
def test_a_continuous_joint_reproduces_the_revolute_answer(tmp_path, method):
    """The same arm with continuous and with revolute joints: the same motion to 1e-10.

    The swing goes past ±π, where the continuous joint's (cos, sin) wraps and the angle must not.
    """
    runs = []
    t = time_grid(3.0, 0.05)
    for kind in ("continuous", "revolute"):
        robot = _robot(tmp_path, kind)
        law = pd_gravity_controller(robot, [60.0, 30.0], [4.0, 2.0], [4.0, -3.5])
        options = TIGHT_RUN if method in ("odepack", "DOP853", "Radau") else {"step": 0.005}
        # the revolute twin's limits would bind its step; a continuous joint has none
        runs.append(simulate(robot, law, [0.2, 0.1], [0.0, 0.0], t, method=method,
                             position_limits=False, **options))  # fmt: skip
    cont, rev = runs
    assert cont.q_names == rev.q_names == ("q_shoulder", "q_elbow")
    assert cont.q[:, 0].max() > np.pi and cont.q[:, 1].min() < -np.pi  # past the wrap
    np.testing.assert_allclose(cont.q, rev.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(cont.tau, rev.tau, rtol=0, atol=1e-8)


def test_example_robot_data_double_pendulum_continuous_runs_as_its_revolute_twin():
    if example_robot_data_dir() is None:
        pytest.fail("example-robot-data is a test dependency")
    cont, rev = get("double_pendulum_continuous"), get("double_pendulum")
    assert [j.kind for j in cont.joints] == ["continuous"] * 2
    assert [j.kind for j in rev.joints] == ["revolute"] * 2
    t = time_grid(2.0, 0.02)
    out = []
    for robot in (cont, rev):
        law = pd_gravity_controller(robot, 20.0, 3.0, [np.pi + 0.5, -0.5])
        out.append(simulate(robot, law, [0.0, 0.0], None, t, **TIGHT_RUN))
    np.testing.assert_allclose(out[0].q, out[1].q, rtol=0, atol=1e-10)
    batch = simulate_batch(cont, [law_c := pd_gravity_controller(cont, 20.0, 3.0,
                                                                  [np.pi + 0.5, -0.5])] * 2,
                           np.zeros((2, 2)), None, t, **TIGHT_RUN)  # fmt: skip
    assert law_c.nv == 2
    np.testing.assert_allclose(batch.q[0], out[0].q, rtol=0, atol=1e-9)


def test_simulate_cli_on_a_continuous_arm_reports_angles(tmp_path, capsys):
    urdf = tmp_path / "continuous.urdf"
    urdf.write_text(ARM.format(kind="continuous", limit=""))
    out = tmp_path / "run.csv"
    argv = ["simulate", "--urdf", str(urdf), "--q0", "0.2,0.1", "--qf", "4,-3.5"]
    argv += ["--kp", "60,30", "--kd", "8,4", "--tf", "10", "--csv", str(out)]
    assert main(argv) == 0
    header, data = read_csv(out)
    assert header[:3] == ["t", "q_shoulder", "q_elbow"] and data.shape == (1001, 7)
    # angles, not (cos, sin): they end near the target 4 rad (> π), unwrapped
    np.testing.assert_allclose(data[-1, 1:3], [4.0, -3.5], atol=1e-3)
    assert np.abs(np.diff(data[:, 1])).max() < 0.5
    # the viewer plays the same CSV back as Pinocchio configurations
    from rrt_pin.viewer.playback import motion_keyframes

    frames = motion_keyframes(Robot.from_urdf(urdf), str(out), 30.0)
    assert frames.q.shape == (301, 4)
    np.testing.assert_allclose(np.hypot(frames.q[:, 0], frames.q[:, 1]), 1.0, atol=1e-12)
    capsys.readouterr()


def test_joints_command_lists_continuous_joints(capsys, tmp_path):
    urdf = tmp_path / "continuous.urdf"
    urdf.write_text(ARM.format(kind="continuous", limit=""))
    assert main(["joints", "--urdf", str(urdf)]) == 0
    text = capsys.readouterr().out
    assert "swing: 2 joints, 2 coordinates" in text
    assert "shoulder" in text and "continuous" in text and "q_shoulder" in text
