"""Where an output may go: each path checked (and planned) before anything is written.

The first half of :mod:`rrt_pin.io.files`: a path is resolved (links followed, ``-``
for standard output, ``/dev/fd/N``), its folder, name length, kind and permission
checked, and the space it needs looked for, so that a run refuses a bad output in
one line before it does its work. :class:`OutputError` is the one error of both.
"""

from __future__ import annotations

import contextlib
import errno
import io
import os
import re
import shutil
import stat
import sys
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import IO, Union

from rrt_pin.core.errors import InputError

__all__ = [
    "STDOUT",
    "OutputError",
    "PathLike",
    "Writer",
    "check_output",
    "check_outputs",
    "check_space",
]

#: The path that means standard output.
STDOUT = "-"

#: A function that writes an output's bytes to the binary file it is given.
Writer = Callable[[IO[bytes]], object]

PathLike = Union[str, "os.PathLike[str]"]

_SPOOL_BYTES = 32 << 20  # in-place outputs beyond this are staged in a temporary file
_NAME_MAX = 255  # bytes, when the file system does not say
_MAX_LINKS = 40  # symbolic links followed before giving up, as Linux does
_FD_DIR = re.compile(r"/proc/(self|thread-self|\d+)(?:/task/\d+)?/fd")
# Unnamed temporary files need O_TMPFILE and /proc/self/fd to give them a name.
_USE_TMPFILE = hasattr(os, "O_TMPFILE") and os.path.isdir("/proc/self/fd")
_NO_TMPFILE = {errno.EOPNOTSUPP, errno.EISDIR, errno.EINVAL, getattr(errno, "ENOTSUP", -1)}
# errno of an OSError from a writer that is about the output, not about the writer.
_OUTPUT_ERRNOS = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EIO, errno.EROFS}
_FULL = {errno.ENOSPC, errno.EDQUOT, errno.EFBIG}
_PROBLEMS = {
    errno.ENOENT: "no such file or folder",
    errno.ENOTDIR: "a part of the path is not a folder",
    errno.EISDIR: "it is a folder",
    errno.EACCES: "permission denied",
    errno.EPERM: "operation not permitted",
    errno.EROFS: "read-only file system",
    errno.ENOSPC: "no space left on device",
    errno.EDQUOT: "disk quota exceeded",
    errno.EFBIG: "file too large",
    errno.EIO: "input/output error",
    errno.ENAMETOOLONG: "file name too long",
    errno.ELOOP: "too many levels of symbolic links",
    errno.ENXIO: "no reader or no device behind it",
    errno.EPIPE: "broken pipe (the reader has gone)",
    errno.EBADF: "bad file descriptor",
}


class OutputError(InputError, OSError):
    """An output cannot be written; ``str(e)`` is one line naming the option and path.

    Attributes:
        message: the one-line message.
        errno: the OS error number (e.g. ``errno.ENOSPC``), or None.
        strerror: the problem alone, without the option and path.
        filename: the path as given.
    """

    def __init__(
        self,
        message: str,
        errno_: int | None = None,
        strerror: str | None = None,
        filename: str | None = None,
    ) -> None:
        if errno_ is None:
            OSError.__init__(self, message)
        else:
            OSError.__init__(self, errno_, strerror or message, filename)
        self.message = message

    def __str__(self) -> str:
        return self.message

    def __reduce__(self) -> tuple[object, ...]:
        return (type(self), (self.message, self.errno, self.strerror, self.filename))


@dataclass
class _Target:
    """Where one output goes, resolved (see :func:`_plan`)."""

    path: str  # as given
    flag: str | None
    kind: str  # "stdout", "fd", "special" (written in place), "replace" or "create"
    target: str  # absolute, symbolic links resolved ("-" for stdout)
    st: os.stat_result | None = None  # of what is there now
    fd: int | None = None  # for "fd": a descriptor of this process, written directly

    @property
    def in_place(self) -> bool:
        return self.kind in ("stdout", "fd", "special")

    def fail(self, problem: str, errno_: int | None = None) -> OutputError:
        return _error(self.flag, self.path, problem, errno_)

    def os_error(self, e: OSError) -> OutputError:
        """An OSError met while writing, as an :class:`OutputError`."""
        if isinstance(e, OutputError):
            return e
        problem = _PROBLEMS.get(e.errno or 0, e.strerror or str(e))
        if e.errno in _FULL:
            problem += "; the old file is unchanged" if self.kind == "replace" else ""
        return self.fail(problem, e.errno)


def _error(flag: str | None, path: str, problem: str, errno_: int | None = None) -> OutputError:
    where = f"{flag} {path!r}" if flag else repr(path)
    return OutputError(f"cannot write {where}: {problem}", errno_, problem, path)


