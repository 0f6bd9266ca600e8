"""``rrt-pin inverse``: joint efforts along the seed's rest-to-rest motion (eq. 30).

Builds only what the outputs need: no geometry model, no meshcat or sympy,
matplotlib only for ``--plot``, and not even Pinocchio for the RRT arm with
``--backend symbolic|compiled`` and no ``--wrenches``.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rrt_pin.commands._common import (
    add_scene_arguments,
    check_urdf_params,
    check_writable,
    finite_float,
    float_list,
    params_from_args,
    positive_seconds,
    resolve_backend,
)
from rrt_pin.errors import InputError, UrdfError

if TYPE_CHECKING:
    import numpy as np
    import pinocchio as pin

    from rrt_pin.params import Params
    from rrt_pin.wrenches import JointWrenches

HELP = "inverse dynamics along the seed's rest-to-rest motion, eq. (30) (SI units)"

#: The RRT arm's first CSV columns (SI: s, rad, m, rad/s, m/s, rad/s², m/s², N·m, N).
RRT_COLUMNS = (
    "t",
    "q1",
    "q2",
    "q3",
    "qd1",
    "qd2",
    "qd3",
    "qdd1",
    "qdd2",
    "qdd3",
    "T01x",
    "T12y",
    "F23z",
)
RRT_EFFORTS = RRT_COLUMNS[10:13]
RRT_EFFORT_UNITS = ("N·m", "N·m", "N")

# Kept here (not imported from rrt_pin.wrenches) so that building the parser stays
# cheap; tests/test_cli_inverse.py checks it names every column of RRT_WRENCH_COLUMNS.
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
    parser.epilog = _EPILOG
    parser.add_argument(
        "--tf",
        type=finite_float,
        default=None,
        metavar="S",
        help="end of the time grid [s] (default: Tp, 15 s for the seed); the RRT arm moves "
        "for Tp and rests at qf after it; with --urdf the motion lasts --tf",
    )
    parser.add_argument(
        "--dt", type=finite_float, default=0.001, metavar="S", help="time step [s] (default 0.001)"
    )
    parser.add_argument("--csv", metavar="PATH", help="write the samples here (atomically)")
    parser.add_argument(
        "--plot", metavar="PATH.png", help="write a PNG of the efforts against time (matplotlib)"
    )
    parser.add_argument(
        "--wrenches",
        action="store_true",
        help="add each joint's whole transmitted load: CSV columns (below), or peak "
        "magnitudes in the summary",
    )
    parser.add_argument(
        "--backend",
        choices=("pinocchio", "symbolic", "compiled", "auto"),
        default="pinocchio",
        help="pinocchio: batched RNEA, any model (default); symbolic: the generated numpy "
        "kernel of the RRT arm; compiled: its numba version (loading it costs ~1 s per "
        "process, more than it saves here; reported on stderr); auto: compiled only when "
        "its code is already built, else pinocchio",
    )
    parser.add_argument(
        "--urdf",
        metavar="PATH",
        help="another fixed-base arm (revolute/prismatic joints) instead of the RRT arm; "
        "needs --q0 and --qf",
    )
    parser.add_argument(
        "--q0",
        type=float_list,
        metavar="A,B,...",
        help="start configuration, one value per joint [rad or m] (default for the RRT arm: "
        "q10,q20,q30)",
    )
    parser.add_argument(
        "--qf",
        type=float_list,
        metavar="A,B,...",
        help="final configuration, one value per joint [rad or m] (default for the RRT arm: "
        "q1f,q2f,q3f)",
    )
    add_scene_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Compute the efforts (and wrenches) and write or summarise them."""
    params = params_from_args(args)
    for path, what in ((args.csv, "--csv"), (args.plot, "--plot")):
        if path:
            check_writable(path, what)
    args.backend = resolve_backend(args.backend, rrt=args.urdf is None)
    job = _Job.from_args(args, params)

    import numpy as np

    from rrt_pin.grid import time_grid
    from rrt_pin.inverse import inverse_dynamics
    from rrt_pin.trajectory import rest_to_rest

    tf = params.Tp if args.tf is None else args.tf
    tf, dt = positive_seconds("--tf", tf), positive_seconds("--dt", args.dt)
    if dt > tf:
        raise InputError(f"--dt={dt!r} is larger than --tf={tf!r} [s]")
    t = time_grid(tf, dt)
    # The RRT arm keeps the seed's Tp (--set Tp=...) and rests after it; another arm
    # has no seed task, so --tf is the duration of its motion.
    duration = params.Tp if job.is_rrt or args.tf is None else tf
    traj = rest_to_rest(job.q0, job.qf, duration, t)
    q = job.configuration(traj.q)
    tau = inverse_dynamics(job.model, q, traj.qd, traj.qdd, backend=args.backend, params=params)

    header = ["t", *job.q_names, *job.qd_names, *job.qdd_names, *job.effort_names]
    columns = [traj.t[:, None], traj.q, traj.qd, traj.qdd, tau]
    wrenches = None
    if args.wrenches:
        from rrt_pin.wrenches import joint_wrenches, wrench_table

        wrenches = joint_wrenches(job.require_model(params), q, traj.qd, traj.qdd)
        names, table = wrench_table(wrenches, rrt=job.is_rrt)
        header += names
        columns.append(table)

    text = None
    if args.csv:
        from rrt_pin.csvio import csv_text

        text = csv_text(header, np.hstack(columns))  # format first: a failure writes nothing
    if args.plot:
        _plot(args.plot, job, traj.t, tau)
        print(f"wrote {args.plot}", file=sys.stderr)
    if text is not None:
        from rrt_pin.io import atomic_write_text

        try:
            atomic_write_text(args.csv, text)
        except OSError as e:
            if args.plot:
                Path(args.plot).unlink(missing_ok=True)
            raise InputError(f"cannot write --csv {args.csv!r}: {e.strerror or e}") from e
        print(f"wrote {args.csv} (backend {args.backend})", file=sys.stderr)
    else:
        sys.stdout.write(summary(job, traj.t, tau, args.backend, dt, wrenches))
    return 0


