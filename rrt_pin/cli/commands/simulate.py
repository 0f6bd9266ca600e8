"""``rrt-pin simulate``: direct dynamics under the chapter's feedback law, eq. (31).

Builds only what the outputs need: no geometry model, no meshcat or sympy, and
matplotlib only for ``--plot``. Importing this module stays cheap (no numpy).
"""

from __future__ import annotations

import argparse
import json
import logging
import sys
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
    positive_float,
    positive_seconds,
    report_run,
    resolve_backend,
    robot_from_args,
    run_metadata,
    write_run_outputs,
)
from rrt_pin.cli.commands._laws import law_from_args, law_source
from rrt_pin.cli.commands._progress import Progress
from rrt_pin.cli.commands._run_summary import summary, summary_text
from rrt_pin.core import backends
from rrt_pin.core.errors import InputError
from rrt_pin.io.files import check_outputs, check_space
from rrt_pin.robot.limits import (
    FRICTION_VELOCITY,
    LIMIT_DAMPING_RATIO,
    LIMIT_OMEGA,
    MAX_STEP_OMEGA,
    LimitWarning,
)
from rrt_pin.simulate import methods

if TYPE_CHECKING:
    import numpy as np

    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate import ErrorEstimate, SimulationResult


HELP = "direct dynamics under the chapter's feedback law, eq. (31) (SI units)"

#: The most output samples a simulation may have: its states stay in memory
#: (10⁷ samples of the chapter's arm: 0.8 GB).
MAX_OUTPUT_SAMPLES = 10**7


def _method_lines() -> str:
    lines = []
    for m in methods.METHODS.values():
        on = (
            ""
            if m.runs_on("pinocchio") and m.runs_on("compiled")
            else (" (compiled only)" if not m.runs_on("pinocchio") else " (pinocchio only)")
        )
        how = "adaptive: --rtol, --atol" if m.adaptive else "fixed step: --step"
        lines.append(f"  {m.name:<17} {m.summary}; {how}{on}")
    return "\n".join(lines)


_EPILOG = f"""\
CSV columns (SI units), one row per sample, both ends of the grid included:
  t [s], q1 q2 [rad] q3 [m], qd1 qd2 [rad/s] qd3 [m/s], T01x T12y [N·m] F23z [N]
(the efforts the controller applied at each sample).
With --urdf the law is PD plus gravity compensation, tau = -kd*qd - kp*(q - qf) + G(q),
and the columns are t, q_<joint>, qd_<joint>, tau_<joint> (joint names from the URDF;
rad, rad/s, N·m for revolute joints, m, m/s, N for prismatic ones). Gravity is
(0, 0, -g) in the URDF's world frame.
Methods (default: odepack on --backend pinocchio, DOP853 on compiled). Adaptive
methods take the loosest rtol and atol (atol = rtol/100) that keep --accuracy
(default {methods.ACCURACY:g} rad or m, max |q - q_exact| over the run) on every problem of
the accuracy catalogue and a UR5 and a Panda run, with a measured safety factor
(docs/benchmarks.md); --rtol/--atol given win:
{_method_lines()}
A summary always goes to stdout (to stderr when --csv - or --json - sends data
there): each joint's final distance to qf, its 2 % settling time (after which
|q - qf| stays within 2 % of |q0 - qf|), and each effort's peak |value| and when;
--json PATH writes it with the run's metadata. The states stay in memory (at most
10^7 output samples); the table is written 65,536 rows at a time.

Every run estimates the global error of q(t) from a companion run of the same method
at looser tolerances and the method's measured rate of error against tolerance
(twice or half the step for fixed-step methods, Richardson's formula): the summary
reports it, and a run whose estimate exceeds the accuracy asked for (--accuracy; with
--rtol/--atol and no --accuracy, max({methods.ACCURACY:g}, rtol, atol)) [rad or m] says so on
stderr. --no-error-estimate skips the companion run."""


