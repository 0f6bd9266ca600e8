"""How numbers, lists and arguments read in messages and summaries.

Durations, long name lists, and the spelling of an argument: messages name the
library's argument (``method``, ``rtol``) when a Python caller gets them, the
command line's flag (``--method``, ``--rtol``) when the CLI runs (it sets
:data:`SPELLING` while a command runs).
"""

from __future__ import annotations

import contextlib
import math
from collections.abc import Iterator, Sequence
from contextvars import ContextVar

__all__ = ["SPELLING", "argument", "cli_spelling", "duration", "names"]

#: How messages spell an argument: ``"library"`` (its name, ``rtol``) or ``"cli"`` (its
#: flag, ``--rtol``).
SPELLING: ContextVar[str] = ContextVar("rrt_pin_spelling", default="library")


def argument(name: str, flag: str | None = None) -> str:
    """``name`` as the caller wrote it: the argument's name, or its flag under the CLI.

    Args:
        name: the library's argument (``"rtol"``).
        flag: the CLI's flag when it is not ``--`` + the name with dashes
            (``"--plot"`` for ``path``).
    """
    if SPELLING.get() == "cli":
        return flag or "--" + name.replace("_", "-")
    return name


@contextlib.contextmanager
def cli_spelling() -> Iterator[None]:
    """Spell arguments as the command line's flags while the block runs."""
    token = SPELLING.set("cli")
    try:
        yield
    finally:
        SPELLING.reset(token)


def _number(x: float) -> str:
    """Three significant digits, without an exponent (thousands grouped)."""
    return f"{x:.3g}" if abs(x) < 1000 else f"{x:,.0f}"


def duration(seconds: float) -> str:
    """``seconds`` [s] as a person would write it: "0.42 ms", "62.5 s", "3.5 min", "2.1 h", "12 d"."""
    if not math.isfinite(seconds):
        return f"{seconds} s"
    s = abs(seconds)
    if s < 1e-3:
        return f"{_number(seconds * 1e6)} µs"
    if s < 1:
        return f"{_number(seconds * 1e3)} ms"
    if s < 120:
        return f"{_number(seconds)} s"
    if s < 7200:
        return f"{_number(seconds / 60)} min"
    if s < 172800:
        return f"{_number(seconds / 3600)} h"
    return f"{_number(seconds / 86400)} d"


def names(items: Sequence[str], limit: int = 8, sep: str = ", ") -> str:
    """``items`` joined, or its first ``limit`` and how many there are: "a, b, … (3,000 names)"."""
    items = [str(x) for x in items]
    if len(items) <= limit:
        return sep.join(items)
    return f"{sep.join(items[:limit])}{sep}… ({len(items):,} names)"
