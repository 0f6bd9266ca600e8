"""Keep C and C++ libraries' chatter (urdfdom, assimp) off the terminal.

Pinocchio's URDF parser (urdfdom) and mesh loader (assimp) print errors and
warnings straight to file descriptor 2, bypassing Python. :func:`captured_stderr`
points descriptor 2 at a temporary file for the duration of a call and logs
what was captured at DEBUG level on the ``rrt_pin`` logger (``rrt-pin -v -v``
shows it).
"""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from rrt_pin._logging import logger

__all__ = ["Captured", "captured_stderr"]

#: At most this much captured output is kept [bytes].
_KEEP = 64 * 1024


@dataclass
class Captured:
    """What a :func:`captured_stderr` block wrote on descriptor 2 (set when the block exits)."""

    text: str = ""

    def first_line(self, limit: int = 200) -> str:
        """The first non-blank captured line, stripped and cut to ``limit`` characters."""
        for line in self.text.splitlines():
            if line.strip():
                line = " ".join(line.split())
                return line if len(line) <= limit else line[: limit - 1] + "…"
        return ""


@contextmanager
def captured_stderr(label: str) -> Iterator[Captured]:
    """Capture file descriptor 2 (C/C++ stderr) for the duration of the block.

    Descriptor 2 is process-wide: output of other threads during the block is
    captured too (and logged). When descriptor 2 cannot be duplicated (closed),
    the block runs without capture.

    Args:
        label: names the source in the DEBUG log line (e.g. ``"urdfdom"``).

    Yields:
        A :class:`Captured` whose ``text`` is filled in when the block exits.
    """
    captured = Captured()
    try:
        sys.stderr.flush()
    except (AttributeError, OSError, ValueError):
        pass
    try:
        saved = os.dup(2)
    except OSError:
        yield captured
        return
    with tempfile.TemporaryFile() as tmp:
        try:
            os.dup2(tmp.fileno(), 2)
        except OSError:
            os.close(saved)
            yield captured
            return
        try:
            yield captured
        finally:
            try:
                sys.stderr.flush()
            except (AttributeError, OSError, ValueError):
                pass
            os.dup2(saved, 2)
            os.close(saved)
            tmp.seek(0)
            data = tmp.read(_KEEP)
            captured.text = data.decode("utf-8", errors="replace").strip()
            if captured.text:
                logger.debug("%s said on stderr: %s", label, captured.text)
