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
naming the option and the path. It is an :class:`~rrt_pin.core.errors.InputError` (the
CLI prints it and exits 2) and an :class:`OSError` (``errno`` set) for callers that
catch those.

:func:`write_outputs` writes the several outputs of one run as one transaction;
:func:`check_outputs` checks them up front, before the run does its work (the checks
live in :mod:`rrt_pin.io.targets` and are offered here too).
"""

from __future__ import annotations

import contextlib
import errno
import functools
import os
import stat
import sys
import tempfile
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import IO

from rrt_pin.io.targets import (
    _NO_TMPFILE,
    _OUTPUT_ERRNOS,
    _SPOOL_BYTES,
    _USE_TMPFILE,
    STDOUT,
    OutputError,
    PathLike,
    Writer,
    _name_max,
    _plan_all,
    _Target,
    check_output,
    check_outputs,
    check_space,
)

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

_AT_FDCWD, _AT_SYMLINK_FOLLOW = -100, 0x400  # Linux


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

        from rrt_pin.io.files import write_outputs

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
