"""A sweep folder's files, one at a time: names, safe opens under a folder descriptor, writes.

The low half of :mod:`rrt_pin.sweeps.store` (which holds the rules): every name
is opened relative to the folder's descriptor with ``O_NOFOLLOW``, a file is
written to a hidden temporary file and linked (exclusive) or renamed into place,
and a manifest is checked for its shape before it is trusted.
"""

from __future__ import annotations

import contextlib
import errno
import logging
import os
import re
import stat
from pathlib import Path
from typing import Any

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.io.targets import _PROBLEMS

__all__ = [
    "CHUNKS",
    "LOCK",
    "MANIFEST",
    "TRAJECTORIES",
    "chunk_name",
    "chunk_problem",
    "folder_path",
]

logger = logging.getLogger("rrt_pin")

MANIFEST = "manifest.json"
LOCK = "sweep.lock"
CHUNKS = "chunks"
TRAJECTORIES = "trajectories"
#: A manifest larger than this is not one of ours [bytes].
MAX_MANIFEST = 64 << 20
#: How long a run refused by the lock waits for the holder's pid to appear [s].
PID_WAIT = 0.5

_CHUNK = re.compile(r"chunk-(\d+)\.parquet")
_TEMP = re.compile(r"\..+\.[0-9a-f]{8}\.tmp")  # our temporary files (see _put)
_NOFOLLOW = os.O_NOFOLLOW | os.O_CLOEXEC
_DIR = os.O_RDONLY | os.O_DIRECTORY | _NOFOLLOW
#: Manifest keys a resumed sweep relies on, and their types.
_KEYS = {"spec_hash": str, "chunk": int, "done": list}
_WORDS = {str: "a string", int: "an integer", list: "a list"}
#: What ``link`` says on a file system without hard links.
_NO_LINKS = {
    errno.EPERM,
    errno.EOPNOTSUPP,
    getattr(errno, "ENOTSUP", errno.EOPNOTSUPP),
    errno.EMLINK,
}


def folder_path(out: object) -> Path:
    """``out`` as a folder's path, refusing None, lists and the empty string.

    Raises:
        InputError: ``out`` is not a ``str`` or ``os.PathLike``, or is empty (it
            would mean the current folder).
    """
    if not isinstance(out, (str, os.PathLike)):
        raise InputError(
            f"out must be a folder's path (str or os.PathLike), not {type(out).__name__}"
        )
    text = os.fspath(out)
    if not isinstance(text, str) or not text.strip():
        raise InputError(f"out={text!r} must not be empty (a folder's path)")
    return Path(text)


def chunk_name(k: int) -> str:
    """The file name of chunk ``k``."""
    return f"chunk-{k:06d}.parquet"


def _table(columns: dict[str, np.ndarray], metadata: dict[str, str]) -> Any:
    import pyarrow as pa

    arrays = {}
    for name, col in columns.items():
        col = np.asarray(col)
        arrays[name] = pa.array(col.tolist() if col.dtype == object else col)
    table = pa.table(arrays)
    return table.replace_schema_metadata({k: str(v) for k, v in metadata.items()})


def _parquet_bytes(table: Any) -> bytes:
    import pyarrow as pa
    import pyarrow.parquet as pq

    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)  # snappy: cheap for the process that writes every chunk
    return sink.getvalue().to_pybytes()


def _problem(e: OSError) -> str:
    if e.errno == errno.ELOOP:
        return "it is a symbolic link (not followed)"
    return _PROBLEMS.get(e.errno or 0, e.strerror or str(e))


def _kind(mode: int) -> str:
    if stat.S_ISDIR(mode):
        return "a folder"
    if stat.S_ISLNK(mode):
        return "a symbolic link"
    if stat.S_ISFIFO(mode):
        return "a FIFO"
    if stat.S_ISCHR(mode) or stat.S_ISBLK(mode):
        return "a device node"
    if stat.S_ISSOCK(mode):
        return "a socket"
    return "a regular file"


def _open_regular(name: str, dir_fd: int) -> int:
    """A read descriptor of the regular file ``name``: never through a link, never blocking."""
    fd = os.open(name, os.O_RDONLY | os.O_NONBLOCK | _NOFOLLOW, dir_fd=dir_fd)
    mode = os.fstat(fd).st_mode
    if not stat.S_ISREG(mode):
        os.close(fd)
        raise InputError(f"is {_kind(mode)}, not a regular file")
    return fd


