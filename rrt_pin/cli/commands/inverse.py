"""``rrt-pin inverse``: joint efforts along eq. (30), or along a user's motion from a file.

Builds only what the outputs need: no geometry model, no meshcat or sympy,
matplotlib only for ``--plot``, and not even Pinocchio for the RRT arm with
``--backend symbolic|compiled`` and no ``--wrenches``.
"""

from __future__ import annotations

import argparse
import json
import logging
from typing import IO, TYPE_CHECKING

from rrt_pin.cli.commands import _chapter
from rrt_pin.cli.commands._common import (
    add_frame_arguments,
    add_output_arguments,
    add_param_arguments,
    add_robot_arguments,
    finite_float,
    frames_from_args,
    params_from_args,
    positive_seconds,
    report_run,
    resolve_backend,
    robot_from_args,
    run_metadata,
    write_run_outputs,
)
from rrt_pin.cli.commands._progress import Progress
from rrt_pin.core import backends
from rrt_pin.core.errors import InputError
from rrt_pin.io.files import check_outputs, check_space

if TYPE_CHECKING:
    import numpy as np

    from rrt_pin.core.grid import Grid
    from rrt_pin.io.tables import TableWriter
    from rrt_pin.robot.robot import Robot

#: The most samples the plot draws (longer runs are thinned evenly, ends kept).
PLOT_POINTS = 200_000

HELP = "inverse dynamics along the chapter's rest-to-rest motion, eq. (30) (SI units)"

# Kept here (not imported from rrt_pin.dynamics.wrenches, which imports numpy) so that building
# the parser stays cheap; tests/test_cli_inverse.py checks it names every wrench column.
_WRENCH_HELP = """\
--wrenches adds the loads each joint transmits (constraint loads; the components
along the joint axes are the effort columns T01x, T12y, F23z):
  F01x,F01y,F01z  force of link 0 on link 1 at A, frame (1) [N]
  T01y,T01z       torque of link 0 on link 1 about A, frame (1) [N·m]
  F12x,F12y,F12z  force of link 1 on link 2 at B, frame (2) [N]
  T12x,T12z       torque of link 1 on link 2 about B, frame (2) [N·m]
  F23x,F23y       force of link 2 on link 3 at C3, frame (2) [N]
  M23x,M23y,M23z  moment of link 2 on link 3 about C3, frame (2) [N·m]"""