def _name_max(folder: str) -> int:
    try:
        return os.pathconf(folder, "PC_NAME_MAX")
    except (OSError, ValueError):
        return _NAME_MAX


def _resolve(text: str, flag: str | None) -> tuple[str, bool]:
    """Follow symbolic links to the file they finally name.

    Returns:
        The absolute path, and whether it is a ``/proc/PID/fd/N`` entry (reached
        directly or through ``/dev/fd``, ``/dev/stdout``...), to be written in place.
    """
    p = text if os.path.isabs(text) else os.path.join(os.getcwd(), text)
    for _ in range(_MAX_LINKS):
        folder = os.path.realpath(os.path.dirname(p))
        p = os.path.join(folder, os.path.basename(p))
        if _FD_DIR.fullmatch(folder):
            return p, True
        if not os.path.islink(p):
            return p, False
        p = os.path.join(folder, os.readlink(p))
    raise _error(flag, text, _PROBLEMS[errno.ELOOP], errno.ELOOP)


def _own_fd(target: str) -> int | None:
    """N when ``target`` is ``/proc/PID/fd/N`` of this process, else None."""
    m = _FD_DIR.fullmatch(os.path.dirname(target))
    name = os.path.basename(target)
    if m and name.isdigit() and m.group(1) in ("self", "thread-self", str(os.getpid())):
        return int(name)
    return None


def _check_folder(t: _Target, folder: str) -> None:
    """Refuse a folder on a read-only file system or that this process cannot write."""
    try:
        read_only = bool(os.statvfs(folder).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):
        read_only = False
    if read_only:
        raise t.fail(f"{_PROBLEMS[errno.EROFS]} (folder {folder!r})", errno.EROFS)
    effective = os.access in os.supports_effective_ids
    if not os.access(folder, os.W_OK | os.X_OK, effective_ids=effective):
        raise t.fail(f"folder {folder!r} is not writable", errno.EACCES)


def _plan(path: PathLike, flag: str | None) -> _Target:
    """Resolve ``path`` and check what can be checked before writing.

    Raises:
        OutputError: the path cannot be written.
    """
    text = os.fspath(path)
    if text == STDOUT:
        return _Target(text, flag, "stdout", STDOUT)
    if not text:
        raise _error(flag, text, "the path is empty", errno.ENOENT)
    if text.endswith(os.sep):
        problem = "it is a folder" if os.path.isdir(text) else "a path ending in '/' names a folder"
        raise _error(flag, text, problem, errno.EISDIR)
    target, fd_link = _resolve(text, flag)
    t = _Target(text, flag, "create", target)
    if fd_link:
        t.kind, t.fd = "fd", _own_fd(target)
        try:
            t.st = os.stat(target)
        except OSError as e:
            if e.errno in (errno.ENOENT, errno.EBADF):
                number = os.path.basename(target)
                raise t.fail(f"file descriptor {number} is not open", e.errno) from e
            raise t.os_error(e) from e
        return t
    try:
        t.st = os.stat(target)
    except (FileNotFoundError, NotADirectoryError):
        t.st = None
    except OSError as e:
        if e.errno == errno.ENAMETOOLONG:
            _check_name(t)
        raise t.os_error(e) from e
    folder = os.path.dirname(target)
    if t.st is None:
        if not os.path.isdir(folder):
            raise _missing_folder(t, text, folder)
        _check_name(t)
        _check_folder(t, folder)
        return t
    mode = t.st.st_mode
    if stat.S_ISDIR(mode):
        raise t.fail("it is a folder", errno.EISDIR)
    if stat.S_ISREG(mode):
        t.kind = "replace"
        _check_folder(t, folder)
        effective = os.access in os.supports_effective_ids
        if not os.access(target, os.W_OK, effective_ids=effective):
            raise t.fail("the file is read-only", errno.EACCES)
        return t
    if stat.S_ISSOCK(mode):
        raise t.fail("it is a socket, not a file", errno.ENXIO)
    t.kind = "special"
    if not os.access(target, os.W_OK):
        raise t.fail(_PROBLEMS[errno.EACCES], errno.EACCES)
    return t


def _check_name(t: _Target) -> None:
    name = os.path.basename(t.target)
    folder = os.path.dirname(t.target)
    size, limit = len(os.fsencode(name)), _name_max(folder)
    if size > limit:
        raise t.fail(
            f"the file name is {size} bytes long, over the {limit} the file system allows",
            errno.ENAMETOOLONG,
        )


