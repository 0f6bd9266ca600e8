"""Argument helpers shared by the subcommands (cheap to import)."""

from __future__ import annotations

import argparse
import math

from rrt_pin.params import PARAM_DOCS, Params

__all__ = [
    "add_scene_arguments",
    "check_urdf_params",
    "check_writable",
    "finite_float",
    "float_list",
    "nonnegative_float",
    "params_from_args",
    "positive_float",
    "positive_int",
    "positive_seconds",
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
    from rrt_pin.errors import SceneError
    from rrt_pin.params import parse_number

    out = []
    for item in text.split(","):
        try:
            value = parse_number(item.strip())
        except SceneError:
            raise argparse.ArgumentTypeError(
                f"not a number: {item.strip()!r} in {text!r}"
            ) from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"must be finite: {item.strip()!r} in {text!r}")
        out.append(value)
    return out


def add_scene_arguments(parser: argparse.ArgumentParser) -> None:
    """Add ``--set NAME=VALUE`` (repeatable) and ``--scene PATH``."""
    names = ", ".join(PARAM_DOCS)
    parser.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="NAME=VALUE",
        help=f"override one of the seed's parameters, SI units (repeatable); names: {names}",
    )
    parser.add_argument(
        "--scene",
        metavar="PATH",
        help="TOML scene file: a [params] table (seed symbols, SI units) and an "
        "[options] table of defaults for this command's long options",
    )


def params_from_args(args: argparse.Namespace) -> Params:
    """Seed parameters < scene file [params] < ``--set`` overrides."""
    from rrt_pin.params import parse_overrides
    from rrt_pin.scene import resolve_params

    return resolve_params(getattr(args, "scene_obj", None), parse_overrides(args.overrides))


def positive_seconds(flag: str, value: object) -> float:
    """A time option (e.g. ``--tf`` from a scene file) as a finite float > 0 [s].

    Raises:
        InputError: the value is not a finite number > 0.
    """
    from rrt_pin.errors import InputError

    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise InputError(f"{flag}={value!r} must be a finite number [s]")
    if value <= 0.0:
        raise InputError(f"{flag}={value!r} must be > 0 [s]")
    return float(value)


def check_writable(path: str, flag: str) -> None:
    """Fail before any work when an output cannot be written (``-`` is stdout: accepted).

    Catches a missing folder, a folder, a name over the file system's limit (255
    bytes), a read-only file system and a folder this process may not write; see
    :func:`rrt_pin.io.check_output`.

    Raises:
        InputError: one line naming the option, the path and the problem.
    """
    from rrt_pin.io import check_output

    check_output(path, flag)


def check_urdf_params(args: argparse.Namespace, hint: str) -> None:
    """With ``--urdf`` only g and Tp mean something: refuse the RRT arm's other parameters.

    Raises:
        InputError: a ``--set`` or scene parameter describes the RRT arm.
    """
    from rrt_pin.errors import InputError
    from rrt_pin.params import parse_overrides

    given = set(parse_overrides(args.overrides))
    scene = getattr(args, "scene_obj", None)
    if scene is not None:
        given |= set(scene.params)
    unused = sorted(given - {"g", "Tp"})
    if unused:
        raise InputError(
            f"parameter {unused[0]} describes the RRT arm and does not apply to --urdf ({hint})"
        )


def resolve_backend(requested: str, rrt: bool) -> str:
    """The backend a run uses, loading the compiled one first so its cost is reported apart.

    ``auto`` picks ``compiled`` only for the RRT arm and only when its machine
    code is already built (in this process or in the disk cache, checked
    without importing numba); otherwise ``pinocchio``. With ``compiled``,
    importing numba and loading (or compiling) the code happens here, and one
    line on stderr says how long it took, so that the run's own time excludes it.

    Raises:
        InputError: ``compiled`` was asked for but numba is missing.
    """
    import sys

    from rrt_pin.errors import InputError

    if requested == "auto":
        try:
            from rrt_pin import compiled

            built = rrt and compiled.is_compiled()
        except ImportError:
            built = False
        requested = "compiled" if built else "pinocchio"
    if requested == "compiled":
        try:
            from rrt_pin import compiled

            report = compiled.ensure_compiled()
        except ImportError as e:
            raise InputError(f"backend 'compiled' is not available: {e}") from e
        print(f"rrt-pin: {report.describe()}", file=sys.stderr)
    return requested
