"""The ``rrt-pin`` command line: ``main(argv)`` dispatches to ``rrt_pin.commands``.

Errors raised by rrt_pin (and argument errors) print one line on stderr and
exit with status 2; no traceback, nothing written.
"""

from __future__ import annotations

import argparse
import importlib
import logging
import sys
from collections.abc import Sequence
from types import ModuleType
from typing import TYPE_CHECKING

from rrt_pin.commands import COMMANDS
from rrt_pin.errors import RrtPinError, SceneError

if TYPE_CHECKING:
    from rrt_pin.scene import Scene

__all__ = ["main"]

EXIT_USAGE = 2


class _OneLineError(Exception):
    def __init__(self, prog: str, message: str) -> None:
        super().__init__(f"{prog}: error: {message}")


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line, without the usage block."""

    def error(self, message: str) -> None:  # type: ignore[override]
        raise _OneLineError(self.prog, message)


def _command_modules() -> dict[str, ModuleType]:
    modules = {}
    for name in COMMANDS:
        try:
            modules[name] = importlib.import_module(f"rrt_pin.commands.{name}")
        except ModuleNotFoundError as e:
            if e.name != f"rrt_pin.commands.{name}":
                raise
    return modules


def build_parser() -> tuple[argparse.ArgumentParser, dict[str, argparse.ArgumentParser]]:
    """The top-level parser and one subparser per available command."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        ver = version("rrt-pin")
    except PackageNotFoundError:  # running from a source tree
        ver = "unknown"
    parser = _Parser(
        prog="rrt-pin",
        description="Rigid-body dynamics of the RRT arm (and any URDF) with Pinocchio. "
        "SI units everywhere: s, m, rad, kg, N, N·m.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {ver}")
    parser.add_argument("-v", "--verbose", action="count", default=0, help="log more on stderr")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    subparsers = {}
    for name, module in _command_modules().items():
        p = sub.add_parser(name, help=module.HELP, description=module.HELP)
        module.add_arguments(p)
        p.set_defaults(_run=module.run)
        subparsers[name] = p
    return parser, subparsers


def _apply_scene(args: argparse.Namespace, subparser: argparse.ArgumentParser) -> Scene:
    """Load ``--scene`` and make its [options] the subparser's defaults."""
    from rrt_pin.scene import load_scene

    scene = load_scene(args.scene)
    dests = {a.dest for a in subparser._actions if a.dest not in ("help", "scene", "overrides")}
    for key, _value in scene.options.items():
        dest = key.replace("-", "_")
        if dest not in dests:
            raise SceneError(
                f"scene file {args.scene!r}: option {key!r} is not an option of "
                f"'rrt-pin {args.command}'; valid: {', '.join(sorted(dests))}"
            )
    subparser.set_defaults(**{k.replace("-", "_"): v for k, v in scene.options.items()})
    return scene


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 success, 2 bad input or failure)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    try:
        parser, subparsers = build_parser()
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        logging.basicConfig(
            level=logging.WARNING - 10 * min(args.verbose, 2),
            format="rrt-pin: %(message)s",
            stream=sys.stderr,
        )
        if getattr(args, "scene", None):
            scene = _apply_scene(args, subparsers[args.command])
            args = parser.parse_args(argv)  # explicit flags win over the scene's options
            args.scene_obj = scene
        return int(args._run(args) or 0)
    except _OneLineError as e:
        print(e, file=sys.stderr)
        return EXIT_USAGE
    except RrtPinError as e:
        print(f"rrt-pin: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("rrt-pin: interrupted", file=sys.stderr)
        return 130
