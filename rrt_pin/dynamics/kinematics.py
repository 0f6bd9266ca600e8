"""Frames of a robot along a motion: positions, orientations, velocities and Jacobians.

Pinocchio's forward kinematics (``pin.forwardKinematics``, ``pin.updateFramePlacements``,
``pin.getFrameVelocity`` and ``pin.computeFrameJacobian``) at joint coordinates [rad or m]
(angles for continuous joints: :meth:`Robot.configuration` maps them). Everything is
expressed in the world frame of the robot's model (``LOCAL_WORLD_ALIGNED``: at the
frame's origin, along the world's axes):

* position of the frame's origin [m];
* orientation as a unit quaternion (x, y, z, w), Eigen's and Pinocchio's order [1];
* spatial velocity: the origin's linear velocity [m/s] and the angular velocity [rad/s];
* Jacobian (6, nv): linear rows then angular rows, columns per joint velocity
  [m/(rad/s) or m/(m/s) for the linear rows, rad/(rad/s) for the angular ones].

As columns (``rrt-pin simulate --frames``, ``rrt-pin inverse --frames``): ``<frame>_x``,
``_y``, ``_z`` [m], ``_qx``, ``_qy``, ``_qz``, ``_qw`` [1], and with velocities ``_vx``,
``_vy``, ``_vz`` [m/s], ``_wx``, ``_wy``, ``_wz`` [rad/s].
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.core.text import argument

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot

__all__ = [
    "FrameMotion",
    "frame_columns",
    "frame_jacobian",
    "frame_motion",
    "frame_table",
    "frame_ids",
]

_POSE = (("x", "m"), ("y", "m"), ("z", "m"), ("qx", "1"), ("qy", "1"), ("qz", "1"), ("qw", "1"))
_TWIST = (("vx", "m/s"), ("vy", "m/s"), ("vz", "m/s"), ("wx", "rad/s"), ("wy", "rad/s"),
          ("wz", "rad/s"))  # fmt: skip


@dataclass(frozen=True)
class FrameMotion:
    """One frame along a motion (read-only arrays, world frame).

    Attributes:
        name: the frame.
        t: times (N,) [s].
        position: its origin (N, 3) [m].
        quaternion: its orientation (N, 4), (x, y, z, w) [1].
        linear_velocity: its origin's velocity (N, 3) [m/s], or None.
        angular_velocity: its angular velocity (N, 3) [rad/s], or None.
    """

    name: str
    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    linear_velocity: np.ndarray | None = None
    angular_velocity: np.ndarray | None = None


def frame_ids(robot: Robot, names: Sequence[str], what: str = "frames") -> list[int]:
    """The indices of ``names`` in the robot's model; an unknown name is one line."""
    model = robot.model
    known = [f.name for f in model.frames]
    ids = []
    for name in names:
        if name not in known:
            raise InputError(
                f"{argument(what)}: {name!r} is not a frame of {robot.name}; its last frames: "
                f"{', '.join(known[-8:])}"
            )
        ids.append(model.getFrameId(name))
    return ids


def _states(robot: Robot, q: Any, qd: Any = None) -> tuple[np.ndarray, np.ndarray | None]:
    q = np.atleast_2d(np.asarray(q, dtype=float))
    if q.shape[1] != robot.nv:
        raise InputError(f"q has {q.shape[1]} coordinates; {robot.name} has {robot.nv}")
    v = None if qd is None else np.atleast_2d(np.asarray(qd, dtype=float))
    if v is not None and v.shape != q.shape:
        raise InputError(f"qd has shape {v.shape}; q has {q.shape}")
    return np.ascontiguousarray(robot.configuration(q)), v


def frame_table(
    robot: Robot, q: Any, qd: Any, names: Sequence[str], velocities: bool = False
) -> np.ndarray:
    """The frames' columns (see :func:`frame_columns`) at each state, shape (N, columns)."""
    import pinocchio as pin

    ids = frame_ids(robot, names)
    config, v = _states(robot, q, qd if velocities else None)
    model = robot.model
    data = model.createData()
    width = len(_POSE) + (len(_TWIST) if velocities else 0)
    out = np.empty((config.shape[0], len(ids) * width))
    world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    for k in range(config.shape[0]):
        if velocities:
            pin.forwardKinematics(model, data, config[k], v[k])
        else:
            pin.forwardKinematics(model, data, config[k])
        pin.updateFramePlacements(model, data)
        for i, f in enumerate(ids):
            placement = data.oMf[f]
            col = i * width
            out[k, col : col + 3] = placement.translation
            out[k, col + 3 : col + 7] = pin.Quaternion(placement.rotation).coeffs()
            if velocities:
                twist = pin.getFrameVelocity(model, data, f, world)
                out[k, col + 7 : col + 10] = twist.linear
                out[k, col + 10 : col + 13] = twist.angular
    return out


def frame_columns(names: Sequence[str], velocities: bool = False) -> dict[str, str]:
    """The columns of :func:`frame_table` and their units, in order."""
    parts = _POSE + (_TWIST if velocities else ())
    return {f"{name}_{suffix}": unit for name in names for suffix, unit in parts}


def frame_motion(robot: Robot, t: Any, q: Any, name: str, qd: Any = None) -> FrameMotion:
    """One frame along samples of q (and qd, for its velocity)."""
    table = frame_table(robot, q, qd, [name], velocities=qd is not None)
    arrays = [table[:, 0:3], table[:, 3:7]]
    if qd is not None:
        arrays += [table[:, 7:10], table[:, 10:13]]
    for a in arrays:
        a.setflags(write=False)
    t = np.asarray(t, dtype=float)
    return FrameMotion(name, t, *arrays)


def frame_jacobian(robot: Robot, q: Any, name: str) -> np.ndarray:
    """The frame's Jacobian (6, nv) at one state ``q`` (nv,) [rad or m], world-aligned."""
    import pinocchio as pin

    (f,) = frame_ids(robot, [name], "name")
    config, _ = _states(robot, q)
    if config.shape[0] != 1:
        raise InputError(f"frame_jacobian() takes one state; got {config.shape[0]}")
    data = robot.model.createData()
    return pin.computeFrameJacobian(
        robot.model, data, config[0], f, pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
    )
