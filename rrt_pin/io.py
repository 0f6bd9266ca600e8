"""Writing outputs without destroying or corrupting what is at the path (stdlib only).

Every file rrt-pin writes goes through this module. What happens depends on what
the path names:

* ``-``: standard output (the Unix convention).
* a regular file, or nothing yet: the new content goes to a temporary file in the
  same folder, which is renamed over the path only once complete and synced. A
  reader, an exception, a full disk or a crash sees the old file or the new one,
  never a mix, and no temporary file is left behind (on Linux the temporary file
  has no name, ``O_TMPFILE``, until the instant before the rename). A replaced file
  keeps its permission bits (and its owner when the process may set it); a new file
  gets ``0o666`` less the umask, applied by the kernel as for any new file.
* a symbolic link: followed; its final target is replaced as above and the link
  stays a link. A dangling link creates the file it points to if that folder exists.
* anything else (FIFO, character or block device, ``/dev/stdout``, ``/dev/fd/N``,
  a shell's process substitution ``>(...)``): written in place, never renamed over
  nor removed. The content is formatted first (in memory up to 32 MiB, beyond that
  in an unnamed temporary file), so a failing writer sends nothing and memory stays
  bounded however long the output. A FIFO blocks until it has a reader, as with the
  shell's ``>``.

Problems a user can fix (a missing folder, a folder, a read-only file system or
folder, a name over 255 bytes, a full disk) raise :class:`OutputError`: one line
naming the option and the path. It is an :class:`~rrt_pin.errors.InputError` (the
CLI prints it and exits 2) and an :class:`OSError` (``errno`` set) for callers that
catch those.

:func:`write_outputs` writes the several outputs of one run as one transaction;
:func:`check_outputs` checks them up front, before the run does its work.
"""

from __future__ import annotations

import contextlib
import errno
import functools
import io
import os
import re
import shutil
import stat
import sys
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Union

from rrt_pin.errors import InputError

__all__ = [
    "STDOUT",
    "OutputError",
    "Writer",
    "atomic_write",
    "atomic_write_bytes",
    "atomic_write_text",
    "check_output",
    "check_outputs",
    "check_space",
    "write_outputs",
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
_AT_FDCWD, _AT_SYMLINK_FOLLOW = -100, 0x400  # Linux
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


@dataclass
class _Staged:
    """The complete new content of one output, not yet where it belongs."""

    target: _Target
    data: IO[bytes] | None = None  # in-place outputs: the bytes to send (spooled)
    fd: int | None = None  # files: the open temporary file
    tmpname: str | None = None  # files: its name (None while it is unnamed)

    def discard(self) -> None:
        if self.data is not None:
            with contextlib.suppress(OSError, ValueError):
                self.data.close()
            self.data = None
        if self.fd is not None:
            with contextlib.suppress(OSError):
                os.close(self.fd)
            self.fd = None
        if self.tmpname is not None:
            with contextlib.suppress(OSError):
                os.unlink(self.tmpname)
            self.tmpname = None


def _temp_names(folder: str, name: str, kind: str) -> Iterable[str]:
    """Hidden names next to ``name`` that fit the file system's name limit."""
    limit = _name_max(folder) - len(f"..{kind}.000000000000")
    raw = os.fsencode(name)[: max(limit, 1)]
    stem = raw.decode("utf-8", "ignore") or "out"
    for _ in range(100):
        yield os.path.join(folder, f".{stem}.{os.urandom(6).hex()}.{kind}")


def _open_temp(t: _Target) -> tuple[int, str | None]:
    folder, name = os.path.split(t.target)
    # A replaced file gets its old mode at the end; a new one 0o666 less the umask.
    mode = 0o600 if t.kind == "replace" else 0o666
    if _USE_TMPFILE:
        try:
            return os.open(folder, os.O_TMPFILE | os.O_RDWR, mode), None
        except OSError as e:
            if e.errno not in _NO_TMPFILE:
                raise
    for tmp in _temp_names(folder, name, "tmp"):
        try:
            return os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, mode), tmp
        except FileExistsError:
            continue
    raise FileExistsError(errno.EEXIST, "no free temporary file name", folder)


def _run_writer(t: _Target, writer: Writer, fh: IO[bytes]) -> None:
    try:
        writer(fh)
        fh.flush()
    except OSError as e:
        if e.errno in _OUTPUT_ERRNOS:
            raise t.os_error(e) from e
        raise


