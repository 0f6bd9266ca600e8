"""Reading input files with a size cap, so that ``--urdf /dev/zero`` fails at once.

Regular files larger than the cap are refused from their size alone; FIFOs
(``<(cmd)``, named pipes) and terminals are read up to the cap and refused
beyond it; devices, sockets and folders are refused without reading. A FIFO
is opened without waiting for a writer, and refused when nothing comes
through it for :data:`FIFO_TIMEOUT` seconds (a named pipe nobody writes to
never blocks a command). :func:`load_toml` adds TOML's parse to the same
read, with its guards (nesting, 64-bit integers), for run files and sweep specs.
"""

from __future__ import annotations

import math
import os
import select
import stat
import sys
from pathlib import Path
from typing import Any

from rrt_pin.core.errors import RrtPinError

__all__ = ["FIFO_TIMEOUT", "check_int64", "load_toml", "read_text_capped"]

_CHUNK = 1 << 20
#: Longest wait for a FIFO's writer or its next bytes [s].
FIFO_TIMEOUT = 10.0


def read_text_capped(path: str | Path, *, cap: int, what: str, error: type[RrtPinError]) -> str:
    """The UTF-8 text of the file at ``path``, at most ``cap`` bytes of it.

    A UTF-8 byte-order mark at the start is dropped.

    Args:
        path: the file to read.
        cap: the largest size accepted [bytes].
        what: what the file is, for messages (e.g. ``"URDF"``, ``"scene file"``).
        error: the exception type raised (e.g. ``UrdfError``).

    Raises:
        error: one line naming ``what`` and the path: it cannot be opened or
            read, is a folder or a device, is larger than ``cap``, or is not UTF-8.
    """
    name = str(path)
    try:  # O_NONBLOCK: a FIFO without a writer must not block the open
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise error(f"cannot read {what} {name!r}: {e.strerror}") from None
    try:
        mode = os.fstat(fd).st_mode
        if stat.S_ISDIR(mode):
            raise error(f"cannot read {what} {name!r}: it is a folder")
        if stat.S_ISREG(mode):
            size = os.fstat(fd).st_size
            if size > cap:
                raise error(f"{what} {name!r} is {size} bytes, larger than the {_mb(cap)} allowed")
        elif not (stat.S_ISFIFO(mode) or (stat.S_ISCHR(mode) and os.isatty(fd))):
            kind = _kind(mode)
            raise error(f"cannot read {what} {name!r}: it is {kind}, not a regular file")
        os.set_blocking(fd, True)
        wait = FIFO_TIMEOUT if stat.S_ISFIFO(mode) else None
        data = _read_at_most(fd, cap + 1, wait)
        if data is None:
            raise error(
                f"cannot read {what} {name!r}: it is a FIFO and nothing came through it "
                f"for {FIFO_TIMEOUT:g} s"
            )
    except OSError as e:
        raise error(f"cannot read {what} {name!r}: {e.strerror}") from None
    finally:
        os.close(fd)
    if len(data) > cap:
        raise error(f"{what} {name!r} is larger than the {_mb(cap)} allowed")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise error(
            f"{what} {name!r} is not UTF-8 text (byte 0x{data[e.start]:02x} at offset {e.start})"
        ) from None


def _read_at_most(fd: int, limit: int, wait: float | None = None) -> bytes | None:
    """At most ``limit`` bytes; None when ``wait`` seconds pass with nothing to read."""
    parts: list[bytes] = []
    total = 0
    while total < limit:
        if wait is not None and not _readable(fd, wait):
            return None
        chunk = os.read(fd, min(_CHUNK, limit - total))
        if not chunk:
            break
        parts.append(chunk)
        total += len(chunk)
    return b"".join(parts)


def _readable(fd: int, wait: float) -> bool:
    """Whether ``fd`` has bytes (or its end) within ``wait`` seconds.

    A FIFO no writer ever opened is not readable (Linux reports neither data nor
    hang-up); one whose writers closed it is (its end).
    """
    poller = select.poll()
    poller.register(fd, select.POLLIN | select.POLLHUP)
    return bool(poller.poll(int(wait * 1000)))


def load_toml(path: str | Path, *, cap: int, what: str, error: type[RrtPinError]) -> dict[str, Any]:
    """The TOML document in the file at ``path`` (read by :func:`read_text_capped`).

    Args:
        path: the file.
        cap: the largest size accepted [bytes].
        what: what the file is, for messages (``"scene file"``, ``"sweep spec"``).
        error: the exception type raised.

    Raises:
        error: one line: the file cannot be read (see :func:`read_text_capped`), is
            not TOML, or is nested too deeply to parse.
    """
    # Imported here: the parser compiles its regular expressions when imported, and most
    # runs read no TOML (their commands only check that --config is not given).
    if sys.version_info >= (3, 11):
        import tomllib
    else:  # pragma: no cover - Python 3.10
        import tomli as tomllib

    name = str(path)
    text = read_text_capped(path, cap=cap, what=what, error=error)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as e:
        raise error(f"{what} {name!r} is not valid TOML: {e}") from e
    except (RecursionError, MemoryError):
        raise error(f"{what} {name!r} is not valid TOML: nested too deeply") from None


def check_int64(where: str, name: str, value: object, error: type[RrtPinError]) -> None:
    """Refuse an integer beyond TOML's 64-bit range (tomllib returns them unbounded).

    Raises:
        error: ``"{where}: {name} is an integer of about N digits, beyond TOML's
            64-bit range"``.
    """
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 63:
        digits = int(value.bit_length() * math.log10(2)) + 1
        raise error(
            f"{where}: {name} is an integer of about {digits} digits, beyond TOML's 64-bit range"
        )


def _mb(size: int) -> str:
    if size >= 1 << 20:
        return f"{size / (1 << 20):.3g} MB"
    if size >= 1 << 10:
        return f"{size / (1 << 10):.3g} kB"
    return f"{size} bytes"


def _kind(mode: int) -> str:
    if stat.S_ISCHR(mode):
        return "a character device"
    if stat.S_ISBLK(mode):
        return "a block device"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "not a file"