def _missing_folder(t: _Target, text: str, folder: str) -> OutputError:
    ancestor = folder
    while not os.path.lexists(ancestor) and os.path.dirname(ancestor) != ancestor:
        ancestor = os.path.dirname(ancestor)
    if os.path.lexists(ancestor) and not os.path.isdir(ancestor):
        return t.fail(f"{ancestor!r} is not a folder", errno.ENOTDIR)
    direct = os.path.join(os.getcwd(), text) if not os.path.isabs(text) else text
    if os.path.normpath(direct) != t.target and os.path.islink(direct):
        return t.fail(
            f"it is a symbolic link to {t.target!r}, whose folder does not exist", errno.ENOENT
        )
    shown = os.path.dirname(text) or "."
    return t.fail(f"folder {shown!r} does not exist", errno.ENOENT)


def _identities(t: _Target) -> set[tuple[object, ...]]:
    """Keys equal for two outputs that name the same file (character devices: none)."""
    if t.kind == "stdout":
        keys: set[tuple[object, ...]] = {("stdout",)}
        with contextlib.suppress(OSError, ValueError, AttributeError, io.UnsupportedOperation):
            st = os.fstat(sys.stdout.fileno())
            keys.add(("inode", st.st_dev, st.st_ino))
        return keys
    if t.st is not None and stat.S_ISCHR(t.st.st_mode):
        return set()  # /dev/null twice is harmless
    keys = {("path", os.path.normcase(t.target))}
    if t.st is not None:
        keys.add(("inode", t.st.st_dev, t.st.st_ino))
    return keys


def check_output(path: PathLike, flag: str | None = None) -> None:
    """Check up front that ``path`` can be written, without writing anything.

    Accepts ``-`` (stdout). Catches a missing folder, a folder, a dangling link
    whose folder is missing, a name longer than the file system allows (255
    bytes), a read-only file system, a folder or file the process may not write.

    Args:
        path: the output path as the user gave it.
        flag: the option it came from (e.g. ``--csv``), named in the message.

    Raises:
        OutputError: one line naming ``flag``, ``path`` and the problem.
    """
    _plan(path, flag)


def _plan_all(outputs: Iterable[tuple[PathLike | None, str | None]]) -> list[_Target]:
    plans: list[_Target] = []
    seen: list[tuple[_Target, set[tuple[object, ...]]]] = []
    for path, flag in outputs:
        if path is None:
            continue
        t = _plan(path, flag)
        keys = _identities(t)
        for other, other_keys in seen:
            if keys & other_keys:
                a, b = other.flag or repr(other.path), t.flag or repr(t.path)
                same = repr(t.path) if t.path == other.path else f"{other.path!r} and {t.path!r}"
                raise OutputError(
                    f"{a} and {b} name the same file {same}", errno.EINVAL, "same file", t.path
                )
        seen.append((t, keys))
        plans.append(t)
    return plans


def check_outputs(outputs: Iterable[tuple[PathLike | None, str | None]]) -> None:
    """Check the outputs of one run up front: each as :func:`check_output`, none twice.

    Args:
        outputs: ``(path, flag)`` pairs; a None path (an output not asked for) is skipped.

    Raises:
        OutputError: an output cannot be written, or two name the same file (the
            same path, a symbolic or hard link to the other, ``-`` twice), e.g.
            ``--csv and --plot name the same file 'out.csv'``.
    """
    _plan_all(outputs)


def check_space(path: PathLike | None, size: int, flag: str | None = None) -> None:
    """Refuse up front an output of about ``size`` bytes that the disk cannot hold.

    A file is staged next to its target (the old file stays until the rename), so
    the target folder's free space must hold all of it; stdout, FIFOs and devices
    are staged in the temporary folder beyond 32 MiB, whose free space is checked.

    Args:
        path: the output path as given (None or ``-`` for stdout are accepted).
        size: the estimated size of the output [bytes].
        flag: the option ``path`` came from, named in the message.

    Raises:
        OutputError: one line with the estimate and the free space (``errno.ENOSPC``).
    """
    if path is None:
        return
    t = _plan(path, flag)
    if t.in_place:
        if size <= _SPOOL_BYTES:
            return
        folder = tempfile.gettempdir()
    else:
        folder = os.path.dirname(t.target)
    try:
        free = shutil.disk_usage(folder).free
    except OSError:
        return
    if size > free:
        raise t.fail(
            f"no space left on device: the output would take about {_size(size)} but "
            f"{folder!r} has {_size(free)} free",
            errno.ENOSPC,
        )


def _size(n: float) -> str:
    for unit in ("bytes", "kB", "MB", "GB", "TB", "PB"):
        if n < 1000 or unit == "PB":
            return f"{n:.0f} {unit}" if unit == "bytes" else f"{n:.3g} {unit}"
        n /= 1000
    return f"{n:.3g} EB"  # pragma: no cover
