"""A user's own motion, sampled: read from a file, differentiated where only q is given.

A planner's or a logger's trajectory comes as samples: times ``t`` [s] and joint
coordinates ``q`` [rad or m], perhaps with velocities ``qd`` and accelerations
``qdd``. :func:`read_motion` reads them from a CSV or Parquet file whose columns
are named as ``rrt-pin joints`` lists them (``t``, the robot's ``q`` names, and
optionally its ``qd`` and ``qdd`` names); :func:`sampled_motion` takes arrays.
Inverse dynamics then runs at the file's own times.

Derivatives that are not given come from the quintic spline that interpolates the
samples (``scipy.interpolate.make_interp_spline``, k = 5, not-a-knot ends): q̇ and q̈
are its exact first and second derivatives at the sample times; a given q̇ (without
q̈) is interpolated the same way for q̈. The estimate recorded with them is the
largest difference between these derivatives and those of the degree-7 spline
through the same samples (the cubic one when there are fewer than 8): for a smooth
motion the higher-order spline is the more accurate, so the difference is about the
quintic's own error (on sin t at 100 samples per second: 3.2e-10 estimated for 3.2e-10 in
q̇, 1.6e-7 for 1.6e-7 in q̈). Noisy samples make it large (it then over-estimates,
about 4×), and the efforts are no better than the derivatives: smooth or filter
the samples first.
"""

from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core import text
from rrt_pin.core.errors import InputError
from rrt_pin.core.extras import require
from rrt_pin.io.csvio import read_csv_table

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot

__all__ = [
    "DEGREES_HINT",
    "MIN_SAMPLES",
    "SampledMotion",
    "coordinate_columns",
    "motion_from_frame",
    "read_efforts",
    "read_motion",
    "read_playback",
    "sampled_motion",
]

#: Samples the quintic spline needs (its order): fewer cannot be differentiated.
MIN_SAMPLES = 6
#: A revolute joint's coordinate beyond this [rad] (two turns) is taken for degrees.
DEGREES_HINT = 4 * math.pi
#: How the derivatives not given are made.
METHOD = "quintic interpolating spline (scipy make_interp_spline, k=5)"