_EPILOG = f"""\
CSV columns (SI units), one row per sample, both ends of the grid included:
  t [s], q1 q2 [rad] q3 [m], qd1 qd2 [rad/s] qd3 [m/s],
  qdd1 qdd2 [rad/s²] qdd3 [m/s²], T01x T12y [N·m] F23z [N]
{_WRENCH_HELP}
With --urdf the columns are t, q_<joint>, qd_<joint>, qdd_<joint>, tau_<joint>
(joint names from the URDF; rad, rad/s, rad/s², N·m for revolute joints, m, m/s,
m/s², N for prismatic ones), and --wrenches adds fx_<joint>, fy_<joint>,
fz_<joint> [N] and mx_<joint>, my_<joint>, mz_<joint> [N·m]: the load of the
parent on the child at the joint origin, in the joint frame. Gravity is
(0, 0, -g) in the URDF's world frame.
A short summary always goes to stdout (to stderr when --csv - or --json - sends
data there): each joint's peak |effort| and when; --json PATH writes it with the
run's metadata. Long runs are computed and written 65,536 rows at a time, so
memory stays flat; a run whose output would not fit on the disk, or of more than
10^9 samples, is refused before any work."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin inverse``."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.description = f"{HELP}\n\n{_chapter.EQ30}"
    parser.epilog = _EPILOG
    parser.add_argument(
        "--tf",
        type=finite_float,
        default=None,
        metavar="S",
        help="end of the time grid [s] (default: Tp, 15 s for the chapter's arm); the arm "
        "moves for Tp and rests at qf after it; a --urdf robot's motion lasts --tf unless "
        "--set Tp=... is given",
    )
    parser.add_argument(
        "--dt", type=finite_float, default=None, metavar="S", help="time step [s] (default 0.001)"
    )
    parser.add_argument(
        "--trajectory",
        default=None,
        metavar="FILE",
        help="follow the motion in FILE (.csv, or .parquet with the parquet extra) at its own "
        "times instead of eq. (30): columns t [s] and the robot's coordinates as "
        "`rrt-pin joints` names them [rad or m], optionally its velocities and "
        "accelerations (qd…, qdd… names); those not given come from the quintic spline "
        "through the samples, with an estimate of their error in the summary (at least 6 "
        "samples; radians, not degrees); not with --tf/--dt",
    )
    add_output_arguments(
        parser,
        "write a plot of the efforts against time (matplotlib); the format follows "
        "the suffix: .png, .svg or .pdf",
    )
    parser.add_argument(
        "--wrenches",
        action="store_true",
        help="add each joint's whole transmitted load: CSV columns (below), and peak "
        "magnitudes in the summary",
    )
    parser.add_argument(
        "--backend",
        choices=(*backends.names("inverse"), "auto"),
        default=None,
        help="; ".join(
            f"{b.name}: {b.summary}" for b in backends.BACKENDS.values() if b.runs("inverse")
        )
        + " (compiled: loaded per process and reported on stderr; another robot's "
        "kernel is compiled once, built ahead of time, then loaded from the disk cache); "
        "auto: compiled when its code is already built (auto never compiles) and it is "
        "estimated faster, start-up included (docs/benchmarks.md gives the costs), else "
        "pinocchio; -v says which and why (default: auto, or $RRT_PIN_BACKEND)",
    )
    add_frame_arguments(parser)
    add_robot_arguments(parser, "inverse")
    add_param_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Compute the efforts (and wrenches) block by block, write them, print the summary."""
    from rrt_pin.io.tables import TableWriter, check_format, estimate_bytes

    params = params_from_args(args)
    fmt = check_format(args.csv, "--csv")
    outputs = [(args.csv, "--csv"), (args.plot, "--plot"), (args.json, "--json")]
    check_outputs(outputs)  # before any work: folders exist, no two name the same file
    if args.trajectory is not None:
        for flag, value in (("--tf", args.tf), ("--dt", args.dt)):
            if value is not None:
                raise InputError(
                    f"{flag} does not apply with --trajectory: the file gives the times"
                )
        robot = robot_from_args(args, params, "view")  # the file gives the motion: no q0, qf
        motion: Motion = FileMotion(robot, args.trajectory)
        tf, dt = float(motion.t[-1]), None
    else:
        robot = robot_from_args(args, params, "inverse")
        from rrt_pin.core.grid import grid_size

        d = robot.defaults
        tf = positive_seconds("--tf", d.Tp if args.tf is None and d.Tp is not None else
                              (args.tf if args.tf is not None else params.Tp))  # fmt: skip
        dt = positive_seconds("--dt", args.dt if args.dt is not None else 0.001)
        if dt > tf:
            raise InputError(f"--dt={dt!r} is larger than --tf={tf!r} [s]")
        grid = grid_size(tf, dt, what="--tf/--dt" if args.tf is not None else "Tp (the --tf)/--dt")
        motion = RestToRestMotion(robot, grid, d.Tp if d.Tp is not None else tf)
    job = InverseJob(robot, motion, args.wrenches, *frames_from_args(args, robot))
    job.keep_plot = bool(args.plot)
    check_space(args.csv, estimate_bytes(fmt, motion.size, len(job.header)), "--csv")
    args.backend = resolve_backend(args.backend, robot, "inverse", work=motion.size, args=args)
    job.backend = args.backend
    meta = run_metadata(
        args, robot, params, command="inverse", backend=args.backend, tf=tf, dt=dt,
        samples=motion.size, columns=job.header, units=job.units,
    )  # fmt: skip
    meta.update(motion.metadata())

    what = f"writing {args.csv}" if args.csv else "computing"
    progress = Progress(motion.size, what, force=args.progress)

    def table(fh: IO[bytes]) -> None:
        with TableWriter(fh, fmt, job.header, job.units, meta) as sink:
            job.run(sink, progress)

    if not args.csv:
        job.run(None, progress)
    logging.getLogger("rrt_pin").info(
        "inverse: backend %s, %s samples of %d columns%s", args.backend, f"{motion.size:,}",
        len(job.header), f", streamed to {args.csv}" if args.csv else "",
    )  # fmt: skip
    facts: dict = {}

    def summary_json() -> str:
        facts.update(summary(robot, job))
        return (
            json.dumps(
                {"metadata": meta, "summary": facts}, indent=2, allow_nan=False, ensure_ascii=False
            )
            + "\n"
        )

    try:
        write_run_outputs(
            args.csv, table, args.plot, lambda: _picture(robot, *job.plot_samples(), args.plot),
            args.json, summary_json,
        )  # fmt: skip
    finally:
        progress.close()
    report_run(args, f"backend {args.backend}", summary_text(facts or summary(robot, job)))
    return 0


