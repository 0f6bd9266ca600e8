"""``rrt-pin simulate``: direct dynamics under the seed's feedback law, eq. (31).

Builds only what the outputs need: no geometry model, no meshcat or sympy, and
matplotlib only for ``--plot``. Importing this module stays cheap (no numpy).
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
    float_list,
    params_from_args,
    positive_float,
    positive_seconds,
    resolve_backend,
)
from rrt_pin.errors import InputError

if TYPE_CHECKING:
    import numpy as np
    import pinocchio as pin

    from rrt_pin.params import Params
    from rrt_pin.simulation import SimulationResult

HELP = "direct dynamics under the seed's feedback law, eq. (31) (SI units)"

#: rrt_pin.simulation.METHODS, repeated here so that building the parser imports no
#: numpy (tests/test_cli_simulate.py checks that the two agree).
METHODS = (
    "odepack",
    "RK45",
    "DOP853",
    "LSODA",
    "Radau",
    "BDF",
    "symplectic_euler",
    "rk4",
    "verlet",
    "leapfrog",
)
FIXED_STEP = ("symplectic_euler", "rk4", "verlet", "leapfrog")
#: The share of the initial distance to qf inside which a joint counts as settled.
SETTLING_BAND = 0.02

_EPILOG = """\
CSV columns (SI units), one row per sample, both ends of the grid included:
  t [s], q1 q2 [rad] q3 [m], qd1 qd2 [rad/s] qd3 [m/s], T01x T12y [N·m] F23z [N]
(the efforts the controller applied at each sample).
With --urdf the law is PD plus gravity compensation, tau = -kd*qd - kp*(q - qf) + G(q),
and the columns are t, q_<joint>, qd_<joint>, tau_<joint> (joint names from the URDF;
rad, rad/s, N·m for revolute joints, m, m/s, N for prismatic ones). Gravity is
(0, 0, -g) in the URDF's world frame.
Methods: odepack (default: ODEPACK's LSODA, rtol 1e-9, atol 1e-11), scipy's RK45,
DOP853, LSODA, Radau, BDF (adaptive: --rtol, --atol), and fixed-step
symplectic_euler, rk4, verlet (step --dt).
Without --csv a summary goes to stdout: each joint's final distance to qf, its 2 %
settling time (after which |q - qf| stays within 2 % of |q0 - qf|), and each
effort's peak |value| and when."""


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
        help=f"integration method: {', '.join(METHODS)} (default odepack; with "
        "--backend compiled, that backend's default and methods)",
    )
    parser.add_argument(
        "--rtol",
        type=positive_float,
        default=None,
        metavar="X",
        help="relative tolerance of the adaptive methods (default 1e-9)",
    )
    parser.add_argument(
        "--atol",
        type=positive_float,
        default=None,
        metavar="X",
        help="absolute tolerance of the adaptive methods [rad, m, rad/s, m/s] (default 1e-11)",
    )
    parser.add_argument("--csv", metavar="PATH", help="write the samples here (atomically)")
    parser.add_argument(
        "--plot", metavar="PATH.png", help="write a PNG of q(t) and the efforts (matplotlib)"
    )
    parser.add_argument(
        "--backend",
        choices=("pinocchio", "compiled", "auto"),
        default="pinocchio",
        help="pinocchio: ABA, any model (default); compiled: the numba kernel of the RRT "
        "arm (loading it costs ~1 s per process, compiling it ~15 s once, both reported on "
        "stderr; a run then takes ~0.2 ms instead of ~3 ms); auto: compiled only when its "
        "code is already built, else pinocchio",
    )
    parser.add_argument(
        "--urdf",
        metavar="PATH",
        help="another fixed-base arm (revolute/prismatic joints) under PD plus gravity "
        "compensation; needs --q0, --qf, --kp, --kd",
    )
    parser.add_argument(
        "--q0",
        type=float_list,
        metavar="A,B,...",
        help="initial configuration, one value per joint [rad or m] (RRT default: q10,q20,q30)",
    )
    parser.add_argument(
        "--qd0",
        type=float_list,
        metavar="A,B,...",
        help="initial velocity [rad/s or m/s] (RRT default: qd10,qd20,qd30; else zero)",
    )
    parser.add_argument(
        "--qf",
        type=float_list,
        metavar="A,B,...",
        help="target configuration [rad or m] (RRT default: q1f,q2f,q3f)",
    )
    parser.add_argument(
        "--kp",
        type=float_list,
        metavar="A,B,...",
        help="stiffness gains >= 0 [N·m/rad or N/m], one per joint or one for all "
        "(RRT default: gamma01,gamma12,gamma23)",
    )
    parser.add_argument(
        "--kd",
        type=float_list,
        metavar="A,B,...",
        help="damping gains >= 0 [N·m·s/rad or N·s/m], one per joint or one for all "
        "(RRT default: beta01,beta12,beta23)",
    )
    add_scene_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Simulate, then write the CSV and plot or print the summary."""
    params = params_from_args(args)
    for path, flag in ((args.csv, "--csv"), (args.plot, "--plot")):
        if path:
            check_writable(path, flag)
    from rrt_pin.grid import time_grid

    # Cheap checks first: loading the compiled backend costs about a second.
    t = time_grid(positive_seconds("--tf", args.tf), positive_seconds("--dt", args.dt))
    args.backend = resolve_backend(args.backend, rrt=args.urdf is None)
    setup = _setup(args, params)

    from rrt_pin.simulation import simulate

    result = simulate(
        setup.model,
        setup.controller,
        setup.q0,
        setup.qd0,
        t,
        method=args.method,
        rtol=args.rtol,
        atol=args.atol,
        backend=args.backend,
        step=args.dt if args.method in FIXED_STEP else None,
    )
    text = None
    if args.csv:
        from rrt_pin.csvio import csv_text

        text = csv_text(result.header, result.table())  # format first: a failure writes nothing
    if args.plot:
        _plot(args.plot, setup, result)
        print(f"wrote {args.plot}", file=sys.stderr)
    if text is not None:
        from rrt_pin.io import atomic_write_text

        try:
            atomic_write_text(args.csv, text)
        except OSError as e:
            if args.plot:
                Path(args.plot).unlink(missing_ok=True)
            raise InputError(f"cannot write --csv {args.csv!r}: {e.strerror or e}") from e
        print(
            f"wrote {args.csv} (method {result.method}, backend {result.backend})", file=sys.stderr
        )
    else:
        sys.stdout.write(summary(setup, result))
    return 0


class _Setup:
    """The model, controller, initial state and the joints' kinds of one run."""

    def __init__(
        self,
        model: pin.Model,
        controller: Any,
        q0: list[float],
        qd0: list[float],
        qf: tuple[float, ...],
        is_rrt: bool,
    ) -> None:
        self.model, self.controller = model, controller
        self.q0, self.qd0, self.qf = q0, qd0, qf
        self.is_rrt = is_rrt
        self.prismatic = tuple(
            model.joints[j].shortname().startswith(("JointModelP", "JointModelTranslation"))
            for j in range(1, model.njoints)
            for _ in range(model.joints[j].nv)
        )


