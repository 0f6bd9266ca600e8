"""Argument helpers shared by the subcommands (cheap to import)."""

from __future__ import annotations

import argparse
import math
import signal
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import IO, TYPE_CHECKING, Any

from rrt_pin.core._logging import note
from rrt_pin.robot.params import PARAM_DOCS, Params

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot

__all__ = [
    "Terminated",
    "add_config_argument",
    "add_output_arguments",
    "add_robot_arguments",
    "add_param_arguments",
    "check_writable",
    "finite_float",
    "float_list",
    "nonnegative_float",
    "params_from_args",
    "positive_float",
    "positive_int",
    "positive_seconds",
    "refuse_run_file_params",
    "resolve_backend",
    "robot_from_args",
    "run_metadata",
    "termination_as_interrupt",
    "write_run_outputs",
]


def finite_float(text: str) -> float:
    """Argparse type: a finite float."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be finite: {text!r}")
    return value


def positive_float(text: str) -> float:
    """Argparse type: a finite float > 0."""
    value = finite_float(text)
    if value <= 0.0:
        raise argparse.ArgumentTypeError(f"must be > 0: {text!r}")
    return value


def nonnegative_float(text: str) -> float:
    """Argparse type: a finite float >= 0."""
    value = finite_float(text)
    if value < 0.0:
        raise argparse.ArgumentTypeError(f"must be >= 0: {text!r}")
    return value


def positive_int(text: str) -> int:
    """Argparse type: an integer > 0."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be > 0: {text!r}")
    return value


def float_list(text: str) -> list[float]:
    """Argparse type: comma-separated finite floats, e.g. ``0.1,-0.5,0.3``.

    Values may be small expressions such as ``pi/3``.
    """
    from rrt_pin.core.errors import OverrideError
    from rrt_pin.robot.params import parse_number

    out = []
    for item in text.split(","):
        try:
            value = parse_number(item.strip())
        except OverrideError:
            raise argparse.ArgumentTypeError(
                f"not a number: {item.strip()!r} in {text!r}"
            ) from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be finite: {item.strip()!r} in {text!r}")
        out.append(value)
    return out


def add_param_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--set NAME=VALUE`` (repeatable) and ``--config PATH`` (alias ``--scene``)."""
    names = ", ".join(PARAM_DOCS)
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=f"override one of the chapter's parameters, SI units (repeatable); names: {names}",
    )
    parser.add_argument(
        "--config",
        "--scene",
        dest="config",
        type=nonempty,
        metavar="PATH",
        help="TOML run file: a [params] table (the chapter's symbols, SI units) and an "
        "[options] table of defaults for this command's long options (--scene is the old "
        "name of this flag)",
    )


def add_config_argument(parser: argparse.ArgumentParser, command: str) -> None:
    """Add ``--config PATH`` for a command without the chapter's parameters (no ``--set``).

    Its run file's ``[options]`` and ``[command]`` tables give the command's long
    options; a ``[params]`` table is refused (:func:`refuse_run_file_params`).
    """
    parser.add_argument(
        "--config",
        dest="config",
        type=nonempty,
        metavar="PATH",
        help=f"TOML run file: defaults for this command's long options from its [{command}] "
        "table (and [options]); no [params]",
    )


def refuse_run_file_params(args: argparse.Namespace, command: str, why: str) -> None:
    """Refuse a run file's ``[params]`` where the command takes none (never ignore them).

    Raises:
        RunFileError: the run file has a ``[params]`` table.
    """
    runfile = getattr(args, "runfile", None)
    if runfile is not None and runfile.params:
        from rrt_pin.core.errors import RunFileError

        raise RunFileError(
            f"run file {args.config!r}: [params] do not apply to 'rrt-pin {command}' ({why})"
        )


class Terminated(KeyboardInterrupt):
    """SIGTERM or SIGHUP, handled like Ctrl-C."""


@contextmanager
def termination_as_interrupt() -> Iterator[None]:
    """Turn SIGTERM and SIGHUP into :class:`Terminated` (a KeyboardInterrupt).

    Cleanup runs and the command ends as Ctrl-C ends it (main thread only).
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def handler(signum: int, frame: Any) -> None:
        raise Terminated()

    signums = [signal.SIGTERM] + ([signal.SIGHUP] if hasattr(signal, "SIGHUP") else [])
    previous = {s: signal.signal(s, handler) for s in signums}
    try:
        yield
    finally:
        for s, h in previous.items():
            signal.signal(s, h)