class Motion:
    """What an inverse run follows: ``size`` samples, handed out a block at a time."""

    size: int
    label: str

    def samples(self, start: int, stop: int) -> tuple[np.ndarray, ...]:
        """Samples ``start`` … ``stop - 1``: t [s], q, qd, qdd (SI units)."""
        raise NotImplementedError

    def metadata(self) -> dict:
        """What the outputs record about the motion (beyond the run's metadata)."""
        return {}

    def facts(self) -> dict:
        """The summary's words about the motion: times and, for a file, its derivatives."""
        raise NotImplementedError


class RestToRestMotion(Motion):
    """Eq. (30) from the robot's q0 to qf in ``duration`` [s], sampled on ``grid``."""

    def __init__(self, robot: Robot, grid: Grid, duration: float) -> None:
        self.robot, self.grid, self.duration = robot, grid, duration
        self.size = grid.size
        self.label = robot.motion

    def samples(self, start: int, stop: int) -> tuple[np.ndarray, ...]:
        """Eq. (30) at samples ``start`` … ``stop - 1`` of the grid."""
        from rrt_pin.core.grid import grid_slice
        from rrt_pin.dynamics.trajectory import rest_to_rest

        d = self.robot.defaults
        t = grid_slice(self.grid, start, stop)
        traj = rest_to_rest(d.q0, d.qf, self.duration, t)
        return t, traj.q, traj.qd, traj.qdd

    def facts(self) -> dict:
        """The grid: t0, tf, dt [s]."""
        g = self.grid
        return {"t0": g.t0, "tf": g.tf, "dt": g.dt}


class FileMotion(Motion):
    """A user's motion from a CSV or Parquet file, at its own times."""

    def __init__(self, robot: Robot, path: str) -> None:
        import os

        from rrt_pin.dynamics.sampled import read_motion

        self.motion = read_motion(path, robot)
        self.t = self.motion.t
        self.size = self.t.size
        self.label = f"the motion in {os.path.basename(path)}"

    def samples(self, start: int, stop: int) -> tuple[np.ndarray, ...]:
        """The file's samples ``start`` … ``stop - 1``."""
        m = self.motion
        return m.t[start:stop], m.q[start:stop], m.qd[start:stop], m.qdd[start:stop]

    def metadata(self) -> dict:
        """The file and how the derivatives not given were made."""
        m = self.motion
        return {
            "trajectory": m.source,
            "derivatives": {
                "derived": list(m.derived), "method": m.method,
                "error_qd": m.error_qd, "error_qdd": m.error_qdd,
            },
        }  # fmt: skip

    def facts(self) -> dict:
        """The file's first and last times [s] and its derivatives' origin and estimate."""
        m = self.motion
        return {
            "t0": float(m.t[0]), "tf": float(m.t[-1]), "dt": None,
            "derivatives": m.describe(), "error_qd": m.error_qd, "error_qdd": m.error_qdd,
        }  # fmt: skip