@dataclass(frozen=True)
class SampledMotion:
    """Samples of a motion with their derivatives (read-only arrays).

    Attributes:
        t: sample times, strictly increasing, shape (N,) [s].
        q: joint coordinates, shape (N, nv) [rad or m].
        qd: velocities, shape (N, nv) [rad/s or m/s].
        qdd: accelerations, shape (N, nv) [rad/s² or m/s²].
        derived: which of ``qd``, ``qdd`` were computed (empty: all given).
        method: how they were computed (None when none was).
        error_qd: the estimate of the velocities' error, max over samples and
            coordinates [rad/s or m/s] (None when given; see the module's docstring:
            an estimate, not a bound).
        error_qdd: the same for the accelerations [rad/s² or m/s²].
        source: the file read, or None.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    derived: tuple[str, ...] = ()
    method: str | None = None
    error_qd: float | None = None
    error_qdd: float | None = None
    source: str | None = None

    def __post_init__(self) -> None:
        for name in ("t", "q", "qd", "qdd"):
            a = np.array(getattr(self, name), dtype=float)
            a.setflags(write=False)
            object.__setattr__(self, name, a)

    def describe(self) -> str:
        """One line: where the derivatives come from, with their estimated error."""
        if not self.derived:
            return "velocities and accelerations as given"
        errors = ", ".join(
            f"{name} ~{value:.2g}"
            for name, value in (("qd", self.error_qd), ("qdd", self.error_qdd))
            if name in self.derived and value is not None
        )
        return f"{' and '.join(self.derived)} from a {self.method} (estimated error {errors})"


def _spline(t: np.ndarray, y: np.ndarray, k: int) -> Any:
    from scipy.interpolate import make_interp_spline

    return make_interp_spline(t, y, k=k, axis=0)


def _check_times(t: np.ndarray, where: str) -> None:
    if t.ndim != 1:
        raise InputError(f"{where}: t must be one column of times [s], not shape {t.shape}")
    if not np.isfinite(t).all():
        k = int(np.flatnonzero(~np.isfinite(t))[0])
        raise InputError(f"{where}: t[{k}]={float(t[k])!r} is not finite [s]")
    steps = np.diff(t)
    if (steps <= 0.0).any():
        k = int(np.argmax(steps <= 0.0)) + 1
        raise InputError(
            f"{where}: times must increase strictly, but t[{k}]={float(t[k]):.6g} s follows "
            f"t[{k - 1}]={float(t[k - 1]):.6g} s"
        )


def _check_values(name: str, a: np.ndarray, n: int, count: int, where: str) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim == 1 and n == 1:
        a = a[:, None]
    if a.shape != (count, n):
        raise InputError(f"{where}: {name} has shape {a.shape}; it needs ({count}, {n})")
    bad = ~np.isfinite(a)
    if bad.any():
        i, j = (int(x) for x in np.argwhere(bad)[0])
        raise InputError(f"{where}: {name}[{i}, {j}]={float(a[i, j])!r} is not finite")
    return a


def _check_degrees(robot: Robot, q: np.ndarray, names: list[str], where: str) -> None:
    """Refuse a revolute coordinate beyond two turns: degrees given for radians."""
    for k, joint_kind in enumerate(_kinds(robot)):
        if joint_kind != "revolute":
            continue
        peak = float(np.abs(q[:, k]).max())
        if peak > DEGREES_HINT:
            raise InputError(
                f"{where}: {names[k]} reaches {peak:.6g}, more than two turns "
                f"({DEGREES_HINT:.4g} rad) for a revolute joint: given in degrees? "
                "rrt-pin takes radians"
            )


def _kinds(robot: Robot) -> list[str]:
    return [j.kind for j in robot.joints for _ in range(j.nv)]


def sampled_motion(
    t: Any,
    q: Any,
    qd: Any = None,
    qdd: Any = None,
    *,
    robot: Robot | None = None,
    names: list[str] | None = None,
    where: str = "motion",
    source: str | None = None,
) -> SampledMotion:
    """A motion from its samples, with the derivatives that are not given.

    Args:
        t: sample times (N,) [s], strictly increasing.
        q: joint coordinates (N, nv) [rad or m] (angles for continuous joints).
        qd: velocities (N, nv) [rad/s or m/s], or None to differentiate ``q``.
        qdd: accelerations (N, nv) [rad/s² or m/s²], or None to differentiate.
        robot: the robot (checks nv and refuses degrees for revolute joints).
        names: the coordinates' names for messages (default the robot's).
        where: what the samples are, for messages (a file's name).
        source: the file they came from.

    Raises:
        InputError: times not finite or not increasing, values not finite, shapes
            that disagree (or not the robot's nv), fewer than :data:`MIN_SAMPLES`
            samples where a derivative is needed, or a revolute coordinate beyond
            :data:`DEGREES_HINT` (degrees for radians).
    """
    t = np.asarray(t, dtype=float)
    _check_times(t, where)
    count = t.size
    q_arr = np.asarray(q, dtype=float)
    n = robot.nv if robot is not None else (q_arr.shape[1] if q_arr.ndim == 2 else 1)
    q_arr = _check_values("q", q_arr, n, count, where)
    if robot is not None:
        _check_degrees(robot, q_arr, names or list(robot.q_names), where)
    qd_arr = None if qd is None else _check_values("qd", qd, n, count, where)
    qdd_arr = None if qdd is None else _check_values("qdd", qdd, n, count, where)
    if qd_arr is not None and qdd_arr is not None:
        return SampledMotion(t, q_arr, qd_arr, qdd_arr, source=source)
    if count < MIN_SAMPLES:
        missing = "qd and qdd" if qd_arr is None else "qdd"
        raise InputError(
            f"{where}: {count} samples are too few to differentiate ({missing} not given): "
            f"the {METHOD} needs at least {MIN_SAMPLES}"
        )
    derived: list[str] = []
    errors: dict[str, float] = {}
    other = 7 if count >= 8 else 3  # the spline the estimate compares with
    if qd_arr is None:
        fine, coarse = _spline(t, q_arr, 5), _spline(t, q_arr, other)
        qd_arr = fine(t, 1)
        errors["qd"] = float(np.abs(qd_arr - coarse(t, 1)).max())
        derived.append("qd")
        if qdd_arr is None:
            qdd_arr = fine(t, 2)
            errors["qdd"] = float(np.abs(qdd_arr - coarse(t, 2)).max())
            derived.append("qdd")
    elif qdd_arr is None:
        fine, coarse = _spline(t, qd_arr, 5), _spline(t, qd_arr, other)
        qdd_arr = fine(t, 1)
        errors["qdd"] = float(np.abs(qdd_arr - coarse(t, 1)).max())
        derived.append("qdd")
    return SampledMotion(
        t, q_arr, qd_arr, qdd_arr, derived=tuple(derived), method=METHOD,
        error_qd=errors.get("qd"), error_qdd=errors.get("qdd"), source=source,
    )  # fmt: skip


_JOINT_COLUMN = re.compile(r"(q|qd|qdd|tau)(_.+|\d+)")


def _refuse_other_joints(robot: Robot, header: list[str], where: str) -> None:
    """A column named as a joint's (``q_…``, ``qd3``, ``tau_…``) that the robot lacks is an error."""
    known = {*robot.q_names, *robot.qd_names, *robot.qdd_names, *robot.effort_names}
    known |= {f"{kind}{k + 1}" for kind in ("q", "qd", "qdd") for k in range(robot.nv)}
    for column in header:
        if column not in known and _JOINT_COLUMN.fullmatch(column):
            raise InputError(
                f"{where} has column {column!r}, which is not one of {robot.name}'s "
                f"{robot.nv} joints ({text.names(list(robot.q_names), sep=',')})"
            )


def coordinate_columns(robot: Robot, header: list[str], where: str = "the file") -> list[str]:
    """The columns of ``header`` holding the robot's joint coordinates.

    Accepted, in order: the robot's coordinate names (``q1`` … or ``q_<joint>``, as
    ``rrt-pin inverse`` writes them), the bare joint names, and ``q1`` … ``qn``.

    Raises:
        InputError: a column is missing (naming it and what the file has).
    """
    names = list(robot.q_names)
    choices = [names]
    bare = [n.removeprefix("q_") for n in names]
    if bare != names:
        choices.append(bare)
    numbered = [f"q{k + 1}" for k in range(robot.nv)]
    if numbered != names:
        choices.append(numbered)
    for cols in choices:
        if all(c in header for c in cols):
            return cols
    missing = next(c for c in names if c not in header)
    raise InputError(
        f"{where} lacks column {missing!r}; it needs t and {text.names(names, sep=',')}; "
        f"it has {','.join(header)}"
    )


def _read_parquet(path: str) -> tuple[list[str], np.ndarray, dict[str, str]]:
    pq = require("pyarrow.parquet", "parquet", "a .parquet motion")
    import json

    try:
        table = pq.read_table(path)
    except (OSError, ValueError) as e:
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise InputError(f"Parquet {path!r} cannot be read: {first}") from e
    header = list(table.column_names)
    meta = table.schema.metadata or {}
    units = {}
    if b"rrt_pin.units" in meta:
        try:
            units = dict(json.loads(meta[b"rrt_pin.units"]))
        except (ValueError, TypeError):
            units = {}
    try:
        data = np.column_stack([table.column(c).to_numpy().astype(float) for c in header])
    except (ValueError, TypeError) as e:
        raise InputError(f"Parquet {path!r}: a column is not numbers ({e})") from e
    return header, data, units


def read_motion(path: str | os.PathLike[str], robot: Robot) -> SampledMotion:
    """The motion in a CSV or Parquet file, for ``robot``.

    Columns: ``t`` [s], the robot's coordinates (its ``q`` names, bare joint names
    or ``q1`` … ``qn``), and optionally its velocities and accelerations (its ``qd``
    and ``qdd`` names, as ``rrt-pin inverse --csv`` writes them); other columns are
    ignored. A Parquet file's units (``rrt_pin.units`` metadata) must be the robot's.
    What is missing is differentiated (see :func:`sampled_motion`).

    Raises:
        InputError: the file cannot be read, a column is missing, a unit differs
            from the robot's, a value is not a finite number, the times do not
            increase, or the samples are too few or look like degrees.
        MissingExtra: a .parquet file without pyarrow (the ``parquet`` extra).
    """
    name = os.fspath(path)
    header, data, units, where = _read_columns(name)
    return _from_columns(header, data, units, robot, where, name)


def motion_from_frame(frame: Any, robot: Robot) -> SampledMotion:
    """The motion in a data frame (pandas, or any mapping of columns): as :func:`read_motion`.

    Raises:
        InputError: as :func:`read_motion` (the frame named ``frame``); the frame's
            ``attrs["units"]`` (as :meth:`SimulationResult.to_frame` writes them) must
            be the robot's.
    """
    header = [str(c) for c in getattr(frame, "columns", frame)]
    try:
        data = np.column_stack([np.asarray(frame[c], dtype=float) for c in header])
    except (TypeError, ValueError) as e:
        raise InputError(f"frame: a column is not numbers ({e})") from e
    units = dict(getattr(frame, "attrs", {}).get("units", {}) or {})
    return _from_columns(header, data, units, robot, "frame", None)


def _check_units(
    robot: Robot,
    units: dict[str, str],
    columns: list[str],
    where: str,
    expected: dict[str, str] | None = None,
) -> None:
    """Each of ``columns`` a file gives a unit for must be in the robot's unit for it."""
    expected = expected or robot.units
    for c in columns:
        if c in units and units[c] != expected[c]:
            raise InputError(
                f"{where}: column {c!r} is in {units[c]}; {robot.name} needs {expected[c]}"
            )


def _from_columns(
    header: list[str],
    data: np.ndarray,
    units: dict[str, str],
    robot: Robot,
    where: str,
    source: str | None,
) -> SampledMotion:
    if "t" not in header:
        raise InputError(f"{where} lacks column 't' [s]")
    _refuse_other_joints(robot, header, where)
    cols = coordinate_columns(robot, header, where)
    _check_units(robot, units, cols, where, dict(zip(cols, robot.coordinate_units, strict=True)))
    column = {c: data[:, header.index(c)] for c in header}
    q = np.column_stack([column[c] for c in cols])
    parts = {}
    for kind, names in (("qd", robot.qd_names), ("qdd", robot.qdd_names)):
        present = [c in column for c in names]
        if any(present) and not all(present):
            missing = next(c for c, p in zip(names, present, strict=True) if not p)
            raise InputError(f"{where} has some {kind} columns but lacks {missing!r}")
        if all(present):
            _check_units(robot, units, list(names), where)
            parts[kind] = np.column_stack([column[c] for c in names])
    return sampled_motion(
        column["t"], q, parts.get("qd"), parts.get("qdd"), robot=robot, names=cols,
        where=where, source=source,
    )  # fmt: skip


def _read_columns(path: str) -> tuple[list[str], np.ndarray, dict[str, str], str]:
    """Header, numbers, units (Parquet) and a name for messages of a CSV or Parquet file."""
    if path.lower().endswith(".parquet"):
        header, data, units = _read_parquet(path)
        return header, data, units, f"Parquet {path!r}"
    table = read_csv_table(path, required=("t",))
    table.check_increasing("t")  # said with the editor's line numbers
    return table.header, table.data, {}, f"CSV {path!r}"


def read_efforts(path: str | os.PathLike[str], robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """Times (N,) [s] and efforts (N, nv) [N·m or N] from a CSV or Parquet file.

    Columns ``t`` and the robot's effort names (as ``rrt-pin joints`` lists them and
    ``rrt-pin inverse --csv`` writes them); other columns are ignored.

    Raises:
        InputError: the file cannot be read, a column is missing, a unit is not the
            robot's (Parquet), a value is not finite or the times do not increase.
    """
    t, tau, _ = read_playback(path, robot)
    return t, tau


def read_playback(
    path: str | os.PathLike[str], robot: Robot
) -> tuple[np.ndarray, np.ndarray, SampledMotion | None]:
    """:func:`read_efforts`, and the motion the same file holds, read once.

    The motion is the file's ``q`` columns (and ``qd``, ``qdd``), as ``rrt-pin inverse
    --csv`` writes them, or None when the file has no such columns.

    Raises:
        InputError: as :func:`read_efforts`, and as :func:`read_motion` for the motion.
    """
    name = os.fspath(path)
    header, data, units, where = _read_columns(name)
    if "t" not in header:
        raise InputError(f"{where} lacks column 't' [s]")
    _refuse_other_joints(robot, header, where)
    names = list(robot.effort_names)
    missing = [c for c in names if c not in header]
    if missing:
        raise InputError(
            f"{where} lacks column {missing[0]!r}; it needs t and {text.names(names, sep=',')}; "
            f"it has {','.join(header)}"
        )
    _check_units(robot, units, names, where)
    t = data[:, header.index("t")]
    _check_times(t, where)
    tau = _check_values("tau", np.column_stack([data[:, header.index(c)] for c in names]),
                        robot.nv, t.size, where)  # fmt: skip
    has_motion = all(c in header for c in robot.q_names)
    motion = _from_columns(header, data, units, robot, where, name) if has_motion else None
    return t, tau, motion