def accuracy_value(text: str) -> float:
    """Argparse type of ``--accuracy``: a finite number in (0, 1) [rad or m]."""
    value = finite_float(text)
    if not 0.0 < value < 1.0:
        raise argparse.ArgumentTypeError(f"must lie in (0, 1) [rad or m]: {text!r}")
    return value


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin simulate``."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.description = f"{HELP}\n\n{_chapter.EQ31}"
    parser.epilog = _EPILOG
    parser.add_argument(
        "--tf", type=positive_float, default=15.0, metavar="S", help="final time [s] (default 15)"
    )
    parser.add_argument(
        "--dt",
        type=positive_float,
        default=0.01,
        metavar="S",
        help="output interval [s]: one CSV row per dt (default 0.01)",
    )
    parser.add_argument(
        "--step",
        type=positive_float,
        default=None,
        metavar="S",
        help="integration step of the fixed-step methods [s] (default: --dt); adaptive "
        "methods choose their own steps from --rtol and --atol",
    )
    parser.add_argument(
        "--method",
        default=None,
        metavar="NAME",
        help=f"integration method: {', '.join(methods.METHODS)} (default: the backend's, "
        "odepack on pinocchio, DOP853 compiled; see below)",
    )
    parser.add_argument(
        "--accuracy",
        type=accuracy_value,
        default=None,
        metavar="X",
        help="the accuracy asked for, max |q - q_exact| over the run [rad or m], in (0, 1): "
        "adaptive methods take the loosest calibrated --rtol/--atol that keep it, and the "
        f"error estimate is judged against it (default {methods.ACCURACY:g})",
    )
    parser.add_argument(
        "--rtol",
        type=positive_float,
        default=None,
        metavar="X",
        help="relative tolerance of the adaptive methods (default: chosen for --accuracy, "
        f"{methods.get('odepack').rtol:g} for odepack at {methods.ACCURACY:g}); given alone it "
        "sets --atol to rtol/100 too (the defaults' ratio), so that it tightens the whole "
        f"run; below {methods.RTOL_FLOOR:.3g} (100 float64 epsilons) it is refused",
    )
    parser.add_argument(
        "--atol",
        type=positive_float,
        default=None,
        metavar="X",
        help="absolute tolerance of the adaptive methods [rad, m, rad/s, m/s] "
        "(default: chosen for --accuracy, rtol/100)",
    )
    law = parser.add_argument_group(
        "the law (default: the robot's regulator, eq. (31) for the chapter's arm; at most one)"
    )
    law.add_argument(
        "--passive",
        action="store_true",
        help="no controller: zero efforts, no gravity compensation (the robot moves under "
        "gravity from q0; --kp, --kd, --qf do not apply)",
    )
    law.add_argument(
        "--track",
        metavar="FILE",
        default=None,
        help="computed-torque tracking of the motion in FILE (.csv or .parquet: t and the "
        "robot's q columns, as `rrt-pin inverse --trajectory` reads them): τ = M(q)(q̈r − "
        "kd·ė − kp·e) + b(q, q̇) with the reference interpolated linearly between samples "
        "and held after the last; starts on the motion unless --q0/--qd0 are given; "
        "--kp, --kd default 100, 20",
    )
    law.add_argument(
        "--efforts",
        metavar="FILE",
        default=None,
        help="open loop: the efforts in FILE (.csv or .parquet: t and the robot's effort "
        "columns, as `rrt-pin inverse --csv` writes them) [N·m or N], interpolated linearly "
        "between samples and held outside them, whatever the state; a file that also holds "
        "the motion (q…, as inverse --csv writes it) starts the run on it unless --q0/--qd0 "
        "are given",
    )
    law.add_argument(
        "--controller",
        metavar="MODULE:FUNCTION",
        default=None,
        help="your own law, a Python function f(t, q, qd) -> efforts (or f(q, qd)), imported "
        "from MODULE (found in the current directory first) or a file PATH.py; checked at "
        "every call",
    )
    physics = parser.add_argument_group(
        "limits, damping and friction (URDF robots, on by default; the chapter's arm states "
        "no binding limit)"
    )
    physics.add_argument(
        "--no-effort-limits",
        dest="effort_limits",
        action="store_false",
        help="do not saturate the law's efforts at the URDF's <limit effort> [N·m or N] "
        "(the output efforts are the saturated ones: what the actuators apply)",
    )
    physics.add_argument(
        "--no-position-limits",
        dest="position_limits",
        action="store_false",
        help="do not hold the joints in the URDF's <limit lower upper> [rad or m]. The "
        "limits are compliant (as MuJoCo's soft constraints): past one, a spring-damper "
        f"that only pushes back, k = m*omega^2, b = 2*zeta*m*omega, omega = "
        f"{LIMIT_OMEGA:g} rad/s, damping ratio zeta = {LIMIT_DAMPING_RATIO:g} (critical), "
        "m = 1/(M^-1)_kk the joint's effective inertia at q0; fixed-step methods then need --step <= "
        f"{MAX_STEP_OMEGA:g}/omega = {MAX_STEP_OMEGA / LIMIT_OMEGA:g} s. Continuous joints "
        "have none; velocity limits are reported, never enforced",
    )
    physics.add_argument(
        "--no-losses",
        dest="losses",
        action="store_false",
        help="do not apply the URDF's <dynamics damping friction>: viscous damping -d*qd "
        "and Coulomb friction regularised as -f*tanh(qd / v), v = "
        f"{FRICTION_VELOCITY:g} rad/s or m/s",
    )
    parser.add_argument(
        "--no-error-estimate",
        dest="error_estimate",
        action="store_false",
        help="skip the companion run that estimates the global error of q(t) [rad or m]",
    )
    add_output_arguments(
        parser,
        "write a plot of q(t) (targets dashed, and the URDF's position limits the run "
        "came near or crossed) and the efforts (matplotlib); the format follows the "
        "suffix: .png, .svg or .pdf",
    )
    parser.add_argument(
        "--backend",
        choices=(*backends.names("simulate"), "auto"),
        default=None,
        help="; ".join(
            f"{b.name}: {b.summary}" for b in backends.BACKENDS.values() if b.runs("simulate")
        )
        + " (compiled: built once, loaded per process, both reported on stderr; its run "
        "times against pinocchio's are in docs/benchmarks.md); auto: compiled when its code "
        "is already built (auto never compiles), it runs the robot, the law and the method "
        "asked for (none named: the chosen backend's, at the tolerances for --accuracy), and "
        "it is estimated faster, start-up included, else pinocchio; -v says which and why "
        "(default: auto, or $RRT_PIN_BACKEND)",
    )
    add_frame_arguments(parser)
    add_robot_arguments(parser, "simulate")
    add_param_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Simulate, then write the table, plot and JSON, and print the summary."""
    from rrt_pin.io.tables import check_format, estimate_bytes

    params = params_from_args(args)
    fmt = check_format(args.csv, "--csv")
    outputs = [(args.csv, "--csv"), (args.plot, "--plot"), (args.json, "--json")]
    check_outputs(outputs)  # before any work: folders exist, no two name the same file
    from rrt_pin.core.grid import grid_size, time_grid

    # Cheap checks first: loading the compiled backend costs about a second.
    tf, dt = positive_seconds("--tf", args.tf), positive_seconds("--dt", args.dt)
    grid = grid_size(tf, dt, what="--tf/--dt")
    if grid.size > MAX_OUTPUT_SAMPLES:
        raise InputError(
            f"--tf/--dt: tf={tf:g} s at dt={dt:g} s makes {grid.size:,} output samples, over "
            f"the {MAX_OUTPUT_SAMPLES:,} a simulation keeps in memory; use a larger dt"
        )
    if args.method is not None:
        methods.get(args.method)
    source = law_source(args)
    if source is not None:
        robot = robot_from_args(args, params, "view")  # the law needs no regulator's defaults
    else:
        robot = robot_from_args(args, params, "simulate")
    frames, frame_velocities = frames_from_args(args, robot)
    frame_units: dict[str, str] = {}
    if frames:
        from rrt_pin.dynamics.kinematics import frame_columns

        frame_units = frame_columns(frames, frame_velocities)
    columns = 1 + 3 * robot.nv + len(frame_units)
    check_space(args.csv, estimate_bytes(fmt, grid.size, columns), "--csv")
    from rrt_pin.simulate.control import regulator

    passive = source is not None
    law, law_name, start = (
        law_from_args(args, robot, source) if passive else (regulator(robot), robot.regulator, None)
    )
    switches = {
        "effort_limits": getattr(args, "effort_limits", True),
        "position_limits": getattr(args, "position_limits", True),
        "losses": getattr(args, "losses", True),
    }
    numeric = None  # BDF's compiled code differs by whether its Jacobian is numerical
    if args.method == "BDF":
        from rrt_pin.robot.limits import physical_model

        numeric = physical_model(robot, **switches).active
    args.backend = resolve_backend(
        args.backend, robot, "simulate", args.method, work=float(args.tf), args=args,
        controllers=[law], numeric_jacobian=numeric,
    )  # fmt: skip
    method = args.method or backends.get(args.backend).default_method
    fixed = not methods.get(method).adaptive
    if args.step is not None and not fixed:
        raise InputError(
            f"--step={args.step!r} sets the step of the fixed-step methods; {method} is "
            "adaptive (its steps follow --rtol and --atol)"
        )

    import warnings

    import numpy as np

    from rrt_pin.simulate import AccuracyWarning, simulate
    from rrt_pin.simulate.options import resolve

    accuracy = getattr(args, "accuracy", None)
    t = time_grid(tf, dt)
    step = (args.step or args.dt) if fixed else None
    chosen = resolve(t, backend=args.backend, method=method, rtol=args.rtol, atol=args.atol,
                     step=step, accuracy=accuracy)  # fmt: skip

    d = robot.defaults
    q0 = d.q0 if d.q0 is not None else np.zeros(robot.nv)
    qd0 = d.qd0
    if start is not None:  # a tracked motion starts the run on it unless told otherwise
        q0 = start[0] if args.q0 is None else q0
        qd0 = start[1] if args.qd0 is None else qd0
    from rrt_pin.core._logging import note
    from rrt_pin.simulate.physical_runs import outside_messages, physics_facts

    qf = robot.defaults.qf if not passive else getattr(law, "qf", None)
    for line in outside_messages(robot, {"q0": q0, "qf": qf}):
        note(f"warning: {line}")
    physical = physics_facts(robot, q0, **switches)
    if physical.get("not_given"):
        logging.getLogger("rrt_pin").info(
            "simulate: limits not given (a zero range or a zero effort in the URDF: no limit) "
            "for joints %s",
            ", ".join(physical["not_given"]),
        )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)  # said below, in one line
        warnings.simplefilter("ignore", LimitWarning)  # said above, as a note
        result = simulate(
            robot,
            law,
            q0,
            qd0,
            t,
            method=method,
            rtol=args.rtol,
            atol=args.atol,
            backend=args.backend,
            step=step,
            estimate_error=getattr(args, "error_estimate", True),
            accuracy=accuracy,
            **switches,
        )
    from rrt_pin.core.text import duration

    est = result.estimate
    logging.getLogger("rrt_pin").info(
        "simulate: backend %s, method %s (%s), %d evaluations in %s%s",
        result.backend, result.method,
        f"rtol {result.rtol:g}, atol {result.atol:g}" if result.rtol else f"step {result.step:g} s",
        result.n_evals, duration(result.wall_time),
        f"; error estimate: {est.how}, {duration(est.wall_time)}" if est is not None else "",
    )  # fmt: skip
    if result.estimate is not None and result.estimate.exceeded:
        print(
            f"rrt-pin simulate: warning: {_accuracy_warning(result, result.estimate)}",
            file=sys.stderr,
        )
    units = {name: robot.units.get(name, "") for name in result.header}
    units.update(frame_units)
    header = [*result.header, *frame_units]
    extra = None
    if frames:
        from rrt_pin.dynamics.kinematics import frame_table

        extra = frame_table(robot, result.q, result.qd, frames, frame_velocities)
    facts = summary(robot, result, law_name)
    facts["physical"] = physical
    given = args.rtol is not None or args.atol is not None
    facts["accuracy"] = chosen.accuracy
    facts["tolerances"] = ("given" if given else "chosen for the accuracy") if not fixed else None
    meta = run_metadata(
        args, robot, params, command="simulate", backend=result.backend,
        method=result.method, rtol=result.rtol, atol=result.atol, step=result.step,
        accuracy=chosen.accuracy, tolerances=facts["tolerances"], tf=tf, dt=dt, samples=int(result.t.size), columns=header, units=units,
        regulator=law_name,
        kp=[float(x) for x in d.kp] if d.kp is not None and not passive else None,
        kd=[float(x) for x in d.kd] if d.kd is not None and not passive else None,
        qd0=[float(x) for x in qd0] if qd0 is not None else None,
        error_estimate=facts["error_estimate"], physical=physical,
        limit_events=facts["limits"],
    )  # fmt: skip
    progress = Progress(result.t.size, f"writing {args.csv}", force=args.progress)

    def table(fh: IO[bytes]) -> None:
        write_result(fh, fmt, result, units, meta, progress, extra=extra)

    def summary_json() -> str:
        doc = {"metadata": meta, "summary": facts}
        return json.dumps(doc, indent=2, allow_nan=False, ensure_ascii=False) + "\n"

    try:
        write_run_outputs(
            args.csv,
            table,
            args.plot,
            lambda: _picture(robot, result, args.plot, law_name),
            args.json,
            summary_json,
        )
    finally:
        progress.close()
    report_run(args, f"method {result.method}, backend {result.backend}", summary_text(facts))
    return 0


def _accuracy_warning(result: SimulationResult, est: ErrorEstimate) -> str:
    k = int(est.q.argmax())
    how = (
        f"--rtol {result.rtol:g} --atol {result.atol:g}: tighten them"
        if result.rtol is not None
        else f"step {result.step:g} s: shorten --dt"
    )
    return (
        f"estimated global error of q(t) {est.max:.2g} ({result.q_names[k]}) exceeds the "
        f"accuracy asked for, {est.accuracy:.2g} [rad or m] (method {result.method}, {how})"
    )


def write_result(
    fh: IO[bytes],
    fmt: str,
    result: SimulationResult,
    units: dict[str, str],
    metadata: dict,
    progress: Progress | None = None,
    extra: np.ndarray | None = None,
) -> None:
    """Write a result's table (t, q…, qd…, tau…) to ``fh``, a block of rows at a time.

    ``extra``: more columns, one row per sample (the frames'), named by ``units``'s last keys.
    """
    import numpy as np

    from rrt_pin.io.tables import BLOCK_ROWS, TableWriter

    n = result.t.size
    header = [*result.header, *list(units)[len(result.header) :]] if extra is not None else None
    with TableWriter(fh, fmt, header or result.header, units, metadata) as sink:
        for start in range(0, n, BLOCK_ROWS):
            stop = min(start + BLOCK_ROWS, n)
            parts = [result.t[start:stop], result.q[start:stop], result.qd[start:stop],
                     result.tau[start:stop]]  # fmt: skip
            if extra is not None:
                parts.append(extra[start:stop])
            sink.write(np.column_stack(parts))
            if progress is not None:
                progress.update(stop - start)


def _picture(robot: Robot, result: SimulationResult, path: str, law: str) -> bytes:
    from rrt_pin.viewer.plot import plot_format, simulate_figure

    return simulate_figure(robot, result.t, result.q, result.tau, targets=robot.defaults.qf,
                           fmt=plot_format(path), law=law)  # fmt: skip