def _setup(args: argparse.Namespace, params: Params) -> _Setup:
    from rrt_pin.control import pd_gravity_controller, seed_controller
    from rrt_pin.model import load_urdf_model, rrt_model

    if args.urdf is None:
        overrides: dict[str, float] = {}
        for flag, value, names in (
            ("--q0", args.q0, ("q10", "q20", "q30")),
            ("--qd0", args.qd0, ("qd10", "qd20", "qd30")),
            ("--qf", args.qf, ("q1f", "q2f", "q3f")),
            ("--kp", args.kp, ("gamma01", "gamma12", "gamma23")),
            ("--kd", args.kd, ("beta01", "beta12", "beta23")),
        ):
            if value is not None:
                values = _values(flag, value, 3, gain=flag in ("--kp", "--kd"))
                overrides.update(zip(names, values, strict=True))
        p = params.with_overrides(overrides) if overrides else params
        return _Setup(rrt_model(p), seed_controller(p), list(p.q0), list(p.qd0), p.qf, True)

    if args.backend != "pinocchio":
        raise InputError(
            f"--backend {args.backend} is the RRT arm's kernel; --urdf needs --backend pinocchio"
        )
    check_urdf_params(args, "only g does; use --q0, --qd0, --qf, --kp, --kd")
    model = load_urdf_model(args.urdf)
    model.gravity.linear[:] = (0.0, 0.0, -params.g)
    given = (("--q0", args.q0), ("--qf", args.qf), ("--kp", args.kp), ("--kd", args.kd))
    missing = [flag for flag, value in given if value is None]
    if missing:
        raise InputError(f"--urdf {args.urdf} needs {', '.join(missing)} ({model.nv} joints)")
    if model.nq != model.nv:
        raise InputError(
            f"--urdf {args.urdf}: nq={model.nq} but nv={model.nv}; simulate supports joints "
            "whose q̇ is v (revolute with limits, prismatic)"
        )
    q0 = _values("--q0", args.q0, model.nq)
    qd0 = _values("--qd0", args.qd0, model.nv) if args.qd0 is not None else [0.0] * model.nv
    qf = _values("--qf", args.qf, model.nq)
    kp = _values("--kp", args.kp, model.nv, gain=True)
    kd = _values("--kd", args.kd, model.nv, gain=True)
    controller = pd_gravity_controller(model, kp, kd, qf)
    return _Setup(model, controller, q0, qd0, tuple(qf), False)


