"""``rrt-pin urdf``: print or write the generated URDF of the RRT arm."""

from __future__ import annotations

import argparse
import sys

from rrt_pin.cli.commands._common import add_param_arguments, nonnegative_float, params_from_args
from rrt_pin.core._logging import note

HELP = "generate the URDF of the RRT arm (SI units: m, kg, kg·m²)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin urdf``."""
    parser.add_argument(
        "-o", "--output", metavar="PATH", help="write here (atomically); stdout if omitted"
    )
    parser.add_argument(
        "--min-inertia",
        type=nonnegative_float,
        default=0.0,
        metavar="X",
        help="raise every principal moment of inertia to at least X [kg·m²] for engines "
        "that refuse zero moments (MuJoCo); default 0 keeps the chapter's I1z = I2z = 0",
    )
    add_param_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Generate the URDF."""
    from rrt_pin.robot.urdf import urdf_xml

    xml = urdf_xml(params_from_args(args), min_inertia=args.min_inertia)
    if args.output:
        from rrt_pin.io.files import atomic_write_text

        atomic_write_text(args.output, xml)
        note(f"wrote {args.output}")
    else:
        sys.stdout.write(xml)
    return 0