def _stage(t: _Target, writer: Writer) -> _Staged:
    """Run ``writer`` into memory (in-place outputs) or into a synced temporary file."""
    if t.in_place:
        buffer = tempfile.SpooledTemporaryFile(max_size=_SPOOL_BYTES)  # noqa: SIM115
        try:
            _run_writer(t, writer, buffer)  # type: ignore[arg-type]
            buffer.seek(0)
        except BaseException:
            buffer.close()
            raise
        return _Staged(t, data=buffer)  # type: ignore[arg-type]
    try:
        fd, tmpname = _open_temp(t)
    except OSError as e:
        raise t.os_error(e) from e
    staged = _Staged(t, fd=fd, tmpname=tmpname)
    try:
        fh = os.fdopen(fd, "wb", closefd=False)
        try:
            _run_writer(t, writer, fh)
        finally:
            with contextlib.suppress(OSError, ValueError):
                fh.close()
        try:
            os.fsync(fd)
            if t.st is not None:
                if (t.st.st_uid, t.st.st_gid) != (os.getuid(), os.getgid()):
                    with contextlib.suppress(OSError):
                        os.fchown(fd, t.st.st_uid, t.st.st_gid)
                os.fchmod(fd, stat.S_IMODE(t.st.st_mode))
        except OSError as e:
            raise t.os_error(e) from e
    except BaseException:
        staged.discard()
        raise
    return staged


def _write_all(fd: int, data: bytes) -> None:
    view = memoryview(data)
    while view:
        view = view[os.write(fd, view) :]


def _chunks(data: IO[bytes] | None) -> Iterable[bytes]:
    """The staged bytes, 1 MiB at a time."""
    while data is not None:
        chunk = data.read(1 << 20)
        if not chunk:
            return
        yield chunk


def _send(s: _Staged) -> None:
    """Write an in-place output: stdout, a descriptor of this process, a FIFO, a device."""
    t = s.target
    try:
        if t.kind == "stdout":
            sys.stdout.flush()
            out = getattr(sys.stdout, "buffer", None)
            for chunk in _chunks(s.data):
                if out is None:
                    sys.stdout.write(chunk.decode("utf-8", "replace"))
                else:
                    out.write(chunk)
            (out or sys.stdout).flush()
        elif t.fd is not None:
            for stream in (sys.stdout, sys.stderr):
                with contextlib.suppress(Exception):
                    if stream.fileno() == t.fd:
                        stream.flush()
            for chunk in _chunks(s.data):
                _write_all(t.fd, chunk)
        else:
            regular = t.st is not None and stat.S_ISREG(t.st.st_mode)
            flags = os.O_WRONLY | getattr(os, "O_NOCTTY", 0) | (os.O_TRUNC if regular else 0)
            fd = os.open(t.target, flags)
            try:
                for chunk in _chunks(s.data):
                    _write_all(fd, chunk)
            finally:
                os.close(fd)
    except OSError as e:
        raise t.os_error(e) from e


def _fsync_folder(folder: str) -> None:
    with contextlib.suppress(OSError, AttributeError):
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


@functools.lru_cache(maxsize=1)
def _linkat() -> Callable[..., int] | None:
    """The C library's ``linkat`` (``os.link`` cannot follow ``/proc`` links before 3.12)."""
    try:
        import ctypes

        return ctypes.CDLL(None, use_errno=True).linkat
    except (ImportError, OSError, AttributeError):
        return None


def _link_unnamed(fd: int, dst: str) -> None:
    """Give the unnamed (``O_TMPFILE``) file open as ``fd`` the name ``dst``."""
    src = f"/proc/self/fd/{fd}"
    linkat = _linkat()
    if linkat is None:
        os.link(src, dst, follow_symlinks=True)
        return
    import ctypes

    if linkat(_AT_FDCWD, os.fsencode(src), _AT_FDCWD, os.fsencode(dst), _AT_SYMLINK_FOLLOW):
        code = ctypes.get_errno()
        raise OSError(code, os.strerror(code), dst)


def _name_temp(s: _Staged, folder: str, name: str) -> str:
    """Name the staged unnamed file: link it, or else copy it to a new named file."""
    assert s.fd is not None
    for tmp in _temp_names(folder, name, "tmp"):
        try:
            _link_unnamed(s.fd, tmp)
            return tmp
        except FileExistsError:
            continue
        except OSError:
            break  # no linkat through /proc here: copy instead
    mode = stat.S_IMODE(os.fstat(s.fd).st_mode)
    for tmp in _temp_names(folder, name, "tmp"):
        try:
            out = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        except FileExistsError:
            continue
        try:
            size, offset = os.fstat(s.fd).st_size, 0
            while offset < size:
                sent = os.sendfile(out, s.fd, offset, size - offset)
                if sent == 0:
                    break
                offset += sent
            os.fchmod(out, mode)
            os.fsync(out)
        except BaseException:
            os.close(out)
            os.unlink(tmp)
            raise
        os.close(out)
        return tmp
    raise FileExistsError(errno.EEXIST, "no free temporary file name", folder)