def params_from_args(args: argparse.Namespace) -> Params:
    """The chapter's parameters < run file [params] < ``--set`` overrides."""
    from rrt_pin.robot.params import parse_overrides

    overrides = parse_overrides(args.overrides)
    runfile = getattr(args, "runfile", None)
    if runfile is None:  # no --config: the run files' module stays unloaded
        return Params().with_overrides(overrides)
    from rrt_pin.cli.runfile import resolve_params

    return resolve_params(runfile, overrides)


def positive_seconds(flag: str, value: object) -> float:
    """A time option (e.g. ``--tf`` from a run file) as a finite float > 0 [s].

    Raises:
        InputError: the value is not a finite number > 0.
    """
    from rrt_pin.core.errors import InputError

    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{flag}={value!r} must be a finite number [s]")
    if value <= 0.0:
        raise InputError(f"{flag}={value!r} must be > 0 [s]")
    return float(value)


def check_writable(path: str, flag: str) -> None:
    """Fail before any work when an output cannot be written (``-`` is stdout: accepted).

    Catches a missing folder, a folder, a name over the file system's limit (255
    bytes), a read-only file system and a folder this process may not write; see
    :func:`rrt_pin.io.files.check_output`.

    Raises:
        InputError: one line naming the option, the path and the problem.
    """
    from rrt_pin.io.files import check_output

    check_output(path, flag)


def add_robot_arguments(parser: argparse.ArgumentParser, task: str) -> None:
    """Add ``--urdf`` and the task's start, target and gains (``--q0``, ``--qf`` …)."""
    needs = {
        "inverse": "--q0 and --qf",
        "simulate": "--q0, --qf, --kp and --kd",
        "view": "a CSV, or the flags of the task it plays",
    }[task]
    which = parser.add_mutually_exclusive_group()
    which.add_argument(
        "--urdf",
        type=nonempty,
        metavar="PATH",
        help="another fixed-base robot (revolute, continuous, prismatic joints) instead of the "
        f"chapter's RRT arm; needs {needs} (list its joints: rrt-pin joints --urdf PATH)",
    )
    which.add_argument(
        "--robot",
        type=nonempty,
        metavar="NAME",
        help="a robot known by name instead: rrt (the chapter's arm) or example-robot-data's "
        f"ur5, panda, double_pendulum, double_pendulum_continuous, kinova; needs {needs} "
        "like --urdf (rrt-pin joints --robot NAME)",
    )
    parser.add_argument(
        "--q0",
        type=float_list,
        metavar="A,B,...",
        help="start configuration, one value per joint [rad or m] (the arm's default: q10,q20,q30)",
    )
    if task in ("simulate", "view"):
        parser.add_argument(
            "--qd0",
            type=float_list,
            metavar="A,B,...",
            help="initial velocity [rad/s or m/s] (the arm's default: qd10,qd20,qd30; else zero)",
        )
    parser.add_argument(
        "--qf",
        type=float_list,
        metavar="A,B,...",
        help="final (target) configuration [rad or m] (the arm's default: q1f,q2f,q3f)",
    )
    if task in ("simulate", "view"):
        parser.add_argument(
            "--kp",
            type=float_list,
            metavar="A,B,...",
            help="stiffness gains >= 0 [N·m/rad or N/m], one per joint or one for all "
            "(the arm's default: gamma01,gamma12,gamma23)",
        )
        parser.add_argument(
            "--kd",
            type=float_list,
            metavar="A,B,...",
            help="damping gains >= 0 [N·m·s/rad or N·s/m], one per joint or one for all "
            "(the arm's default: beta01,beta12,beta23)",
        )


def name_list(text: str) -> list[str]:
    """Argparse type: comma-separated names, e.g. ``tool0,wrist_3_link`` (none empty)."""
    names = [n.strip() for n in text.split(",")]
    if not all(names):
        raise argparse.ArgumentTypeError(f"{text!r} must be names separated by commas")
    return names


def add_frame_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--frames`` and ``--frame-velocities`` (``inverse`` and ``simulate``)."""
    parser.add_argument(
        "--frames",
        type=name_list,
        default=None,
        metavar="NAME,...",
        help="add columns for these frames of the robot's model (its URDF links and joints, "
        "e.g. UR5's tool0; an unknown name lists the model's last frames): NAME_x, NAME_y, "
        "NAME_z [m], the origin in the world frame, and NAME_qx, NAME_qy, NAME_qz, NAME_qw "
        "[1], the orientation as a unit quaternion",
    )
    parser.add_argument(
        "--frame-velocities",
        action="store_true",
        help="with --frames, also NAME_vx, NAME_vy, NAME_vz [m/s] and NAME_wx, NAME_wy, NAME_wz "
        "[rad/s]: the frame's velocity along the world's axes",
    )


def frames_from_args(args: argparse.Namespace, robot: Robot) -> tuple[list[str], bool]:
    """The frames asked for (checked against the robot) and whether with velocities."""
    from rrt_pin.core.errors import InputError

    names = list(getattr(args, "frames", None) or [])
    velocities = bool(getattr(args, "frame_velocities", False))
    if velocities and not names:
        raise InputError("--frame-velocities needs --frames NAME,...")
    if names:  # the kinematics module only when frames are asked for
        from rrt_pin.dynamics.kinematics import frame_ids

        frame_ids(robot, names)
    return names, velocities


def nonempty(text: str) -> str:
    """Argparse type: a non-empty string (an empty path or host never changes meaning)."""
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty")
    return text


def plot_path(text: str) -> str:
    """``--plot``'s value: not empty, and a suffix naming an image format (png, svg, pdf)."""
    from rrt_pin.core.errors import InputError
    from rrt_pin.viewer.plot import plot_format

    path = nonempty(text)
    try:
        plot_format(path)
    except InputError as e:
        raise argparse.ArgumentTypeError(str(e).split(": ", 1)[1]) from None
    return path


