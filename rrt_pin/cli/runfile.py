"""Run files (``--config``): a TOML description of a run's setup, reusable by every command.

A run file holds parameter values (the chapter's symbols), options shared by
the commands that have them, and options for one command each::

    # run.toml
    [params]            # any field of rrt_pin.robot.params.Params, SI units
    m3 = 50.0
    q1f = "pi/3"        # strings may be small expressions (pi, tau, e, + - * / **)

    [options]           # for every command that has the option (others ignore it)
    tf = 15.0           # [s]

    [inverse]           # for `rrt-pin inverse` only
    dt = 0.001          # [s] sample interval
    [simulate]          # for `rrt-pin simulate` only
    dt = 0.01           # [s] output interval

Precedence: the chapter's values < ``[options]`` < the command's table < ``--set``
and explicit flags. A key of ``[options]`` must be an option of at least one
command, and a key of a command's table an option of that command.
"""

from __future__ import annotations

import math
from collections.abc import Collection
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rrt_pin.core.errors import OverrideError, RunFileError
from rrt_pin.io._read import check_int64, load_toml
from rrt_pin.robot.params import PARAM_DOCS, Params, param_names, parse_number

__all__ = ["MAX_RUNFILE_BYTES", "RunFile", "load_runfile", "resolve_params"]


@dataclass(frozen=True)
class RunFile:
    """A parsed run file: parameter overrides and command-option defaults.

    Attributes:
        params: the chapter's symbols -> values (SI units).
        options: ``[options]``, shared by every command that has the option.
        commands: command name -> its own table of options.
    """

    params: dict[str, float] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)
    commands: dict[str, dict[str, Any]] = field(default_factory=dict)

    def options_for(self, command: str) -> dict[str, Any]:
        """The options ``command`` takes from the file: ``[options]`` then its own table."""
        return {**self.options, **self.commands.get(command, {})}


#: Largest run file accepted [bytes].
MAX_RUNFILE_BYTES = 1 << 20


def load_runfile(path: str | Path, tables: Collection[str] = ()) -> RunFile:
    """Read a TOML run file (UTF-8, a byte-order mark allowed, at most 1 MB).

    Args:
        path: the run file.
        tables: the names of the tables it may hold besides ``[params]`` and
            ``[options]`` (the CLI passes its commands' names); any other table
            is refused.

    Raises:
        RunFileError: the file cannot be read, is larger than 1 MB, is not UTF-8
            or not TOML, has an unknown table or parameter, or a value that is
            not a finite number where one is due (or an integer beyond 64 bits).
    """
    path = Path(path)
    data = load_toml(path, cap=MAX_RUNFILE_BYTES, what="run file", error=RunFileError)
    names = tuple(tables)
    unknown = sorted(set(data) - {"params", "options", *names})
    if unknown:
        valid = (
            f"params, options or a command's name ({', '.join(names)})"
            if names
            else ("params, options")
        )
        raise RunFileError(f"run file {str(path)!r}: unknown table {unknown[0]!r}; valid: {valid}")
    raw = data.get("params", {})
    if not isinstance(raw, dict):
        raise RunFileError(f"run file {str(path)!r}: 'params' must be a table")
    params: dict[str, float] = {}
    for name, value in raw.items():
        if name not in PARAM_DOCS:
            raise RunFileError(
                f"run file {str(path)!r}: unknown parameter {name!r}; "
                f"valid names: {', '.join(param_names())}"
            )
        if isinstance(value, str):
            try:
                value = parse_number(value, name)
            except OverrideError as e:
                raise RunFileError(f"run file {str(path)!r}: {e}") from None
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise RunFileError(f"run file {str(path)!r}: {name}={value!r} is not a number")
        _check_int(path, name, value)
        params[name] = float(value)
    tables = {}
    for table in ("options", *names):
        options = data.get(table, {})
        if not isinstance(options, dict):
            raise RunFileError(f"run file {str(path)!r}: {table!r} must be a table")
        for name, value in options.items():
            if isinstance(value, float) and not math.isfinite(value):
                raise RunFileError(
                    f"run file {str(path)!r}: [{table}] {name}={value!r} must be finite"
                )
            _check_int(path, f"[{table}] {name}", value)
        tables[table] = dict(options)
    options = tables.pop("options")
    return RunFile(params=params, options=options, commands={k: v for k, v in tables.items() if v})


def _check_int(path: Path, name: str, value: object) -> None:
    """Refuse integers beyond TOML's 64-bit range (tomllib returns them unbounded)."""
    check_int64(f"run file {str(path)!r}", name, value, RunFileError)


def resolve_params(
    runfile: RunFile | None = None, overrides: dict[str, float] | None = None
) -> Params:
    """The chapter's parameters, updated by a run file's ``[params]``, then by ``--set`` overrides."""
    values: dict[str, float] = {}
    if runfile is not None:
        values.update(runfile.params)
    values.update(overrides or {})
    return Params().with_overrides(values)
