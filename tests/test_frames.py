"""Frames along a motion: positions, quaternions, velocities and Jacobians against
Pinocchio's own calls, in Python (result.frame, result.jacobian) and as CSV columns."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.kinematics import frame_columns, frame_jacobian, frame_table
from rrt_pin.io.csvio import read_csv
from rrt_pin.robot.robots import chapter_arm, get
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import pd_gravity_controller

WORLD = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


@pytest.fixture(scope="module")
def ur5_run():
    ur5 = get("ur5")
    law = pd_gravity_controller(ur5, 100.0, 20.0, np.array([0.5, -0.4, 0.6, 0.2, -0.3, 0.1]))
    return ur5, simulate(ur5, law, np.zeros(6), None, time_grid(1.0, 0.05), estimate_error=False)


@pytest.mark.parametrize("name", ["tool0", "wrist_2_link", "shoulder_pan_joint"])
def test_frames_equal_pinocchios_placements_velocities_and_jacobians(ur5_run, name):
    ur5, run = ur5_run
    motion = run.frame(name, velocity=True)
    model, data = ur5.model, ur5.model.createData()
    f = model.getFrameId(name)
    for k in (0, 7, run.t.size - 1):
        pin.forwardKinematics(model, data, run.q[k], run.qd[k])
        pin.updateFramePlacements(model, data)
        placement = data.oMf[f]
        np.testing.assert_allclose(motion.position[k], placement.translation, rtol=0, atol=1e-14)
        rotation = pin.Quaternion(*np.roll(motion.quaternion[k], 1)).toRotationMatrix()
        np.testing.assert_allclose(rotation, placement.rotation, rtol=0, atol=1e-14)
        twist = pin.getFrameVelocity(model, data, f, WORLD)
        np.testing.assert_allclose(motion.linear_velocity[k], twist.linear, rtol=0, atol=1e-14)
        np.testing.assert_allclose(motion.angular_velocity[k], twist.angular, rtol=0, atol=1e-14)
        jac = run.jacobian(name, k)
        ref = pin.computeFrameJacobian(model, model.createData(), run.q[k], f, WORLD)
        np.testing.assert_allclose(jac, ref, rtol=0, atol=1e-14)
        # and the Jacobian maps the joint velocities to the frame's velocity
        np.testing.assert_allclose(jac @ run.qd[k], np.r_[twist.linear, twist.angular], atol=1e-13)
    assert np.allclose(np.linalg.norm(motion.quaternion, axis=1), 1.0, atol=1e-14)


def test_continuous_joints_take_angles():
    robot = get("double_pendulum_continuous")
    q = np.array([[0.3, -1.2], [3.5, 0.1]])
    table = frame_table(robot, q, None, ["link2"])
    model, data = robot.model, robot.model.createData()
    for k, angles in enumerate(q):
        pin.forwardKinematics(model, data, robot.configuration(angles))
        pin.updateFramePlacements(model, data)
        np.testing.assert_allclose(table[k, :3], data.oMf[model.getFrameId("link2")].translation,
                                   atol=1e-14)  # fmt: skip
    assert frame_jacobian(robot, q[1], "link2").shape == (6, 2)


def test_unknown_frames_and_results_without_a_robot_are_one_line(ur5_run):
    import pickle

    ur5, run = ur5_run
    with pytest.raises(InputError, match=r"'nope' is not a frame of ur5; its last frames: "):
        run.frame("nope")
    with pytest.raises(InputError, match=r"sample k=99 is not one of the run's 21"):
        run.jacobian("tool0", 99)
    with pytest.raises(InputError, match="this result has no robot"):
        pickle.loads(pickle.dumps(run)).frame("tool0")


def test_frame_columns_in_the_csv_of_simulate_and_inverse(tmp_path, capsys):
    arm = chapter_arm()
    out = tmp_path / "s.csv"
    assert main(["simulate", "--tf", "1", "--frames", "link3,link2", "--frame-velocities",
                 "--csv", str(out)]) == 0  # fmt: skip
    header, data = read_csv(out)
    columns = list(frame_columns(["link3", "link2"], velocities=True))
    assert header[-len(columns) :] == columns and header[:10] == ["t", *arm.q_names,
                                                                   *arm.qd_names, "T01x", "T12y", "F23z"][:10]  # fmt: skip
    q, qd = data[:, 1:4], data[:, 4:7]
    np.testing.assert_array_equal(data[:, -len(columns) :],
                                  frame_table(arm, q, qd, ["link3", "link2"], velocities=True))  # fmt: skip
    inv = tmp_path / "i.csv"
    assert main(["inverse", "--dt", "0.5", "--frames", "link3", "--csv", str(inv)]) == 0
    header, data = read_csv(inv)
    assert header[-7:] == list(frame_columns(["link3"])) and data.shape == (31, 13 + 7)
    np.testing.assert_array_equal(data[:, -7:], frame_table(arm, data[:, 1:4], None, ["link3"]))
    capsys.readouterr()