class InverseJob:
    """The efforts along a motion, computed and handed on a block of rows at a time.

    Holds, besides the block being computed, only what the summary and the plot
    need: each column's peak so far and a thinned copy of the efforts for the plot
    (at most :data:`PLOT_POINTS` samples).
    """

    def __init__(
        self,
        robot: Robot,
        motion: Motion,
        wrenches: bool,
        frames: list[str] | None = None,
        frame_velocities: bool = False,
    ) -> None:
        import numpy as np

        self.robot, self.motion = robot, motion
        self.frames, self.frame_velocities = list(frames or []), frame_velocities
        self.backend = "pinocchio"
        self.wrenches = wrenches
        self.header = [
            "t", *robot.q_names, *robot.qd_names, *robot.qdd_names, *robot.effort_names
        ]  # fmt: skip
        self.units = dict(robot.units)
        if wrenches:
            names, _ = self._wrench_table(*motion.samples(0, 1)[1:])
            self.header += names
            self.units.update({n: "N" if n[0] in "Ff" else "N·m" for n in names})
        if self.frames:
            from rrt_pin.dynamics.kinematics import frame_columns

            columns = frame_columns(self.frames, frame_velocities)
            self.header += list(columns)
            self.units.update(columns)
        n = len(robot.effort_names) + (2 * len(robot.load_labels()) if wrenches else 0)
        self.peak = np.full(n, -1.0)  # peak |value| of each effort and load magnitude
        self.peak_t = np.zeros(n)
        self.stride = max(1, -(-motion.size // PLOT_POINTS))
        self._plot: list[tuple[np.ndarray, np.ndarray]] = []
        self.keep_plot = True  # whether to keep the thinned efforts for a plot

    def _wrench_table(
        self, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray
    ) -> tuple[tuple[str, ...], np.ndarray]:
        from rrt_pin.dynamics.wrenches import joint_wrenches, robot_wrench_table

        w = joint_wrenches(self.robot, q, qd, qdd)
        self._last_wrenches = w
        return robot_wrench_table(self.robot, w)

    def block(self, start: int, stop: int) -> np.ndarray:
        """Rows ``start`` … ``stop - 1`` of the table (SI units); updates the peaks."""
        import numpy as np

        from rrt_pin.dynamics.inverse import inverse_dynamics

        t, q, qd, qdd = self.motion.samples(start, stop)
        tau = inverse_dynamics(self.robot, q, qd, qdd, backend=self.backend)
        columns = [t[:, None], q, qd, qdd, tau]
        watched = [tau]
        if self.wrenches:
            _, table = self._wrench_table(q, qd, qdd)
            columns.append(table)
            w = self._last_wrenches
            for j in range(w.force.shape[1]):
                watched.append(np.linalg.norm(w.force[:, j], axis=1)[:, None])
                watched.append(np.linalg.norm(w.moment[:, j], axis=1)[:, None])
        if self.frames:
            from rrt_pin.dynamics.kinematics import frame_table

            columns.append(frame_table(self.robot, q, qd, self.frames, self.frame_velocities))
        values = np.abs(np.hstack(watched))
        i = np.argmax(values, axis=0)
        best = values[i, np.arange(values.shape[1])]
        better = best > self.peak
        self.peak[better], self.peak_t[better] = best[better], t[i[better]]
        if self.keep_plot:
            index = np.arange(start, stop)
            keep = (index % self.stride == 0) | (index == self.motion.size - 1)
            self._plot.append((t[keep], tau[keep]))
        return np.hstack(columns)

    def run(self, sink: TableWriter | None, progress: Progress | None = None) -> None:
        """Compute every block in order, writing each to ``sink`` (when given)."""
        from rrt_pin.io.tables import BLOCK_ROWS

        self.peak[:] = -1.0
        self._plot.clear()
        for start in range(0, self.motion.size, BLOCK_ROWS):
            stop = min(start + BLOCK_ROWS, self.motion.size)
            rows = self.block(start, stop)
            if sink is not None:
                sink.write(rows)
            if progress is not None:
                progress.update(stop - start)

    def plot_samples(self) -> tuple[np.ndarray, np.ndarray]:
        """The thinned times [s] and efforts [N·m or N] for the plot."""
        import numpy as np

        return (
            np.concatenate([t for t, _ in self._plot]),
            np.concatenate([tau for _, tau in self._plot]),
        )


def summary(robot: Robot, job: InverseJob) -> dict:
    """The run's summary as data: samples, grid, backend, each effort's (and load's) peak.

    A pure function of what the job gathered; :func:`summary_text` prints it and
    ``--json`` writes it.
    """
    names = list(robot.effort_names)
    units = list(robot.effort_units)
    if job.wrenches:
        for f_name, m_name in robot.load_labels():
            names += [f_name, m_name]
            units += ["N", "N·m"]
    peaks = [
        {"name": n, "unit": u, "peak": float(job.peak[k]), "t": float(job.peak_t[k]),
         "kind": "effort" if k < len(robot.effort_names) else "load"}
        for k, (n, u) in enumerate(zip(names, units, strict=True))
    ]  # fmt: skip
    return {
        "command": "inverse",
        "robot": robot.name,
        "motion": job.motion.label,
        "samples": job.motion.size,
        **job.motion.facts(),
        "backend": job.backend,
        "peaks": peaks,
    }


def summary_text(facts: dict) -> str:
    """The summary for people: each effort's peak |value| and when (and each load's)."""
    step = "the file's times" if facts["dt"] is None else f"dt = {facts['dt']:g} s"
    lines = [
        f"inverse dynamics of the {facts['robot']} along {facts['motion']}: "
        f"{facts['samples']} samples, t = {facts['t0']:g} .. {facts['tf']:g} s, "
        f"{step}, backend {facts['backend']}",
    ]
    if "derivatives" in facts:
        lines.append(f"derivatives: {facts['derivatives']}")
    lines.append(f"{'effort':<24} {'peak |effort|':>16}  {'at t [s]':>10}")
    header_done = False
    for p in facts["peaks"]:
        if p["kind"] == "load" and not header_done:
            lines.append(f"{'joint load':<24} {'peak magnitude':>16}  {'at t [s]':>10}")
            header_done = True
        lines.append(f"{p['name']:<24} {p['peak']:>12.6g} {p['unit']:<3}  {p['t']:>10.6g}")
    return "\n".join(lines) + "\n"


def _picture(robot: Robot, t: np.ndarray, tau: np.ndarray, path: str) -> bytes:
    from rrt_pin.viewer.plot import inverse_figure, plot_format

    return inverse_figure(robot, t, tau, fmt=plot_format(path))
