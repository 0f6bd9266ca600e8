"""Argument helpers shared by the subcommands (cheap to import)."""

from __future__ import annotations

import argparse
import math

from rrt_pin.params import PARAM_DOCS, Params

__all__ = [
    "add_scene_arguments",
    "finite_float",
    "float_list",
    "nonnegative_float",
    "params_from_args",
    "positive_float",
    "positive_int",
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
