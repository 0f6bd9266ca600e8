"""Joint reaction wrenches: the whole load each joint transmits.

Kane's method (and Lagrange's) yields only the efforts along the joint axes
(T01x, T12y, F23z); the other components of the transmitted loads are the
constraint (bearing) loads that do no work. After Pinocchio's RNEA,
``data.f[j]`` is the spatial force that joint j transmits from its parent body
to its child body (with all that the child carries), gravity included,
expressed in joint j's frame, about joint j's origin.

For the RRT arm these frames are the chapter's (see :mod:`rrt_pin.robot.urdf`):

* joint q1: frame (1), origin A. The load of link 0 on link 1: force F01 at A
  and torque T01 = T01x·ı1 + T01y·ȷ1 + T01z·k1 about A.
* joint q2: frame (2), origin B. The load of link 1 on link 2: force F12 at B
  and torque T12 = T12x·ı2 + T12y·ȷ2 + T12z·k2 about B.
* joint q3: frame (2) translated to C3 (it moves with q3). The load of link 2
  on link 3: force F23 = F23x·ı2 + F23y·ȷ2 + F23z·k2 at C3 and moment M23 about C3.

Forces in N, moments in N·m, components along the named frame's unit vectors.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.dynamics.inverse import batch_arrays
from rrt_pin.robot.robot import Robot, bare_model

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "RRT_WRENCH_COLUMNS",
    "JointWrenches",
    "generic_wrench_columns",
    "joint_wrenches",
    "robot_wrench_table",
    "wrench_table",
]

#: CSV columns of the RRT arm's constraint loads, in order: (joint index, kind, axis, name).
#: The joint-axis components T01x, T12y, F23z are the effort columns and are not repeated.
_RRT_COMPONENTS = (
    (0, "force", 0, "F01x"),
    (0, "force", 1, "F01y"),
    (0, "force", 2, "F01z"),
    (0, "moment", 1, "T01y"),
    (0, "moment", 2, "T01z"),
    (1, "force", 0, "F12x"),
    (1, "force", 1, "F12y"),
    (1, "force", 2, "F12z"),
    (1, "moment", 0, "T12x"),
    (1, "moment", 2, "T12z"),
    (2, "force", 0, "F23x"),
    (2, "force", 1, "F23y"),
    (2, "moment", 0, "M23x"),
    (2, "moment", 1, "M23y"),
    (2, "moment", 2, "M23z"),
)
RRT_WRENCH_COLUMNS = tuple(c[3] for c in _RRT_COMPONENTS)


@dataclass(frozen=True)
class JointWrenches:
    """Loads transmitted by each joint, in the joint's frame, about its origin.

    Attributes:
        joint_names: the model's joint names, in the order of the middle axis.
        force: shape (N, n_joints, 3), force of the parent on the child [N].
        moment: shape (N, n_joints, 3), moment of the parent on the child
            about the joint frame's origin [N·m].
    """

    joint_names: tuple[str, ...]
    force: np.ndarray
    moment: np.ndarray


def joint_wrenches(
    model: Robot | pin.Model, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray
) -> JointWrenches:
    """The load each joint transmits along a batch of states (Pinocchio RNEA).

    Args:
        model: the robot (its model's gravity is used); a bare Pinocchio model is
            deprecated (pass ``Robot.from_model(model)``).
        q: joint coordinates, shape (N, nv) [rad or m] (angles for continuous joints;
            with a bare model, its (N, nq) configurations).
        qd: velocities, shape (N, model.nv) [rad/s or m/s].
        qdd: accelerations, shape (N, model.nv) [rad/s² or m/s²].

    Returns:
        The wrenches of joints 1 … njoints−1 (the universe joint is left out).

    Raises:
        InputError: bad shapes or non-finite values.
    """
    import pinocchio as pin

    if isinstance(model, Robot):
        robot, model = model, model.model
        q, qd, qdd = batch_arrays(q, qd, qdd, robot.nv, robot.nv)
        q = np.ascontiguousarray(robot.configuration(q))
    else:
        bare_model("joint_wrenches", model)
        q, qd, qdd = batch_arrays(q, qd, qdd, model.nq, model.nv)
    n, nj = q.shape[0], model.njoints - 1
    data = model.createData()
    out = np.empty((n, nj, 6))
    forces = data.f
    joints = range(1, nj + 1)
    for i in range(n):
        pin.rnea(model, data, q[i], qd[i], qdd[i])
        for j in joints:
            out[i, j - 1] = forces[j].vector  # (linear, angular)
    force = out[:, :, :3].copy()
    moment = out[:, :, 3:].copy()
    for arr in (force, moment):
        arr.flags.writeable = False
    return JointWrenches(tuple(model.names[1:]), force, moment)


def wrench_table(wrenches: JointWrenches, rrt: bool) -> tuple[tuple[str, ...], np.ndarray]:
    """CSV columns of the wrenches: names and an (N, columns) array.

    Args:
        wrenches: as returned by :func:`joint_wrenches`.
        rrt: True for the RRT arm: the chapter's names (:data:`RRT_WRENCH_COLUMNS`,
            axis components left out); False for any model: six columns per
            joint (see :func:`generic_wrench_columns`).
    """
    if rrt:
        parts = {"force": wrenches.force, "moment": wrenches.moment}
        data = np.column_stack([parts[kind][:, j, k] for j, kind, k, _ in _RRT_COMPONENTS])
        return RRT_WRENCH_COLUMNS, data
    n, nj, _ = wrenches.force.shape
    data = np.concatenate([wrenches.force, wrenches.moment], axis=2).reshape(n, nj * 6)
    return generic_wrench_columns(wrenches.joint_names), data


def generic_wrench_columns(joint_names: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """``fx_<joint>, fy_<joint>, fz_<joint>`` [N] and ``mx_<joint>, …`` [N·m] per joint."""
    return tuple(
        f"{c}{a}_{name}" for name in joint_names for c in ("f", "m") for a in ("x", "y", "z")
    )


def robot_wrench_table(robot: Robot, wrenches: JointWrenches) -> tuple[tuple[str, ...], np.ndarray]:
    """Column names and values of a robot's joint loads.

    The chapter's frames and names for the arm (:data:`RRT_WRENCH_COLUMNS`),
    ``fx_<joint>`` … for any other robot.
    """
    return wrench_table(wrenches, rrt=robot.layout == "chapter")