def robot_from_args(args: argparse.Namespace, params: Params, task: str) -> Robot:
    """The run's robot from the flags (``--urdf``, ``--q0`` …): see :func:`rrt_pin.robot.robots.for_task`."""
    from rrt_pin.robot.params import parse_overrides
    from rrt_pin.robot.robots import for_task

    given = set(parse_overrides(args.overrides))
    runfile = getattr(args, "runfile", None)
    if runfile is not None:
        given |= set(runfile.params)
    values = {k: getattr(args, k, None) for k in ("q0", "qd0", "qf", "kp", "kd")}
    return for_task(
        task, params, urdf=args.urdf, name=getattr(args, "robot", None), given=given, **values
    )


def add_output_arguments(parser: argparse.ArgumentParser, plot_help: str) -> None:
    """Add ``--csv``, ``--plot``, ``--json`` and ``--progress`` (``inverse`` and ``simulate``)."""
    parser.add_argument(
        "--csv",
        type=nonempty,
        metavar="PATH",
        help="write the samples here (atomically, in blocks: memory stays flat); a .parquet "
        "or .pq path writes Parquet (pyarrow) with units and the run's metadata, any other "
        "path CSV; - is stdout",
    )
    parser.add_argument("--plot", type=plot_path, metavar="PATH.png", help=plot_help)
    parser.add_argument(
        "--json",
        type=nonempty,
        metavar="PATH",
        help="write the run's metadata (parameters, robot, backend, method, tolerances, "
        "version, command line, column units) and its summary as JSON; - is stdout",
    )
    parser.add_argument(
        "--progress",
        action="store_true",
        help="show a progress line on stderr even when it is not a terminal (on a terminal "
        "it shows by itself for runs over 2 s)",
    )


def run_metadata(args: argparse.Namespace, robot: Robot, params: Params, **run: object) -> dict:
    """What describes a run, for ``--json`` and Parquet's schema metadata (JSON-ready).

    Args:
        args: the parsed command line (``args.argv``: the words typed).
        robot: the run's robot.
        params: the chapter's parameters in force [SI].
        run: more fields (``command``, ``backend``, ``method``, ``rtol`` …).
    """
    import dataclasses
    import sys

    from rrt_pin._version import __version__

    d = robot.defaults

    def floats(v: object) -> object:
        return None if v is None else [float(x) for x in v]  # type: ignore[attr-defined]

    return {
        "rrt_pin_version": __version__,
        "command_line": list(getattr(args, "argv", None) or ["rrt-pin", *sys.argv[1:]]),
        **run,
        **({"backend_reason": args.backend_reason} if hasattr(args, "backend_reason") else {}),
        "robot": robot.name,
        "urdf": getattr(args, "urdf", None),
        "joints": [j.name for j in robot.joints],
        "q0": floats(d.q0),
        "qf": floats(d.qf),
        "parameters": dataclasses.asdict(params),
    }


def write_run_outputs(
    csv: str | None,
    table: Callable[[IO[bytes]], object],
    plot: str | None = None,
    picture: Callable[[], bytes] | None = None,
    json_path: str | None = None,
    json_text: Callable[[], str] | None = None,
) -> None:
    """Write the table, the plot and the JSON summary: all of them or none (``rrt_pin.io.files``).

    The writers run in that order: ``table`` (which may compute the run block by
    block while writing it) first, so the plot and the summary can use what it
    gathered. A failure (a writer, a full disk) leaves every pre-existing output as
    it was.
    """
    from rrt_pin.io.files import write_outputs

    write_outputs(
        [
            (csv, "--csv", table),
            (plot, "--plot", lambda fh: fh.write(picture() if picture else b"")),
            (json_path, "--json", lambda fh: fh.write(json_text().encode() if json_text else b"")),
        ]
    )


