"""Reading input files with a size cap, so that ``--urdf /dev/zero`` fails at once.

Regular files larger than the cap are refused from their size alone; FIFOs
(``<(cmd)``, named pipes) and terminals are read up to the cap and refused
beyond it; devices, sockets and folders are refused without reading.
"""

from __future__ import annotations

import os
import stat
from pathlib import Path

from rrt_pin.errors import RrtPinError

__all__ = ["read_text_capped"]

_CHUNK = 1 << 20


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
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_CLOEXEC", 0))
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
        data = _read_at_most(fd, cap + 1)
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


def _read_at_most(fd: int, limit: int) -> bytes:
    parts: list[bytes] = []
    total = 0
    while total < limit:
        chunk = os.read(fd, min(_CHUNK, limit - total))
        if not chunk:
            break
        parts.append(chunk)
        total += len(chunk)
    return b"".join(parts)


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
