"""The ``rrt-pin`` command line: ``main(argv)`` dispatches to ``rrt_pin.cli.commands``.

Errors raised by rrt_pin (and argument errors) print one line on stderr and
exit with status 2; no traceback, nothing written.
"""

from __future__ import annotations

import argparse
import atexit
import contextlib
import gc
import importlib
import logging
import os
import re
import sys
from collections.abc import Callable, Iterator, Sequence
from types import ModuleType
from typing import TYPE_CHECKING, Any

from rrt_pin.cli.commands import COMMANDS
from rrt_pin.core.errors import RrtPinError, RunFileError
from rrt_pin.core.text import cli_spelling

if TYPE_CHECKING:
    from rrt_pin.cli.runfile import RunFile

__all__ = ["main"]

EXIT_USAGE = 2


class _OneLineError(Exception):
    def __init__(self, prog: str, message: str) -> None:
        super().__init__(f"{prog}: error: {message}")


class _Parser(argparse.ArgumentParser):
    """An ArgumentParser whose errors are one line, without the usage block.

    It keeps the options added to it in :attr:`options` (what ``add_argument``
    returned), so that run files can be checked against them without argparse's
    private attributes.
    """

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        self.options: list[argparse.Action] = []
        super().__init__(*args, **kwargs)

    def add_argument(self, *args: Any, **kwargs: Any) -> argparse.Action:  # type: ignore[override]
        action = super().add_argument(*args, **kwargs)
        self.options.append(action)
        return action

    def add_argument_group(self, *args: Any, **kwargs: Any) -> Any:  # noqa: D102
        return self._recording(super().add_argument_group(*args, **kwargs))

    def add_mutually_exclusive_group(self, **kwargs: Any) -> Any:  # noqa: D102
        return self._recording(super().add_mutually_exclusive_group(**kwargs))

    def _recording(self, group: Any) -> Any:
        """``group``, whose options are kept in :attr:`options` too."""
        add = group.add_argument

        def add_argument(*args: Any, **kwargs: Any) -> argparse.Action:
            action = add(*args, **kwargs)
            self.options.append(action)
            return action

        group.add_argument = add_argument
        return group

    def error(self, message: str) -> None:  # type: ignore[override]
        raise _OneLineError(self.prog, message)


def _command_modules(names: Sequence[str] = COMMANDS) -> dict[str, ModuleType]:
    modules = {}
    for name in names:
        try:
            modules[name] = importlib.import_module(f"rrt_pin.cli.commands.{name}")
        except ModuleNotFoundError as e:
            if e.name != f"rrt_pin.cli.commands.{name}":
                raise
    return modules


def build_parser(command: str | None = None) -> tuple[_Parser, dict[str, _Parser]]:
    """The top-level parser and one subparser per available command.

    Args:
        command: build only this command's subparser (a run imports only its own
            command's module); None builds them all (what ``--help``, a mistyped
            command and run files need).
    """
    from rrt_pin._version import __version__ as ver  # not importlib.metadata: ~20 ms

    parser = _Parser(
        prog="rrt-pin",
        description="Rigid-body dynamics of the RRT arm (and any URDF) with Pinocchio. "
        "SI units everywhere: s, m, rad, kg, N, N·m.",
    )
    parser.add_argument("--version", action="version", version=f"%(prog)s {ver}")
    # -v/-q anywhere on the line: before the command (defaults 0) or after it (the
    # subcommand's copies leave the namespace alone unless given).
    for where, default in ((parser, 0), (verbosity := _Parser(add_help=False), argparse.SUPPRESS)):
        where.add_argument(
            "-v",
            "--verbose",
            action="count",
            default=default,
            help="say more on stderr: what was chosen and why, timings (-vv: debug)",
        )
        where.add_argument("-q", "--quiet", action="count", default=default,
                           help="say less on stderr: only warnings and errors (-qq: errors)")  # fmt: skip
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    subparsers = {}
    modules = _command_modules((command,)) if command is not None else {}
    for name, module in (modules or _command_modules()).items():
        p = sub.add_parser(name, help=module.HELP, description=module.HELP, parents=[verbosity])
        module.add_arguments(p)
        p.set_defaults(command_run=module.run)
        subparsers[name] = p
    return parser, subparsers


