"""How numbers and lists read in messages and summaries: durations, long name lists."""

from __future__ import annotations

import math
from collections.abc import Sequence

__all__ = ["duration", "names"]


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
