"""``rrt-pin simulate``: direct dynamics under the chapter's feedback law, eq. (31).

Builds only what the outputs need: no geometry model, no meshcat or sympy, and
matplotlib only for ``--plot``. Importing this module stays cheap (no numpy).
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from rrt_pin import backends, methods
from rrt_pin.commands._common import (
    add_robot_arguments,
    add_scene_arguments,
    nonempty,
    params_from_args,
    positive_float,
    positive_seconds,
    resolve_backend,
    robot_from_args,
    write_run_outputs,
)
from rrt_pin.io import check_outputs

if TYPE_CHECKING:
    from rrt_pin.robot import Robot
    from rrt_pin.simulate import ErrorEstimate, SimulationResult

HELP = "direct dynamics under the chapter's feedback law, eq. (31) (SI units)"


def _method_lines() -> str:
    lines = []
    for m in methods.METHODS.values():
        on = (
            ""
            if m.runs_on("pinocchio") and m.runs_on("compiled")
            else (" (compiled only)" if not m.runs_on("pinocchio") else " (pinocchio only)")
        )
        how = "adaptive: --rtol, --atol" if m.adaptive else "fixed step: --dt"
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
methods default to rtol {methods.DEFAULT_RTOL:g}, atol {methods.DEFAULT_ATOL:g}; odepack to rtol {methods.ODEPACK_RTOL:g}, atol {methods.ODEPACK_ATOL:g}.
The defaults keep max |q - q_exact| <= {methods.ACCURACY:g} rad or m on every scene of the
accuracy catalogue (docs/benchmarks.md):
{_method_lines()}
Without --csv a summary goes to stdout: each joint's final distance to qf, its 2 %
settling time (after which |q - qf| stays within 2 % of |q0 - qf|), and each
effort's peak |value| and when.
Every run estimates the global error of q(t) from a second run of the same method
at tolerances ten times tighter (half the step for fixed-step methods; it costs
about as much as the first run): the summary reports it, and a run whose estimate exceeds
the accuracy asked for, max({methods.ACCURACY:g}, rtol, atol) [rad or m], says so on stderr.
--no-error-estimate skips the second run."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin simulate``."""
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = _EPILOG
    parser.add_argument(
        "--tf", type=positive_float, default=15.0, metavar="S", help="final time [s] (default 15)"
    )
    parser.add_argument(
        "--dt",
        type=positive_float,
        default=0.01,
        metavar="S",
        help="output interval [s], and the step of the fixed-step methods (default 0.01)",
    )
    parser.add_argument(
        "--method",
        default=None,
        metavar="NAME",
        help=f"integration method: {', '.join(methods.METHODS)} (default odepack; "
        "--backend compiled: DOP853; see below)",
    )
    parser.add_argument(
        "--rtol",
        type=positive_float,
        default=None,
        metavar="X",
        help="relative tolerance of the adaptive methods (default "
        f"{methods.DEFAULT_RTOL:g}; odepack {methods.ODEPACK_RTOL:g})",
    )
    parser.add_argument(
        "--atol",
        type=positive_float,
        default=None,
        metavar="X",
        help="absolute tolerance of the adaptive methods [rad, m, rad/s, m/s] "
        f"(default {methods.DEFAULT_ATOL:g}; odepack {methods.ODEPACK_ATOL:g})",
    )
    parser.add_argument(
        "--no-error-estimate",
        dest="error_estimate",
        action="store_false",
        help="skip the second run that estimates the global error of q(t) [rad or m] "
        "(typically half of the call's time)",
    )
    parser.add_argument(
        "--csv", type=nonempty, metavar="PATH", help="write the samples here (atomically)"
    )
    parser.add_argument(
        "--plot",
        type=nonempty,
        metavar="PATH.png",
        help="write a PNG of q(t) and the efforts (matplotlib)",
    )
    parser.add_argument(
        "--backend",
        choices=(*backends.names("simulate"), "auto"),
        default="pinocchio",
        help="; ".join(
            f"{b.name}: {b.summary}" for b in backends.BACKENDS.values() if b.runs("simulate")
        )
        + " (loading compiled costs ~1 s per process, compiling it ~15 s once, both reported "
        "on stderr; a run then takes ~0.2 ms instead of ~3 ms); auto: compiled only when its "
        "code is already built and it runs the method asked for, else pinocchio "
        "(default: pinocchio)",
    )
    add_robot_arguments(parser, "simulate")
    add_scene_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Simulate, then write the CSV and plot or print the summary."""
    params = params_from_args(args)
    outputs = [(args.csv, "--csv"), (args.plot, "--plot")]
    check_outputs(outputs)  # before any work: folders exist, no two name the same file
    from rrt_pin.grid import time_grid

    # Cheap checks first: loading the compiled backend costs about a second.
    t = time_grid(positive_seconds("--tf", args.tf), positive_seconds("--dt", args.dt))
    if args.method is not None:
        methods.get(args.method)
    robot = robot_from_args(args, params, "simulate")
    args.backend = resolve_backend(args.backend, robot, "simulate", args.method)
    method = args.method or backends.get(args.backend).default_method
    fixed = not methods.get(method).adaptive

    import warnings

    from rrt_pin.control import regulator
    from rrt_pin.simulate import AccuracyWarning, simulate

    d = robot.defaults
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)  # said below, in one line
        result = simulate(
            robot,
            regulator(robot),
            d.q0,
            d.qd0,
            t,
            method=method,
            rtol=args.rtol,
            atol=args.atol,
            backend=args.backend,
            step=args.dt if fixed else None,
            estimate_error=getattr(args, "error_estimate", True),
        )
    if result.estimate is not None and result.estimate.exceeded:
        print(
            f"rrt-pin simulate: warning: {_accuracy_warning(result, result.estimate)}",
            file=sys.stderr,
        )
    if args.csv or args.plot:
        from rrt_pin.csvio import csv_text

        write_run_outputs(
            args.csv,
            lambda: csv_text(result.header, result.table()),
            args.plot,
            lambda: _picture(robot, result),
        )
        for path in (args.plot, args.csv):
            if path:
                print(
                    f"wrote {path} (method {result.method}, backend {result.backend})",
                    file=sys.stderr,
                )
    if not args.csv:
        sys.stdout.write(summary(robot, result))
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


def _estimate_line(robot: Robot, result: SimulationResult) -> str:
    est = result.estimate
    if est is None:
        return "estimated global error of q(t): not computed"
    per = ", ".join(
        f"{name} {e:.2g} {unit}"
        for name, e, unit in zip(result.q_names, est.q, robot.coordinate_units, strict=True)
    )
    verdict = "exceeds" if est.exceeded else "within"
    return (
        f"estimated global error of q(t), max over t: {per} ({verdict} the accuracy asked "
        f"for, {est.accuracy:.2g} rad or m; second run: {est.how}, {est.wall_time * 1e3:.3g} ms)"
    )


def summary(robot: Robot, result: SimulationResult) -> str:
    """Final distance to qf, 2 % settling time per joint and peak efforts, as text."""
    import numpy as np

    from rrt_pin.metrics import settling_times

    t, q, tau = result.t, result.q, result.tau
    qf = robot.defaults.qf
    tol = (
        f"rtol {result.rtol:g}, atol {result.atol:g}" if result.rtol else f"step {result.step:g} s"
    )
    lines = [
        f"simulated the {robot.name} under {robot.regulator}: {t.size} samples, "
        f"t = {t[0]:g} .. {t[-1]:g} s, method {result.method} ({tol}), backend {result.backend}, "
        f"{result.n_evals} evaluations, {result.wall_time * 1e3:.3g} ms",
        _estimate_line(robot, result),
        f"{'joint':<24} {'q(tf)':>14} {'qf':>14} {'|q(tf) - qf|':>16}  {'settled (2 %) at t':>18}",
    ]
    settled = settling_times(t, q, robot.defaults.q0, qf)
    for k, name in enumerate(result.q_names):
        unit = robot.coordinate_units[k]
        when = f"{settled[k]:.6g} s" if settled[k] is not None else "not settled"
        lines.append(
            f"{name:<24} {q[-1, k]:>14.10g} {qf[k]:>14.10g} "
            f"{abs(q[-1, k] - qf[k]):>12.3e} {unit:<3}  {when:>18}"
        )
    lines.append(f"{'effort':<24} {'peak |effort|':>16}  {'at t [s]':>10}")
    for k, name in enumerate(result.tau_names):
        unit = robot.effort_units[k]
        i = int(np.argmax(np.abs(tau[:, k])))
        lines.append(f"{name:<24} {abs(tau[i, k]):>12.6g} {unit:<3}  {t[i]:>10.6g}")
    return "\n".join(lines) + "\n"


def _picture(robot: Robot, result: SimulationResult) -> bytes:
    from rrt_pin.plot import effort_panels, position_panels, render_panels

    panels = position_panels(robot, result.q) + effort_panels(
        robot, result.tau, what=": applied efforts"
    )
    return render_panels(
        result.t, panels, f"{robot.name} under {robot.regulator}: q(t) and efforts"
    )