def _option_value(where: str, action: argparse.Action, value: object) -> object:
    """A run file's option value, checked and converted by the same parser as its flag."""
    flag = action.option_strings[-1] if action.option_strings else action.dest
    if action.nargs == 0:  # a switch: store_true, store_false or --x/--no-x
        if not isinstance(value, bool):
            raise RunFileError(f"{where}: {flag} = {value!r} must be true or false")
        if isinstance(action, argparse.BooleanOptionalAction) or action.const is True:
            return value
        return not value  # store_false: "wrenches = false" means the flag's opposite
    if isinstance(value, bool) or not isinstance(value, (str, int, float, list)):
        raise RunFileError(f"{where}: {flag} = {value!r} is not a value of {flag}")
    if isinstance(value, list):
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in value):
            raise RunFileError(f"{where}: {flag} = {value!r} must be a list of numbers")
        text = ",".join(repr(float(v)) for v in value)
    else:
        text = str(value)
    try:
        converted = action.type(text) if action.type is not None else text
    except (argparse.ArgumentTypeError, TypeError, ValueError) as e:
        raise RunFileError(f"{where}: {flag} = {value!r}: {e}") from None
    if action.choices is not None and converted not in action.choices:
        valid = ", ".join(map(str, action.choices))
        raise RunFileError(f"{where}: {flag} = {value!r} is not one of {valid}")
    return converted


def _apply_runfile(
    args: argparse.Namespace, subparsers: dict[str, argparse.ArgumentParser]
) -> RunFile:
    """Load ``--config`` and make its options the command's defaults.

    ``[options]`` apply to every command that has them (a key no command has is
    refused); the command's own table applies to it alone (a key it lacks is
    refused). Each value passes the same parser as its flag (type, range,
    choices): a value from a file is held to what the same value on the command
    line is.
    """
    from rrt_pin.cli.runfile import load_runfile

    runfile = load_runfile(args.config, tables=COMMANDS)
    where = f"run file {args.config!r}"

    def actions(command: str) -> dict[str, argparse.Action]:
        skip = ("help", "config", "overrides", "verbose", "quiet")
        return {a.dest: a for a in subparsers[command].options if a.dest not in skip}

    mine = actions(args.command)
    everyone = {dest for command in subparsers for dest in actions(command)}
    for key in runfile.options:
        if key.replace("-", "_") not in everyone:
            raise RunFileError(
                f"{where}: [options] {key!r} is not an option of any command; "
                f"valid: {', '.join(sorted(everyone))}"
            )
    for command, table in runfile.commands.items():
        valid = actions(command) if command in subparsers else {}
        for key in table:
            if key.replace("-", "_") not in valid:
                raise RunFileError(
                    f"{where}: [{command}] {key!r} is not an option of 'rrt-pin {command}'; "
                    f"valid: {', '.join(sorted(valid))}"
                )
    defaults = {}
    own = runfile.commands.get(args.command, {})
    for key, value in runfile.options_for(args.command).items():
        dest = key.replace("-", "_")
        if dest in mine:
            label = f"{where} [{args.command if key in own else 'options'}]"
            defaults[dest] = _option_value(label, mine[dest], value)
    subparsers[args.command].set_defaults(**defaults)
    return runfile


#: What may come before the command on its line when only its subparser is built.
_BEFORE_COMMAND = re.compile(r"-[vq]+|--verbose|--quiet")


def _command_of(argv: list[str]) -> str | None:
    """The command ``argv`` runs, when it plainly names one after nothing but -v/-q; else None."""
    for token in argv:
        if token in COMMANDS:
            return token
        if not _BEFORE_COMMAND.fullmatch(token):
            return None
    return None


#: Options whose value is a comma-separated list that may start with a minus sign.
_LIST_OPTIONS = ("--q0", "--qd0", "--qf", "--kp", "--kd")


def _join_negative_lists(argv: list[str]) -> list[str]:
    """``--q0 -0.1,0.5,0.3`` as ``--q0=-0.1,0.5,0.3``: argparse takes the value for an option."""
    out: list[str] = []
    i = 0
    while i < len(argv):
        token = argv[i]
        nxt = argv[i + 1] if i + 1 < len(argv) else None
        if (
            token in _LIST_OPTIONS
            and nxt is not None
            and nxt[:1] == "-"
            and (nxt[1:2].isdigit() or nxt[1:2] == ".")
        ):
            out.append(f"{token}={nxt}")
            i += 2
            continue
        out.append(token)
        i += 1
    return out


class _Stderr(logging.StreamHandler):
    """A handler writing to whatever ``sys.stderr`` is when a record comes (tests swap it)."""

    def __init__(self) -> None:
        super().__init__(sys.stderr)

    @property
    def stream(self):  # noqa: ANN201
        return sys.stderr

    @stream.setter
    def stream(self, value) -> None:  # noqa: ANN001
        pass


@contextlib.contextmanager
def _log_to_stderr() -> Iterator[Callable[[int], None]]:
    """Show the ``rrt_pin`` logger's records as "rrt-pin: message" lines while a command runs.

    Yields the function that sets the level (once the flags are parsed); the
    logger's handlers, level and propagation are restored afterwards, so that a
    program calling :func:`main` (or a test) keeps its own logging.
    """
    logger = logging.getLogger("rrt_pin")
    saved = (logger.level, logger.propagate)
    handler = _Stderr()
    handler.setFormatter(logging.Formatter("rrt-pin: %(message)s"))
    logger.addHandler(handler)
    logger.propagate = False  # one line each, whatever the embedding program's root logger does
    try:
        yield logger.setLevel
    finally:
        logger.removeHandler(handler)
        logger.setLevel(saved[0])
        logger.propagate = saved[1]