def _values(flag: str, value: list[float], n: int, gain: bool = False) -> list[float]:
    """One value per joint (or, for gains, one for all); gains must be >= 0."""
    from rrt_pin.errors import ParameterError

    if gain and len(value) == 1:
        value = value * n
    if len(value) != n:
        extra = " (or one for all)" if gain else ""
        raise InputError(f"{flag} has {len(value)} values but the arm has {n} joints{extra}")
    if gain:
        for i, v in enumerate(value):
            if v < 0.0:
                raise ParameterError(f"{flag}[{i}]", v, "gain must be >= 0")
    return list(value)


def settling_times(
    t: np.ndarray, q: np.ndarray, q0: Any, qf: Any, band: float = SETTLING_BAND
) -> list[float | None]:
    """Per joint, the first sample time after which |q − qf| stays within ``band``·|q0 − qf|.

    A joint that starts at its target uses ``band`` times its largest excursion.
    None: still outside the band at the last sample.
    """
    import numpy as np

    dist = np.abs(q - np.asarray(qf))
    out: list[float | None] = []
    for k in range(q.shape[1]):
        scale = abs(float(q0[k]) - float(qf[k])) or float(dist[:, k].max())
        outside = np.flatnonzero(dist[:, k] > band * scale)
        if outside.size == 0:
            out.append(float(t[0]))
        elif outside[-1] == t.size - 1:
            out.append(None)
        else:
            out.append(float(t[outside[-1] + 1]))
    return out


def summary(setup: _Setup, result: SimulationResult) -> str:
    """Final distance to qf, 2 % settling time per joint and peak efforts, as text."""
    import numpy as np

    t, q, tau = result.t, result.q, result.tau
    arm = "the RRT arm under eq. (31)" if setup.is_rrt else "the URDF under PD + gravity"
    tol = (
        f"rtol {result.rtol:g}, atol {result.atol:g}" if result.rtol else f"step {result.step:g} s"
    )
    lines = [
        f"simulated {arm}: {t.size} samples, t = {t[0]:g} .. {t[-1]:g} s, "
        f"method {result.method} ({tol}), backend {result.backend}, "
        f"{result.n_evals} evaluations, {result.wall_time * 1e3:.3g} ms",
        f"{'joint':<24} {'q(tf)':>14} {'qf':>14} {'|q(tf) - qf|':>16}  {'settled (2 %) at t':>18}",
    ]
    settled = settling_times(t, q, setup.q0, setup.qf)
    for k, name in enumerate(result.q_names):
        unit = "m" if setup.prismatic[k] else "rad"
        when = f"{settled[k]:.6g} s" if settled[k] is not None else "not settled"
        lines.append(
            f"{name:<24} {q[-1, k]:>14.10g} {setup.qf[k]:>14.10g} "
            f"{abs(q[-1, k] - setup.qf[k]):>12.3e} {unit:<3}  {when:>18}"
        )
    lines.append(f"{'effort':<24} {'peak |effort|':>16}  {'at t [s]':>10}")
    for k, name in enumerate(result.tau_names):
        unit = "N" if setup.prismatic[k] else "N·m"
        i = int(np.argmax(np.abs(tau[:, k])))
        lines.append(f"{name:<24} {abs(tau[i, k]):>12.6g} {unit:<3}  {t[i]:>10.6g}")
    return "\n".join(lines) + "\n"


def _plot(path: str, setup: _Setup, result: SimulationResult) -> None:
    from rrt_pin.plot import Panel, plot_panels

    groups = [
        (prismatic, [k for k, p in enumerate(setup.prismatic) if p == prismatic])
        for prismatic in (False, True)
    ]
    groups = [(prismatic, ks) for prismatic, ks in groups if ks]
    panels = [
        Panel(
            f"q [{'m' if prismatic else 'rad'}]",
            {result.q_names[k]: result.q[:, k] for k in ks},
            title=f"{'prismatic' if prismatic else 'revolute'} joints: positions",
        )
        for prismatic, ks in groups
    ] + [
        Panel(
            f"effort [{'N' if prismatic else 'N·m'}]",
            {result.tau_names[k]: result.tau[:, k] for k in ks},
            title=f"{'prismatic' if prismatic else 'revolute'} joints: applied efforts",
        )
        for prismatic, ks in groups
    ]
    title = (
        "RRT arm under eq. (31): q(t) and efforts"
        if setup.is_rrt
        else "PD + gravity compensation: q(t) and efforts"
    )
    try:
        plot_panels(path, result.t, panels, title)
    except OSError as e:
        raise InputError(f"cannot write --plot {path!r}: {e.strerror or e}") from e
