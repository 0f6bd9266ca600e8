"""Keep C and C++ libraries' chatter (urdfdom, assimp) off the terminal.

Pinocchio's URDF parser (urdfdom) and mesh loader (assimp) print errors and
warnings straight to file descriptor 2, bypassing Python. :func:`captured_stderr`
points descriptor 2 at a temporary file for the duration of a call and logs
what was captured at DEBUG level on the ``rrt_pin`` logger (``rrt-pin -v -v``
shows it). :func:`native_message` turns the text of their exceptions (which
name C++ source files, functions and lines) into one line for a user.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

from rrt_pin.core._logging import logger

__all__ = ["Captured", "captured_stderr", "native_message"]

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


# Lines of a C++ exception's text that locate it in the library's sources.
_WHERE = re.compile(r"^\s*(from file|in function|at line|hint)\s*:", re.IGNORECASE)
# A C++ source path, with its line if any (``/project/src/mesh_loader/assimp.cpp:91``).
_SOURCE = re.compile(r"\S+\.(?:cpp|cc|cxx|hpp|hxx|h)(?::\d+)?\b")
_RESOURCE = re.compile(r"^could not load resource (.+)$", re.IGNORECASE)
_NOT_FOUND = re.compile(r"^mesh (.+) could not be found\.?$", re.IGNORECASE)


def native_message(text: str, limit: int = 300) -> str:
    """One line for a user from a C++ library's exception text (Pinocchio, coal, assimp).

    Drops the lines that locate the error in the library's sources (``From file:
    /project/src/mesh_loader/assimp.cpp``, ``in function: ...``, ``at line: 91``)
    and its hints; a mesh that does not load becomes ``mesh file PATH does not
    load: REASON``, one that is missing ``mesh file PATH could not be found``.

    Args:
        text: the exception's text, possibly several lines.
        limit: the longest line returned [characters].
    """
    lines = []
    for line in str(text).splitlines():
        if _WHERE.match(line):
            continue
        line = re.sub(r"^\s*message\s*:\s*", "", line, flags=re.IGNORECASE)
        line = " ".join(_SOURCE.sub("", line).split())
        if line:
            lines.append(line)
    if not lines:
        return "an error without a message"
    if found := _NOT_FOUND.match(lines[0]):
        out = f"mesh file {found.group(1).strip()} could not be found"
    elif found := _RESOURCE.match(lines[0]):
        path = found.group(1).strip()
        reasons = []
        for line in lines[1:]:
            line = line.replace(f' "{path}"', "").replace(f" '{path}'", "")
            line = line.replace(f" for {path}", "").replace(f" {path}", "").rstrip(" .")
            if line:
                reasons.append(line[0].lower() + line[1:])
        out = f"mesh file {path} does not load"
        if reasons:
            out += ": " + "; ".join(reasons)
    else:
        out = "; ".join(line.rstrip(".") for line in lines)
    return out if len(out) <= limit else out[: limit - 1] + "…"