class _Job:
    """What one run computes: the model, the coordinates' names, kinds and ends."""

    def __init__(
        self,
        model: pin.Model | None,
        names: tuple[str, ...],
        prismatic: tuple[bool, ...],
        q0: list[float],
        qf: list[float],
        is_rrt: bool,
    ) -> None:
        self.model = model
        self.is_rrt = is_rrt
        self.joint_names = names
        self.prismatic = prismatic
        self.q0, self.qf = q0, qf
        if is_rrt:
            self.q_names = RRT_COLUMNS[1:4]
            self.qd_names = RRT_COLUMNS[4:7]
            self.qdd_names = RRT_COLUMNS[7:10]
            self.effort_names = RRT_COLUMNS[10:13]
        else:
            self.q_names = tuple(f"q_{n}" for n in names)
            self.qd_names = tuple(f"qd_{n}" for n in names)
            self.qdd_names = tuple(f"qdd_{n}" for n in names)
            self.effort_names = tuple(f"tau_{n}" for n in names)
        self.effort_units = tuple("N" if p else "N·m" for p in prismatic)
        self._unbounded: tuple[int, ...] = ()
        if model is not None and not is_rrt:
            self._unbounded = _unbounded_joints(model)

    @classmethod
    def from_args(cls, args: argparse.Namespace, params: Params) -> _Job:
        if args.urdf is None:
            q0 = _ends("--q0", args.q0, params.q0, 3)
            qf = _ends("--qf", args.qf, params.qf, 3)
            model = None
            if args.backend == "pinocchio":
                from rrt_pin.model import rrt_model

                model = rrt_model(params)
            return cls(model, ("q1", "q2", "q3"), (False, False, True), q0, qf, is_rrt=True)
        if args.backend != "pinocchio":
            raise InputError(
                f"--backend {args.backend} is the RRT arm's kernel; --urdf needs --backend pinocchio"
            )
        check_urdf_params(args, "only g and Tp do")
        from rrt_pin.model import load_urdf_model

        model = load_urdf_model(args.urdf)
        model.gravity.linear[:] = (0.0, 0.0, -params.g)
        names, prismatic = _joint_coordinates(model, args.urdf)
        if args.q0 is None or args.qf is None:
            raise InputError(f"--urdf {args.urdf} needs --q0 and --qf ({len(names)} values each)")
        q0 = _ends("--q0", args.q0, None, len(names), names)
        qf = _ends("--qf", args.qf, None, len(names), names)
        return cls(model, names, prismatic, q0, qf, is_rrt=False)

    def require_model(self, params: Params) -> pin.Model:
        """The Pinocchio model (built now for the RRT arm if the backend did not need it)."""
        if self.model is None:
            from rrt_pin.model import rrt_model

            self.model = rrt_model(params)
        return self.model

    def configuration(self, coords: np.ndarray) -> np.ndarray:
        """Pinocchio configurations (N, nq) from coordinates (N, nv).

        A continuous (unbounded revolute) joint stores (cos θ, sin θ) in q.
        """
        if not self._unbounded:
            return coords
        import numpy as np

        model = self.model
        q = np.empty((coords.shape[0], model.nq))
        for j in range(1, model.njoints):
            jm = model.joints[j]
            theta = coords[:, jm.idx_v]
            if j in self._unbounded:
                q[:, jm.idx_q] = np.cos(theta)
                q[:, jm.idx_q + 1] = np.sin(theta)
            else:
                q[:, jm.idx_q] = theta
        return q