def _lstat(name: str, dir_fd: int) -> os.stat_result | None:
    try:
        return os.stat(name, dir_fd=dir_fd, follow_symlinks=False)
    except FileNotFoundError:
        return None


def _subfolder(parent: int, name: str, create: bool) -> int | None:
    """A descriptor of the real folder ``name`` in ``parent`` (None if missing and not created)."""
    if create:
        with contextlib.suppress(FileExistsError):
            os.mkdir(name, 0o777, dir_fd=parent)
    try:
        return os.open(name, _DIR, dir_fd=parent)
    except FileNotFoundError:
        return None


def _not_writable(folder: Path) -> str | None:
    """Why ``folder`` cannot take new files (read-only file system, permissions), or None."""
    if os.access(folder, os.W_OK | os.X_OK):
        return None
    try:
        read_only = bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except OSError:
        read_only = False
    return _PROBLEMS[errno.EROFS if read_only else errno.EACCES]


def _remove_temps(fd: int) -> None:
    """Remove the temporary files an interrupted run left (ours by their names)."""
    for name in os.listdir(fd):
        st = _lstat(name, fd)
        if _TEMP.fullmatch(name) and st is not None and stat.S_ISREG(st.st_mode):
            with contextlib.suppress(FileNotFoundError):
                os.unlink(name, dir_fd=fd)


def _check_manifest(data: object, where: str) -> dict[str, Any]:
    """``data`` if it has a sweep manifest's shape; one line naming what is wrong otherwise."""
    bad = f"{where} is not a sweep's manifest"
    if not isinstance(data, dict):
        raise InputError(f"{bad}: a JSON {type(data).__name__}, not an object")
    for key, kind in _KEYS.items():
        if key not in data:
            raise InputError(f"{bad}: it has no {key!r}")
        value = data[key]
        if not isinstance(value, kind) or isinstance(value, bool):
            raise InputError(f"{bad}: {key!r} must be {_WORDS[kind]}, not {type(value).__name__}")
    if data["chunk"] < 1:
        raise InputError(f"{bad}: 'chunk' is {data['chunk']}, not >= 1")
    wrong = [k for k in data["done"] if not isinstance(k, int) or isinstance(k, bool) or k < 0]
    if wrong:
        raise InputError(f"{bad}: 'done' lists {wrong[0]!r}, not a chunk number")
    return data


def chunk_problem(chunks: int, k: int, manifest: dict[str, Any]) -> str | None:
    """Why chunk ``k`` cannot be trusted, or None if it holds exactly its variants.

    ``chunks``: the descriptor of the sweep's open ``chunks/`` folder.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    n, size = manifest["variants"], manifest["chunk"]
    if k >= manifest["chunks"]:
        return f"is beyond the sweep's {manifest['chunks']} chunks"
    start, stop = k * size, min((k + 1) * size, n)
    try:
        fd = _open_regular(chunk_name(k), chunks)
    except FileNotFoundError:
        return "is missing"
    except InputError as e:
        return str(e)
    except OSError as e:
        if e.errno == errno.ELOOP:
            return "is a symbolic link (not followed)"
        return f"cannot be read ({_problem(e)})"
    try:
        with os.fdopen(fd, "rb") as fh:
            meta = pq.ParquetFile(fh)
            tags = meta.schema_arrow.metadata or {}
            theirs = tags.get(b"rrt_pin.spec_hash", b"").decode("utf-8", "replace")
            if theirs != manifest["spec_hash"]:
                return f"belongs to another spec (hash {theirs[:16] or 'none'})"
            if meta.metadata.num_rows != stop - start:
                return f"holds {meta.metadata.num_rows} rows, not {stop - start}"
            table = meta.read()
    except (OSError, ValueError, pa.ArrowException) as e:
        first = str(e).splitlines()[0] if str(e) else type(e).__name__
        return f"is not readable Parquet ({first})"
    if "variant" not in table.column_names:
        return "has no 'variant' column"
    variant = table.column("variant").to_numpy(zero_copy_only=False)
    if not np.array_equal(variant, np.arange(start, stop)):
        return f"does not hold variants {start} to {stop - 1} in order"
    return None
