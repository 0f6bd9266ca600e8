"""``rrt-pin joints``: list a robot's joints, their kinds, columns and units."""

from __future__ import annotations

import argparse
import sys

from rrt_pin.cli.commands._common import add_param_arguments, params_from_args

HELP = "list a robot's joints: kinds, CSV columns and units (the chapter's arm, a URDF or a known robot)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin joints``."""
    group = parser.add_mutually_exclusive_group()
    group.add_argument("--urdf", metavar="PATH", help="a URDF file (default: the chapter's arm)")
    group.add_argument(
        "--robot",
        metavar="NAME",
        help="a robot known by name: rrt (the chapter's arm), or one of example-robot-data's "
        "(ur5, panda, double_pendulum, double_pendulum_continuous, kinova)",
    )
    add_param_arguments(parser)


def run(args: argparse.Namespace) -> int:
    """Print the joint table."""
    from rrt_pin.robot import robots

    params = params_from_args(args)
    if args.robot:
        robot = robots.get(args.robot, params)
    else:
        robot = robots.for_task("view", params, urdf=args.urdf)
    sys.stdout.write(robot.describe())
    return 0
