"""What the viewer plays: a robot's motion as keyframes, from a task or a CSV file.

Pure functions of a :class:`~rrt_pin.robot.robot.Robot` and plain values; the CLI's
``rrt-pin view`` parses flags and calls :func:`motion_keyframes`. Coordinates
are joint coordinates [rad or m] (angles for continuous joints); the viewer
maps them to Pinocchio's configuration with :meth:`Robot.configuration`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.core.text import argument
from rrt_pin.dynamics.sampled import coordinate_columns
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.io.csvio import read_csv_table
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import regulator

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot

__all__ = ["Keyframes", "csv_columns", "motion_keyframes", "read_trajectory_csv"]

#: Largest magnitude of a played value (the page computes in single precision: 3.4e38
#: overflows; no time [s], angle [rad] or position [m] comes near this).
MAX_VALUE = 1e30
#: The sources a motion may come from besides a CSV path.
SOURCES = ("inverse", "simulate")


@dataclass(frozen=True)
class Keyframes:
    """A motion resampled for playback.

    Attributes:
        t: keyframe times from 0 [s], shape (N,).
        q: Pinocchio configurations, shape (N, nq).
        ghost: the configuration drawn as the target ghost (nq,), or None.
    """

    t: np.ndarray
    q: np.ndarray
    ghost: np.ndarray | None


def csv_columns(robot: Robot, header: list[str], path: str = "CSV") -> list[str]:
    """The columns of ``header`` holding the robot's joint coordinates.

    Accepted, in order: the robot's coordinate names (``q1`` … or
    ``q_<joint>``, as ``rrt-pin inverse`` writes them), the bare joint names,
    and ``q1`` … ``qn``.

    Raises:
        InputError: a column is missing (naming it and what the file has).
    """
    return coordinate_columns(robot, header, f"CSV {path!r}")


def read_trajectory_csv(path: str, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) [s] and joint coordinates (N, nv) [rad or m] from a CSV, validated.

    Raises:
        InputError: the file cannot be read, a column is missing, a value is
            not a finite number, or the times do not increase strictly.
    """
    table = read_csv_table(path, required=("t",))
    header, data = table.header, table.data
    cols = csv_columns(robot, header, path)
    t = data[:, header.index("t")]
    values = np.column_stack([data[:, header.index(c)] for c in cols])
    for name, column in (("t", t), *zip(cols, values.T, strict=True)):
        huge = np.flatnonzero(np.abs(column) > MAX_VALUE)
        if huge.size:
            row = int(huge[0])
            raise InputError(
                f"{table.where(row, name)}: {table.value_text(row, name)} is beyond ±{MAX_VALUE:g}"
            )
    table.check_increasing("t")
    return t, values


def motion_keyframes(robot: Robot, source: str, fps: float, tf: float | None = None) -> Keyframes:
    """Keyframes of ``source`` at ``fps`` [1/s].

    ``inverse``: eq. (30) from the robot's q0 to qf; ``simulate``: the robot's
    regulator from q0; else the path of a CSV file.

    Args:
        robot: the robot, with the defaults the task needs (q0, qf; gains to simulate).
        source: ``inverse``, ``simulate`` or the path of a CSV file.
        fps: keyframes per second [1/s].
        tf: length of an ``inverse`` or ``simulate`` run [s] (default the robot's Tp).

    Raises:
        InputError: a missing default, an unreadable CSV, or bad values.
    """
    from rrt_pin.viewer.keyframes import keyframe_times, resample

    d = robot.defaults
    if source in SOURCES:
        missing = [k for k in ("q0", "qf") if getattr(d, k) is None]
        if source == "simulate":
            missing += [k for k in ("kp", "kd") if getattr(d, k) is None]
        if missing:
            raise InputError(
                f"{argument('source', '--trajectory')} {source} for {robot.name} needs "
                f"{', '.join('--' + m for m in missing)} (or give a CSV, e.g. from "
                f"`rrt-pin {source} --urdf ... --csv`)"
            )
        Tp = d.Tp if d.Tp is not None else tf
        if Tp is None:
            raise InputError(
                f"{argument('source', '--trajectory')} {source} for {robot.name} needs "
                f"{argument('tf')}"
            )
        t = keyframe_times(tf if tf is not None else Tp, fps)
        if source == "inverse":
            values = np.asarray(rest_to_rest(d.q0, d.qf, Tp, t).q)
        else:
            values = np.asarray(simulate(robot, regulator(robot), d.q0, d.qd0, t).q)
        ghost = robot.configuration(np.asarray(d.qf, dtype=float))
        return Keyframes(t, robot.configuration(values), ghost)
    if not os.path.isfile(source):
        raise InputError(
            f"{argument('source', '--trajectory')} {source!r}: expected {', '.join(SOURCES)} or "
            "the path of a CSV file"
        )
    t_csv, values = read_trajectory_csv(source, robot)
    t, values = resample(t_csv, values, fps)
    target = d.qf if d.qf is not None else values[-1]
    ghost = robot.configuration(np.asarray(target, dtype=float))
    return Keyframes(t - t[0], robot.configuration(values), ghost)