def verbosity_level(verbose: int, quiet: int) -> int:
    """The ``rrt_pin`` logging level for ``-v``/``-q`` counts: notes by default (NOTICE)."""
    from rrt_pin.core._logging import NOTICE

    steps = [logging.ERROR, logging.WARNING, NOTICE, logging.INFO, logging.DEBUG]
    return steps[max(0, min(len(steps) - 1, 2 + verbose - quiet))]


#: OpenBLAS's thread count, read once, when numpy loads the library.
_BLAS_THREADS = "OPENBLAS_NUM_THREADS"


def _numpy_with_one_blas_thread() -> None:
    """Import numpy with one OpenBLAS thread, unless it is loaded or the user set the variable.

    numpy's OpenBLAS starts a pool of threads as it loads, and they spin, waiting for work,
    for a while after: CPU that a command's work never uses (its linear algebra is per
    sample, on matrices of a few joints, below OpenBLAS's threading thresholds; the
    threads that pay are numba's) taken from it where cores are few. The variable is
    removed at once, so that processes the command starts get OpenBLAS's default.
    """
    if "numpy" in sys.modules or _BLAS_THREADS in os.environ:
        return
    os.environ[_BLAS_THREADS] = "1"
    try:
        import numpy  # noqa: F401
    finally:
        os.environ.pop(_BLAS_THREADS, None)


def _no_collection_at_exit() -> None:
    """Let the process end without the interpreter's last collections of every object.

    At exit Python clears each module and collects cycles several times over, walking
    every object that numpy, Pinocchio and the run made. Moving them to the permanent
    generation first (:func:`gc.freeze`, an ``atexit`` handler, registered once) skips
    those walks; the objects go with the process, and Python never promised finalizers
    at exit for objects still alive.
    """
    atexit.unregister(gc.freeze)
    atexit.register(gc.freeze)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the CLI; returns the exit status (0 success, 2 bad input or failure).

    Without ``argv`` (the ``rrt-pin`` program, ``python -m rrt_pin``: ``sys.argv``), the
    process is taken to end with the command (:func:`_no_collection_at_exit`); with it
    (a program or test calling the CLI), the caller's garbage collection is left alone.
    """
    if argv is None:
        _no_collection_at_exit()
    argv = _join_negative_lists(list(sys.argv[1:] if argv is None else argv))
    for stream in (sys.stdout, sys.stderr):  # "N·m" on an ASCII terminal: never a traceback
        if hasattr(stream, "reconfigure"):
            try:
                stream.reconfigure(errors="backslashreplace")
            except (ValueError, OSError):  # pragma: no cover - a stream that cannot
                pass
    with _log_to_stderr() as set_level, cli_spelling():  # messages name flags, not arguments
        return _main(argv, set_level)


def _main(argv: list[str], set_level: Callable[[int], None]) -> int:
    try:
        command = _command_of(argv)
        if command is not None:  # it runs: every command's work needs numpy
            _numpy_with_one_blas_thread()
        parser, subparsers = build_parser(command)
        args = parser.parse_args(argv)
        if args.command is None:
            parser.print_help(sys.stderr)
            return EXIT_USAGE
        set_level(verbosity_level(args.verbose, args.quiet))
        if getattr(args, "config", None):
            if command is not None:  # a run file's [options] may hold any command's options
                parser, subparsers = build_parser()
                args = parser.parse_args(argv)
            runfile = _apply_runfile(args, subparsers)
            args = parser.parse_args(argv)  # explicit flags win over the run file's options
            args.runfile = runfile
        args.argv = ["rrt-pin", *argv]  # the command line, for the outputs' metadata
        return int(args.command_run(args) or 0)
    except _OneLineError as e:
        print(e, file=sys.stderr)
        return EXIT_USAGE
    except RrtPinError as e:
        print(f"rrt-pin: error: {e}", file=sys.stderr)
        return EXIT_USAGE
    except (
        MemoryError
    ) as e:  # what rrt_pin.core.memory's estimates before allocating did not foresee
        detail = f" ({e})" if str(e) else ""
        print(
            f"rrt-pin: error: out of memory{detail}: the run needs more than this process may "
            "take (ulimit -v, the cgroup's limit or the machine's memory); try fewer samples, "
            "joints or variants",
            file=sys.stderr,
        )
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("rrt-pin: interrupted", file=sys.stderr)
        return 130
