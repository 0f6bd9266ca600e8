"""Robot: one description of the chapter's arm and of any URDF (joints, columns, units, defaults)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import rrt_pin
from rrt_pin.cli.app import main
from rrt_pin.core.errors import InputError, RrtPinError
from rrt_pin.robot import robots
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from tests.support import robot_urdf


def test_the_chapter_arm_needs_no_pinocchio_until_its_model_is_used():
    import subprocess
    import sys

    code = (
        "import sys, rrt_pin.robot.robots as r; arm = r.chapter_arm(); "
        "print(arm.q_names, arm.effort_units, 'pinocchio' in sys.modules); arm.model; "
        "print('pinocchio' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split("\n")[:2] == [
        "('q1', 'q2', 'q3') ('N·m', 'N·m', 'N') False",
        "True",
    ]


def test_chapter_arm_defaults_and_units():
    p = Params(m3=50.0, gamma23=70.0)
    arm = robots.chapter_arm(p)
    d = arm.defaults
    assert (d.q0, d.qf, d.kp, d.kd, d.Tp) == (p.q0, p.qf, p.kp, p.kd, p.Tp)
    assert arm.units == {
        "t": "s", "q1": "rad", "q2": "rad", "q3": "m", "qd1": "rad/s", "qd2": "rad/s",
        "qd3": "m/s", "qdd1": "rad/s²", "qdd2": "rad/s²", "qdd3": "m/s²",
        "T01x": "N·m", "T12y": "N·m", "F23z": "N",
    }  # fmt: skip
    assert arm.backends == ("pinocchio", "symbolic", "compiled") and arm.is_chapter_arm
    assert all(arm.supports("compiled", task) for task in ("inverse", "simulate", None))
    assert bool(arm.model == rrt_pin.rrt_model(p))


def test_a_urdf_robot_takes_its_names_from_the_file():
    ur5 = Robot.from_urdf(robot_urdf("ur5"), g=9.0)
    assert ur5.name == "ur5" and ur5.nv == ur5.nq == 6
    assert ur5.q_names[0] == "q_shoulder_pan_joint" and ur5.effort_names[-1] == "tau_wrist_3_joint"
    assert ur5.backends == ("pinocchio",) and ur5.parameters == ("g", "Tp")
    # compiled: from generated code (RNEA, integrators); the closed forms are the arm's
    assert ur5.inverse_backends == ("compiled",) and ur5.supports("compiled", "inverse")
    assert ur5.supports("compiled", "simulate") and not ur5.supports("compiled")
    assert not ur5.supports("symbolic", "inverse")
    assert ur5.defaults.q0 is None and ur5.defaults.qd0 == (0.0,) * 6
    np.testing.assert_array_equal(ur5.model.gravity.linear, [0, 0, -9.0])


def test_a_model_laid_out_as_the_arm_keeps_the_chapters_names():
    robot = Robot.from_model(rrt_pin.rrt_model())
    assert robot.q_names == ("q1", "q2", "q3") and robot.effort_names == ("T01x", "T12y", "F23z")
    assert not robot.is_chapter_arm  # no Params: only Pinocchio computes it


def test_panda_mixes_revolute_and_prismatic_units():
    panda = Robot.from_urdf(robot_urdf("panda"))
    kinds = [j.kind for j in panda.joints]
    assert kinds.count("prismatic") == 2 and kinds.count("revolute") == 7
    assert [panda.units[n] for n in panda.effort_names[-2:]] == ["N", "N"]


def test_unsupported_joints_are_named():
    model = pin.Model()
    model.addJoint(0, pin.JointModelSpherical(), pin.SE3.Identity(), "ball")
    with pytest.raises(RrtPinError, match="joint 'ball' is a Spherical joint"):
        Robot.from_model(model)
    with pytest.raises(InputError, match="must be a pinocchio.Model"):
        Robot.from_model("arm.urdf")


def test_for_task_sets_and_checks_the_defaults():
    p = Params()
    arm = robots.for_task("simulate", p, kp=[1.0], q0=[0.1, 0.2, 0.3])
    assert arm.defaults.kp == (1.0, 1.0, 1.0) and arm.defaults.q0 == (0.1, 0.2, 0.3)
    with pytest.raises(InputError, match="--qf has 2 values but the arm has 3 joints"):
        robots.for_task("inverse", p, qf=[1.0, 2.0])
    with pytest.raises(InputError, match=r"needs --q0 and --qf \(6 values each"):
        robots.for_task("inverse", p, urdf=robot_urdf("ur5"))
    with pytest.raises(InputError, match="parameter m1 describes the RRT arm"):
        robots.for_task("view", p, urdf=robot_urdf("ur5"), given={"m1"})
    ur5 = robots.for_task("view", Params(g=3.0, Tp=2.0), urdf=robot_urdf("ur5"), given={"Tp"})
    assert ur5.defaults.Tp == 2.0 and ur5.model.gravity.linear[2] == -3.0


def test_the_registry_knows_the_arm_and_example_robot_data():
    assert robots.names()[0] == "rrt" and "ur5" in robots.names()
    assert robots.get("rrt").name == "RRT arm"
    assert robots.get("panda").nv == 9
    with pytest.raises(InputError, match="robot 'r2d2' is unknown; known: rrt, ur5"):
        robots.get("r2d2")


def test_joints_command(capsys):
    assert main(["joints"]) == 0
    out = capsys.readouterr().out
    assert out.splitlines()[0] == "RRT arm: 3 joints, 3 coordinates"
    assert "q3     prismatic   q3" in out and "F23z" in out
    assert main(["joints", "--robot", "ur5"]) == 0
    out = capsys.readouterr().out
    assert "shoulder_pan_joint" in out and "tau_wrist_3_joint" in out
    assert main(["joints", "--robot", "nope"]) == 2
    assert "robot 'nope' is unknown" in capsys.readouterr().err


def test_a_robot_by_name_without_its_package_names_the_robots_extra(monkeypatch, capsys):
    from rrt_pin.cli.app import main
    from rrt_pin.core.extras import MissingExtra
    from rrt_pin.robot import robots

    monkeypatch.setattr(robots, "example_robot_data_dir", lambda: None)
    with pytest.raises(
        MissingExtra, match=r"example-robot-data not found \(needed for robot 'ur5'\)"
    ):
        robots.urdf_path("ur5")
    assert main(["joints", "--robot", "ur5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "[robots]" in err and "Traceback" not in err
    assert robots.urdf_path("rrt") is None  # the chapter's arm needs no package