def report_run(args: argparse.Namespace, how: str, summary: str) -> None:
    """Say which outputs were written (``how``: backend, method) and print the summary.

    The summary goes to stdout, or to stderr when stdout carries the data
    (``--csv -`` or ``--json -``).
    """
    import sys

    from rrt_pin.io.files import STDOUT

    for path in (args.plot, args.csv, args.json):
        if path:
            note(f"wrote {path} ({how})")
    to = sys.stderr if STDOUT in (args.csv, args.json) else sys.stdout
    to.write(summary)


def _load_generated(robot: Robot, task: str, method: str | None, job: dict[str, Any]) -> str:
    """Load (or compile) ``robot``'s generated code for ``task``, and say how long it took.

    A simulation's: the entry the job will run (its method, its laws, one run or a batch:
    :func:`rrt_pin.compiled.robot_entries.pd_entries`), not another one besides.
    """
    from rrt_pin.compiled import rnea, robot_code, robot_entries
    from rrt_pin.core import backends
    from rrt_pin.core.errors import InputError
    from rrt_pin.simulate import methods

    try:
        if task == "inverse":
            kernel = rnea.kernel_for(robot.model)
            what = "inverse dynamics"
            where = f" ({kernel.path.parent})" if kernel.path is not None else ""
        else:
            kernel = robot_code.integrators_for(robot.model, robot.name)
            code = methods.get(method or backends.get("compiled").default_method).code
            pd = robot_entries.pd_only(job.get("controllers", ()))
            numeric = job.get("numeric_jacobian")
            for group in robot_entries.pd_entries(code, bool(job.get("batch")), pd, numeric):
                kernel.entry(group[0])
            what, where = "integrators", ""
    except ImportError as e:
        raise InputError(f"backend 'compiled' is not available: {e}") from e
    how = {
        "loaded": "loaded from the cache",
        "compiled": "compiled",
        "ahead of time": "loaded (built ahead of time)",
    }.get(kernel.origin, "compiled (memory only, no cache)")
    note(f"generated {what} of {robot.name} {how} in {kernel.seconds:.2f} s{where}")
    return "compiled"


def resolve_backend(
    requested: str | None,
    robot: Robot,
    task: str,
    method: str | None = None,
    work: float = 0.0,
    args: argparse.Namespace | None = None,
    **job: Any,
) -> str:
    """The backend a run uses, loading the compiled one first so its cost is reported apart.

    ``auto`` (the default, unless ``$RRT_PIN_BACKEND`` says otherwise) is
    :func:`rrt_pin.core.backends.choose`, the one policy (``work``: the number of samples
    for ``inverse``, the simulated seconds for ``simulate``; ``job``: its laws and
    whether it is a batch); ``-v`` says which and why, and so does the run's metadata
    (``backend_reason``, kept on ``args`` when given). A backend the robot does not
    support is refused (a robot with a joint the generated RNEA does not handle:
    the message names it). With ``compiled``, importing numba and loading (or
    compiling) the code happens here (for another robot than the chapter's arm:
    its generated kernel), and one line on stderr says how long it
    took, so that the run's own time excludes it; with the dynamics and single
    runs built ahead of time (:func:`rrt_pin.compiled.aot_built`) that is skipped
    (they load without numba).

    Raises:
        InputError: ``compiled`` was asked for but numba is missing.
    """
    from rrt_pin.core import backends
    from rrt_pin.core.errors import InputError

    choice = backends.decide(robot, requested, task, method, work, **job)
    requested = choice.name
    if args is not None:
        args.backend_reason = choice.reason  # the run's metadata says why
    if requested == "compiled" and not robot.supports(requested, task):
        from rrt_pin.dynamics.rnea_source import unsupported_joint

        raise InputError(
            f"--backend compiled: {unsupported_joint(robot.model)}; --urdf needs --backend pinocchio"
        )
    if not robot.supports(requested, task):
        what = "simulates" if task == "simulate" and requested == "compiled" else "computes"
        raise InputError(
            f"--backend {requested} {what} the chapter's RRT arm only; --urdf needs "
            "--backend pinocchio"
        )
    if requested == "compiled":
        from rrt_pin.core.extras import MissingExtra

        backends.get("compiled").require()
        if not robot.supports("compiled"):  # not the arm: its generated code
            return _load_generated(robot, task, method, job)
        try:
            from rrt_pin import compiled

            if compiled.aot_built():
                return requested  # loaded on first use, in ~20 ms (no numba import)
            report = compiled.ensure_compiled()
        except MissingExtra:
            raise
        except ImportError as e:
            raise InputError(f"backend 'compiled' is not available: {e}") from e
        note(report.describe())
    return requested
