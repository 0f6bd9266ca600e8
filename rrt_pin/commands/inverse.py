"""``rrt-pin inverse``: joint efforts along the chapter's rest-to-rest motion (eq. 30).

Builds only what the outputs need: no geometry model, no meshcat or sympy,
matplotlib only for ``--plot``, and not even Pinocchio for the RRT arm with
``--backend symbolic|compiled`` and no ``--wrenches``.
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from rrt_pin import backends
from rrt_pin.commands import _chapter
from rrt_pin.commands._common import (
    add_robot_arguments,
    add_scene_arguments,
    finite_float,
    nonempty,
    params_from_args,
    plot_path,
    positive_seconds,
    resolve_backend,
    robot_from_args,
    write_run_outputs,
)
from rrt_pin.errors import InputError
from rrt_pin.io import check_outputs

if TYPE_CHECKING:
    import numpy as np

    from rrt_pin.robot import Robot
    from rrt_pin.wrenches import JointWrenches

HELP = "inverse dynamics along the chapter's rest-to-rest motion, eq. (30) (SI units)"

# Kept here (not imported from rrt_pin.wrenches, which imports numpy) so that building
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
Without --csv a short summary goes to stdout: each joint's peak |effort| and when."""


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
        "--dt", type=finite_float, default=0.001, metavar="S", help="time step [s] (default 0.001)"
    )
    parser.add_argument(
        "--csv", type=nonempty, metavar="PATH", help="write the samples here (atomically)"
    )
    parser.add_argument(
        "--plot",
        type=plot_path,
        metavar="PATH.png",
        help="write a plot of the efforts against time (matplotlib); the format follows the "
        "suffix: .png, .svg or .pdf",
    )
    parser.add_argument(
        "--wrenches",
        action="store_true",
        help="add each joint's whole transmitted load: CSV columns (below), or peak "
        "magnitudes in the summary",
    )
    parser.add_argument(
        "--backend",
        choices=(*backends.names("inverse"), "auto"),
        default="pinocchio",
        help="; ".join(
            f"{b.name}: {b.summary}" for b in backends.BACKENDS.values() if b.runs("inverse")
        )
        + " (loading compiled costs ~1 s per process, reported on stderr); auto: compiled "
        "only when its code is already built and the job is large enough for it to be at "
        "least twice as fast, start-up included (about 2 million samples), else pinocchio; "
        "-v says why (default: pinocchio)",
    )
    add_robot_arguments(parser, "inverse")
    add_scene_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Compute the efforts (and wrenches) and write or summarise them."""
    params = params_from_args(args)
    outputs = [(args.csv, "--csv"), (args.plot, "--plot")]
    check_outputs(outputs)  # before any work: folders exist, no two name the same file
    robot = robot_from_args(args, params, "inverse")

    import numpy as np

    from rrt_pin.grid import time_grid
    from rrt_pin.inverse import inverse_dynamics
    from rrt_pin.trajectory import rest_to_rest

    d = robot.defaults
    tf = positive_seconds("--tf", d.Tp if args.tf is None and d.Tp is not None else
                          (args.tf if args.tf is not None else params.Tp))  # fmt: skip
    dt = positive_seconds("--dt", args.dt)
    if dt > tf:
        raise InputError(f"--dt={dt!r} is larger than --tf={tf!r} [s]")
    t = time_grid(tf, dt)
    args.backend = resolve_backend(args.backend, robot, "inverse", work=t.size)
    # The motion lasts the robot's Tp (the chapter's arm: Tp; a URDF: --set Tp, else --tf)
    # and rests at qf after it.
    duration = d.Tp if d.Tp is not None else tf
    traj = rest_to_rest(d.q0, d.qf, duration, t)
    tau = inverse_dynamics(robot, traj.q, traj.qd, traj.qdd, backend=args.backend)

    header = ["t", *robot.q_names, *robot.qd_names, *robot.qdd_names, *robot.effort_names]
    columns = [traj.t[:, None], traj.q, traj.qd, traj.qdd, tau]
    wrenches = None
    if args.wrenches:
        from rrt_pin.wrenches import joint_wrenches, robot_wrench_table

        wrenches = joint_wrenches(robot.model, robot.configuration(traj.q), traj.qd, traj.qdd)
        names, table = robot_wrench_table(robot, wrenches)
        header += names
        columns.append(table)

    if args.csv or args.plot:
        from rrt_pin.csvio import csv_text

        write_run_outputs(
            args.csv,
            lambda: csv_text(header, np.hstack(columns)),
            args.plot,
            lambda: _picture(robot, traj.t, tau, args.plot),
        )
        for path in (args.plot, args.csv):
            if path:
                print(f"wrote {path} (backend {args.backend})", file=sys.stderr)
    if not args.csv:
        sys.stdout.write(summary(robot, traj.t, tau, args.backend, dt, wrenches))
    return 0


def summary(
    robot: Robot,
    t: np.ndarray,
    tau: np.ndarray,
    backend: str,
    dt: float,
    wrenches: JointWrenches | None = None,
) -> str:
    """Peak |effort| of each joint and when it occurs (and of its whole load), as text."""
    import numpy as np

    lines = [
        f"inverse dynamics of the {robot.name} along {robot.motion}: {t.size} samples, "
        f"t = {t[0]:g} .. {t[-1]:g} s, dt = {dt:g} s, backend {backend}",
        f"{'effort':<24} {'peak |effort|':>16}  {'at t [s]':>10}",
    ]

    def peak(name: str, values: np.ndarray, unit: str) -> str:
        i = int(np.argmax(np.abs(values)))
        return f"{name:<24} {abs(values[i]):>12.6g} {unit:<3}  {t[i]:>10.6g}"

    for k, (name, unit) in enumerate(zip(robot.effort_names, robot.effort_units, strict=True)):
        lines.append(peak(name, tau[:, k], unit))
    if wrenches is not None:
        lines.append(f"{'joint load':<24} {'peak magnitude':>16}  {'at t [s]':>10}")
        for j, (f_name, m_name) in enumerate(robot.load_labels()):
            lines.append(peak(f_name, np.linalg.norm(wrenches.force[:, j], axis=1), "N"))
            lines.append(peak(m_name, np.linalg.norm(wrenches.moment[:, j], axis=1), "N·m"))
    return "\n".join(lines) + "\n"


def _picture(robot: Robot, t: np.ndarray, tau: np.ndarray, path: str) -> bytes:
    from rrt_pin.plot import inverse_figure, plot_format

    return inverse_figure(robot, t, tau, fmt=plot_format(path))
