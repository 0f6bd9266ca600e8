"""A one-line progress counter on stderr for long runs (no dependency).

Shown only when stderr is a terminal (or with ``--progress``) and only once the
run has lasted :data:`DELAY` seconds, so short runs and captured output print
nothing extra.
"""

from __future__ import annotations

import sys
import time
from typing import TextIO

__all__ = ["DELAY", "Progress"]

#: Seconds before the counter first appears.
DELAY = 2.0


class Progress:
    """Counts rows done out of ``total`` and redraws ``rrt-pin: what 42 % (n / N rows)``.

    Args:
        total: rows the run will produce.
        what: what is being done (``"writing out.csv"``).
        force: show it even when stderr is not a terminal (``--progress``).
        stream: where to draw (default: stderr).
    """

    def __init__(
        self, total: int, what: str, force: bool = False, stream: TextIO | None = None
    ) -> None:
        self.stream = stream or sys.stderr
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = force or bool(isatty and isatty())
        self.total, self.what, self.done = max(int(total), 1), what, 0
        self.start = time.perf_counter()
        self._drawn = False
        self._last = 0.0

    def update(self, rows: int) -> None:
        """Add ``rows`` rows done; redraw at most five times a second."""
        self.done += rows
        if not self.enabled:
            return
        now = time.perf_counter()
        if now - self.start < DELAY or now - self._last < 0.2:
            return
        self._last = now
        self._draw(now)

    def _draw(self, now: float) -> None:
        rate = self.done / max(now - self.start, 1e-9)
        pct = 100.0 * self.done / self.total
        self.stream.write(
            f"\rrrt-pin: {self.what} {pct:3.0f} % ({self.done:,} / {self.total:,} rows, "
            f"{rate:,.0f} rows/s)"
        )
        self.stream.flush()
        self._drawn = True

    def close(self) -> None:
        """End the line if one was drawn."""
        if self._drawn:
            self._draw(time.perf_counter())
            self.stream.write("\n")
            self.stream.flush()
            self._drawn = False