_UNBOUNDED = (
    "JointModelRUBX",
    "JointModelRUBY",
    "JointModelRUBZ",
    "JointModelRevoluteUnboundedUnaligned",
)


def _unbounded_joints(model: pin.Model) -> tuple[int, ...]:
    return tuple(j for j in range(1, model.njoints) if model.joints[j].shortname() in _UNBOUNDED)


def _joint_coordinates(model: pin.Model, path: str) -> tuple[tuple[str, ...], tuple[bool, ...]]:
    """Joint names and whether each is prismatic; refuses joints with several coordinates."""
    names, prismatic = [], []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        kind = jm.shortname()
        if jm.nv != 1:
            raise UrdfError(
                f"{path}: joint {model.names[j]!r} ({kind}) has {jm.nv} velocity coordinates; "
                "the rest-to-rest motion needs one coordinate per joint"
            )
        names.append(model.names[j])
        prismatic.append(kind.startswith("JointModelP"))
    return tuple(names), tuple(prismatic)


def _ends(
    flag: str,
    value: Any,
    default: tuple[float, ...] | None,
    n: int,
    names: tuple[str, ...] = ("q1", "q2", "q3"),
) -> list[float]:
    import math

    if value is None:
        return list(default)  # type: ignore[arg-type]
    if isinstance(value, (int, float)) or not hasattr(value, "__len__"):
        value = [value]
    if len(value) != n:
        raise InputError(
            f"{flag} has {len(value)} values but the arm has {n} joints ({', '.join(names)})"
        )
    out = []
    for i, v in enumerate(value):
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
            raise InputError(f"{flag} value {i + 1} ({names[i]}) = {v!r} must be a finite number")
        out.append(float(v))
    return out


def summary(
    job: _Job,
    t: np.ndarray,
    tau: np.ndarray,
    backend: str,
    dt: float,
    wrenches: JointWrenches | None = None,
) -> str:
    """Peak |effort| of each joint and when it occurs (and of its whole load), as text."""
    import numpy as np

    arm = "the RRT arm" if job.is_rrt else f"{len(job.joint_names)} joints"
    lines = [
        f"inverse dynamics of {arm} along eq. (30): {t.size} samples, t = {t[0]:g} .. "
        f"{t[-1]:g} s, dt = {dt:g} s, backend {backend}",
        f"{'effort':<24} {'peak |effort|':>16}  {'at t [s]':>10}",
    ]

    def peak(name: str, values: np.ndarray, unit: str) -> str:
        i = int(np.argmax(np.abs(values)))
        return f"{name:<24} {abs(values[i]):>12.6g} {unit:<3}  {t[i]:>10.6g}"

    for k, (name, unit) in enumerate(zip(job.effort_names, job.effort_units, strict=True)):
        lines.append(peak(name, tau[:, k], unit))
    if wrenches is not None:
        lines.append(f"{'joint load':<24} {'peak magnitude':>16}  {'at t [s]':>10}")
        labels = _RRT_LOADS if job.is_rrt else None
        for j, joint in enumerate(wrenches.joint_names):
            f_name, m_name = labels[j] if labels else (f"|f_{joint}|", f"|m_{joint}|")
            lines.append(peak(f_name, np.linalg.norm(wrenches.force[:, j], axis=1), "N"))
            lines.append(peak(m_name, np.linalg.norm(wrenches.moment[:, j], axis=1), "N·m"))
    return "\n".join(lines) + "\n"


_RRT_LOADS = (
    ("|F01| at A", "|T01| about A"),
    ("|F12| at B", "|T12| about B"),
    ("|F23| at C3", "|M23| about C3"),
)


def _plot(path: str, job: _Job, t: np.ndarray, tau: np.ndarray) -> None:
    from rrt_pin.plot import Panel, plot_panels

    if job.is_rrt:
        panels = [
            Panel(f"{name} [{unit}]", {name: tau[:, k]}, title=title)
            for k, (name, unit, title) in enumerate(
                zip(
                    RRT_EFFORTS,
                    RRT_EFFORT_UNITS,
                    (
                        "torque of 0 on 1 about ı1",
                        "torque of 1 on 2 about ȷ2",
                        "force of 2 on 3 along k2",
                    ),
                    strict=True,
                )
            )
        ]
        title = "RRT arm: joint efforts along eq. (30)"
    else:
        panels = []
        for unit, kind in (("N·m", "revolute"), ("N", "prismatic")):
            curves = {
                name: tau[:, k]
                for k, (name, u) in enumerate(zip(job.joint_names, job.effort_units, strict=True))
                if u == unit
            }
            if curves:
                panels.append(Panel(f"effort [{unit}]", curves, title=f"{kind} joints"))
        title = "joint efforts along eq. (30)"
    try:
        plot_panels(path, t, panels, title)
    except OSError as e:
        raise InputError(f"cannot write --plot {path!r}: {e.strerror or e}") from e