def _commit(s: _Staged) -> None:
    """Rename a staged file over its target (naming it first if it has no name)."""
    t = s.target
    folder, name = os.path.split(t.target)
    try:
        if s.tmpname is None:
            s.tmpname = _name_temp(s, folder, name)
        os.replace(s.tmpname, t.target)
        s.tmpname = None
    except OSError as e:
        raise t.os_error(e) from e
    finally:
        s.discard()
    _fsync_folder(folder)


def _backup(t: _Target) -> str | None:
    """A hard link to the file about to be replaced, to restore it; None if impossible."""
    folder, name = os.path.split(t.target)
    for tmp in _temp_names(folder, name, "old"):
        try:
            os.link(t.target, tmp)
        except FileExistsError:
            continue
        except OSError:
            return None
        return tmp
    return None


def _commit_all(files: list[_Staged]) -> None:
    """Rename every staged file; if one fails, put back what the others replaced."""
    backups: list[str] = []
    done: list[tuple[_Staged, str | None]] = []
    try:
        for s in files:
            backup = None
            if len(files) > 1 and s.target.kind == "replace":
                backup = _backup(s.target)
                if backup is not None:
                    backups.append(backup)
            _commit(s)
            done.append((s, backup))
    except BaseException:
        for s, backup in reversed(done):
            with contextlib.suppress(OSError):
                if backup is not None:
                    os.replace(backup, s.target.target)
                elif s.target.kind == "create":
                    os.unlink(s.target.target)
        raise
    finally:
        for backup in backups:
            with contextlib.suppress(OSError):
                os.unlink(backup)


def write_outputs(outputs: Iterable[tuple[PathLike | None, str | None, Writer]]) -> list[Path]:
    """Write all the outputs of one run, or leave every pre-existing one as it was.

    The steps: check every output (as :func:`check_outputs`: no two may name the
    same file); run every writer into a synced temporary file next to its target
    (or into memory for stdout, FIFOs and devices); send the in-place outputs;
    then rename the temporary files over their targets. A failure in a writer, a
    full disk or an interrupt before the renames removes the temporary files and
    changes no file; should a rename itself fail, the files already replaced are
    put back from hard links made just before.

    Example::

        from rrt_pin.io import write_outputs

        write_outputs([
            (args.csv, "--csv", lambda fh: fh.write(text.encode())),
            (args.plot, "--plot", lambda fh: fig.savefig(fh, format="png")),
        ])

    Args:
        outputs: ``(path, flag, writer)`` triples. ``path`` is a path or ``-`` for
            stdout; a None path (an output not asked for) is skipped. ``flag`` is the
            option named in error messages (or None). ``writer`` writes the bytes to
            the binary file it is given: a temporary file, or a spooled buffer (in
            memory, then a temporary file) for stdout, FIFOs and devices (so it may
            always seek). It may write in blocks: nothing holds the whole output.

    Returns:
        The paths written, as given, in order.

    Raises:
        OutputError: an output cannot be written (one line naming its flag and
            path); no pre-existing output was changed.
        Exception: whatever a writer raised; no pre-existing output was changed.
    """
    items = [(path, flag, writer) for path, flag, writer in outputs if path is not None]
    plans = _plan_all((path, flag) for path, flag, _ in items)
    staged: list[_Staged] = []
    try:
        for t, (_, _, writer) in zip(plans, items, strict=True):
            staged.append(_stage(t, writer))
        for s in staged:
            if s.target.in_place:
                _send(s)
        _commit_all([s for s in staged if not s.target.in_place])
    finally:
        for s in staged:
            s.discard()
    return [Path(path) for path, _, _ in items]


def atomic_write(path: PathLike, writer: Writer, *, flag: str | None = None) -> Path:
    """Write one output: ``writer`` gets a binary file; see the module's rules.

    Args:
        path: the output path, or ``-`` for stdout.
        writer: writes the bytes to the binary file it is given.
        flag: the option ``path`` came from, named in error messages.

    Returns:
        ``path`` as a :class:`~pathlib.Path`.

    Raises:
        OutputError: ``path`` cannot be written; what was there is unchanged.
    """
    return write_outputs([(path, flag, writer)])[0]


def atomic_write_bytes(path: PathLike, data: bytes, *, flag: str | None = None) -> Path:
    """Write ``data`` to ``path`` (``-``: stdout) as :func:`atomic_write`."""
    return atomic_write(path, lambda fh: fh.write(data), flag=flag)


def atomic_write_text(path: PathLike, text: str, *, flag: str | None = None) -> Path:
    """Write ``text`` as UTF-8 to ``path`` (``-``: stdout) as :func:`atomic_write`."""
    return atomic_write_bytes(path, text.encode("utf-8"), flag=flag)
