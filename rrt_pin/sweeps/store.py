"""A sweep's folder: one Parquet file per chunk, the kept trajectories, and a manifest.

Layout of ``OUT/``::

    manifest.json                 spec, its hash, variants, chunks, which are done
    sweep.lock                    held (``flock``) by the one run writing into the folder
    chunks/chunk-000042.parquet   variant index, varied values, metrics (units in metadata)
    trajectories/variant-17.parquet  t, q…, qd…, tau… of a kept variant

The rules, each checked before anything is computed or written:

* One writer: a run holds an exclusive, non-blocking ``flock`` on ``sweep.lock``
  from opening the folder to its end; a second run into the same folder stops
  with "another sweep is writing into 'OUT' (pid N)". The lock file stays (it
  holds the running writer's pid, emptied at its end); the kernel drops the
  lock when the run ends, even on SIGKILL.
* A new sweep adopts nothing: ``OUT`` must be missing, empty, or hold only an
  empty ``chunks/``, ``sweep.lock`` and temporary files (what a run stopped
  before its first manifest leaves). A folder with a manifest needs ``resume``.
* Nothing is written through a link or into a special file: the folder is
  opened once (``OUT`` itself may be a link to a folder) and every name inside
  it is opened with ``O_NOFOLLOW``. Each file is written to a new hidden
  temporary file (``O_EXCL``) in its own folder, synced, and then *linked* to
  its name (``link`` fails if anything is there: exclusive creation) or, for a
  file this run replaces on purpose, *renamed* over it. A rename replaces a
  symbolic link, FIFO or device node at the name by the file itself, never
  writing through it (on a file system without hard links the name is checked
  free, then renamed to); a crash leaves the old file or the new one, and the
  temporary files (``.NAME.XXXXXXXX.tmp``) it may leave are removed by the
  next run and ignored by Parquet readers (hidden names).
* ``resume`` trusts no file: the manifest must have the right shape and the
  spec's hash, and every chunk it lists as done is read back: a regular file,
  readable Parquet, the spec hash in its metadata, exactly the rows of its
  variant range in order. A chunk that fails is recomputed (a warning says
  which and why); one that passes is kept.
* ``chunks/`` holds chunks only, so ``pandas.read_parquet("OUT/chunks")`` reads
  this sweep and nothing else: ``resume`` refuses a folder whose ``chunks/``
  holds any other visible name (a stray file), naming it; the user moves it
  out. :meth:`Store.read` reads only the chunks the manifest lists.
* ``OUT/METRIC.png`` (``--plot``) goes through :func:`write_into`: the same
  temporary file and rename, so a link there is replaced, not written through.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import json
import logging
import os
import secrets
import stat
import time
from pathlib import Path
from typing import Any

import numpy as np

from rrt_pin._version import __version__
from rrt_pin.core.errors import InputError
from rrt_pin.io.targets import OutputError

__all__ = ["LOCK", "MANIFEST", "Store", "folder_path", "write_into"]

from rrt_pin.sweeps.folder import (
    _CHUNK,
    _DIR,
    _NO_LINKS,
    _NOFOLLOW,
    _TEMP,
    CHUNKS,
    LOCK,
    MANIFEST,
    MAX_MANIFEST,
    PID_WAIT,
    TRAJECTORIES,
    _check_manifest,
    _kind,
    _lstat,
    _not_writable,
    _open_regular,
    _parquet_bytes,
    _problem,
    _remove_temps,
    _subfolder,
    _table,
    chunk_name,
    chunk_problem,
    folder_path,
)

logger = logging.getLogger("rrt_pin")


class Store:
    """The output folder of one sweep (see the module's rules).

    A run calls :meth:`check` (reads only), :meth:`start` (creates the folder,
    takes the lock, verifies what a resumed sweep kept), :meth:`write_chunk` per
    chunk, and :meth:`close` at the end.
    """

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)
        self._fd: int | None = None  # the folder, while open
        self._chunks: int | None = None
        self._trajectories: int | None = None
        self._lock: int | None = None
        self._locked = False  # this run holds the lock
        self._replace: dict[str, set[str]] = {CHUNKS: set(), TRAJECTORIES: set()}

    # ------------------------------------------------------------------ names
    @property
    def manifest_path(self) -> Path:
        """The manifest's path."""
        return self.folder / MANIFEST

    def chunk_path(self, k: int) -> Path:
        """Where chunk ``k`` is stored."""
        return self.folder / CHUNKS / chunk_name(k)

    def _where(self, *names: str) -> str:
        return repr(str(self.folder.joinpath(*names)))

    def _os_error(self, e: OSError, *names: str) -> OutputError:
        problem = _problem(e)
        return OutputError(
            f"cannot write into the sweep folder {self._where(*names)}: {problem}",
            e.errno,
            problem,
            str(self.folder.joinpath(*names)),
        )

    # ------------------------------------------------------------------ reading
    def _open_folder(self) -> int | None:
        """A descriptor of the folder (following ``OUT`` itself if a link), None if missing."""
        path = self.folder
        try:
            st = path.lstat()
        except FileNotFoundError:
            parent = path.absolute().parent
            if not parent.is_dir():
                raise InputError(
                    f"sweep folder {self._where()}: its folder does not exist"
                ) from None
            return None
        except OSError as e:
            raise InputError(f"sweep folder {self._where()}: {_problem(e)}") from e
        if stat.S_ISLNK(st.st_mode) and not path.exists():
            raise InputError(
                f"sweep folder {self._where()} is a symbolic link to nothing "
                f"({os.readlink(path)!r}); remove it or name a folder"
            )
        if not path.is_dir():
            raise InputError(f"sweep folder {self._where()} is not a folder")
        try:
            return os.open(path, os.O_RDONLY | os.O_DIRECTORY | os.O_CLOEXEC)
        except OSError as e:
            raise InputError(f"sweep folder {self._where()}: {_problem(e)}") from e

    def _manifest_at(self, fd: int) -> dict[str, Any] | None:
        where = self._where(MANIFEST)
        try:
            mfd = _open_regular(MANIFEST, fd)
        except FileNotFoundError:
            return None
        except InputError as e:
            raise InputError(f"{where} {e}: not a sweep's manifest") from None
        except OSError as e:
            raise InputError(f"cannot read {where}: {_problem(e)}") from e
        with os.fdopen(mfd, "rb") as fh:
            try:
                raw = fh.read(MAX_MANIFEST + 1)
            except OSError as e:
                raise InputError(f"cannot read {where}: {_problem(e)}") from e
        if len(raw) > MAX_MANIFEST:
            raise InputError(f"{where} is not a sweep's manifest: over {MAX_MANIFEST >> 20} MiB")
        try:
            data = json.loads(raw.decode("utf-8"))
        except (UnicodeDecodeError, ValueError, RecursionError) as e:
            line = str(e).splitlines()[0] if str(e) else type(e).__name__
            raise InputError(f"{where} is not a sweep's manifest: not JSON ({line})") from None
        return _check_manifest(data, where)

    def read_manifest(self) -> dict[str, Any] | None:
        """The manifest (checked for shape), or None when the folder holds no manifest.

        Raises:
            InputError: the manifest is a link, a special file, not JSON or not of
                a manifest's shape; or the folder cannot be read.
        """
        fd = self._open_folder()
        if fd is None:
            return None
        try:
            return self._manifest_at(fd)
        finally:
            os.close(fd)

    def read(self) -> Any:
        """The chunks the manifest lists as done, as one pyarrow Table sorted by variant."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        fd = self._open_folder()
        if fd is None:
            raise InputError(f"sweep folder {self._where()} does not exist")
        try:
            manifest = self._manifest_at(fd)
            if manifest is None:
                raise InputError(f"{self._where()} holds no sweep (no {MANIFEST})")
            cfd = os.open(CHUNKS, _DIR, dir_fd=fd) if manifest["done"] else None
            tables = []
            try:
                for k in sorted(set(manifest["done"])):
                    try:
                        with os.fdopen(_open_regular(chunk_name(k), cfd), "rb") as fh:
                            tables.append(pq.read_table(fh))
                    except (OSError, InputError, pa.ArrowException) as e:
                        raise InputError(
                            f"cannot read {self._where(CHUNKS, chunk_name(k))}: {e}"
                        ) from e
            finally:
                if cfd is not None:
                    os.close(cfd)
        except OSError as e:
            raise InputError(f"cannot read the sweep in {self._where()}: {_problem(e)}") from e
        finally:
            os.close(fd)
        if not tables:
            raise InputError(f"{self._where()} holds no chunk yet")
        return pa.concat_tables(tables).sort_by("variant")

    # ------------------------------------------------------------------ checks
    def check(self, manifest: dict[str, Any], resume: bool) -> None:
        """Refuse, writing nothing, a folder this sweep cannot use.

        Raises:
            InputError: ``OUT`` is a file, a dangling link, or its parent is missing;
                it cannot be written; it holds another sweep and ``resume`` is false;
                it is not empty and holds no sweep; the manifest has the wrong shape;
                ``resume`` is true and the spec or chunk size differ, or ``chunks/``
                holds a file that is not one of this sweep's chunks.
        """
        fd = self._open_folder()
        if fd is None:
            problem = _not_writable(self.folder.absolute().parent)
            if problem:
                raise InputError(f"cannot create the sweep folder {self._where()}: {problem}")
            return
        try:
            self._check_unlocked(fd)
            self._inspect(fd, manifest, resume)
        finally:
            os.close(fd)
        problem = _not_writable(self.folder)
        if problem:
            raise InputError(f"cannot write into the sweep folder {self._where()}: {problem}")

    def _check_unlocked(self, fd: int) -> None:
        """Refuse a folder another run holds (tried with a shared lock, released at once)."""
        try:
            lock = os.open(LOCK, os.O_RDONLY | os.O_NONBLOCK | _NOFOLLOW, dir_fd=fd)
        except OSError:
            return  # no lock file (or not one): start() tells
        try:
            if not stat.S_ISREG(os.fstat(lock).st_mode):
                return
            try:
                fcntl.flock(lock, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except BlockingIOError:
                raise InputError(
                    f"another sweep is writing into {self._where()} (pid {self._holder(lock)})"
                ) from None
        finally:
            os.close(lock)  # releases the shared lock

    def _inspect(self, fd: int, manifest: dict[str, Any], resume: bool) -> dict[str, Any] | None:
        """The checks of :meth:`check` on the open folder; the old manifest (or None)."""
        old = self._manifest_at(fd)
        if old is None:
            self._check_empty(fd)
            return None
        if not resume:
            raise InputError(
                f"sweep folder {self._where()} already holds a sweep: resume it "
                "(--resume, resume=True) or choose another folder"
            )
        if old["spec_hash"] != manifest["spec_hash"]:
            raise InputError(
                f"cannot resume the sweep in {self._where()}: the spec changed since it was "
                f"started (hash {manifest['spec_hash']} vs {old['spec_hash']}); "
                "use another folder"
            )
        if old["chunk"] != manifest["chunk"]:
            raise InputError(
                f"cannot resume the sweep in {self._where()}: chunk={manifest['chunk']} but it "
                f"was started with chunk={old['chunk']}"
            )
        if old.get("backend", manifest.get("backend")) != manifest.get("backend"):
            raise InputError(
                f"cannot resume the sweep in {self._where()}: it ran on backend "
                f"{old['backend']!r}, which this process would not use (now "
                f"{manifest.get('backend')!r}): resume it where {old['backend']!r} runs"
            )
        for name in (CHUNKS, TRAJECTORIES):
            st = _lstat(name, fd)
            if st is not None and not stat.S_ISDIR(st.st_mode):
                raise InputError(f"{self._where(name)} is {_kind(st.st_mode)}, not a folder")
        self._check_strays(fd, manifest["chunks"])
        return old

    def _check_empty(self, fd: int) -> None:
        """Refuse a folder without a manifest that holds anything but an empty start."""
        for name in sorted(os.listdir(fd)):
            st = _lstat(name, fd)
            if st is None:
                continue
            if stat.S_ISREG(st.st_mode) and (name == LOCK or _TEMP.fullmatch(name)):
                continue  # what a run stopped before its first manifest leaves
            if name == CHUNKS and stat.S_ISDIR(st.st_mode):
                cfd = os.open(CHUNKS, _DIR, dir_fd=fd)
                try:
                    inside = [n for n in os.listdir(cfd) if not _TEMP.fullmatch(n)]
                finally:
                    os.close(cfd)
                if not inside:
                    continue
                name = f"{CHUNKS}/{sorted(inside)[0]}"
            raise InputError(
                f"sweep folder {self._where()} is not empty and holds no sweep (no {MANIFEST}; "
                f"it holds {name!r}): name a new or empty folder"
            )

    def _check_strays(self, fd: int, n_chunks: int) -> None:
        """Refuse a ``chunks/`` holding a visible name that is not one of this sweep's chunks."""
        try:
            cfd = os.open(CHUNKS, _DIR, dir_fd=fd)
        except FileNotFoundError:
            return
        try:
            for name in sorted(os.listdir(cfd)):
                if name.startswith((".", "_")):  # hidden from Parquet readers
                    continue
                m = _CHUNK.fullmatch(name)
                st = _lstat(name, cfd)
                ours = m is not None and chunk_name(int(m.group(1))) == name
                if not ours or int(m.group(1)) >= n_chunks:
                    raise InputError(
                        f"{self._where(CHUNKS, name)} is not a chunk of this sweep (a reader of "
                        f"{self._where(CHUNKS)} would take it in): move it out of the folder"
                    )
                if st is not None and stat.S_ISDIR(st.st_mode):
                    raise InputError(
                        f"{self._where(CHUNKS, name)} is a folder, not a chunk: move it out "
                        "of the folder"
                    )
        finally:
            os.close(cfd)

    # ------------------------------------------------------------------ writing
    def start(self, manifest: dict[str, Any], resume: bool) -> set[int]:
        """Open the folder for a sweep (after :meth:`check`); the chunks already done.

        Creates the folder, takes its lock, repeats :meth:`check`'s checks under the
        lock, removes an interrupted run's temporary files, verifies every chunk the
        old manifest lists (see the module's rules) and writes the new manifest.

        Raises:
            InputError: another run holds the lock; what :meth:`check` refuses; the
                folder cannot be written (``OutputError``).
        """
        try:
            self._start()
            old = self._inspect(self._fd, manifest, resume)
            self._replace[""] = set(os.listdir(self._fd))  # the manifest when resuming
            _remove_temps(self._fd)
            self._chunks = _subfolder(self._fd, CHUNKS, create=True)
            _remove_temps(self._chunks)
            self._replace[CHUNKS] = set(os.listdir(self._chunks))
            self._trajectories = _subfolder(self._fd, TRAJECTORIES, create=False)
            if self._trajectories is not None:
                _remove_temps(self._trajectories)
                self._replace[TRAJECTORIES] = set(os.listdir(self._trajectories))
            done = set() if old is None else self._verified(old["done"], manifest)
            self.manifest = dict(manifest, done=sorted(done))
            self._write_manifest()
        except BaseException as e:
            self.close()
            if isinstance(e, OSError) and not isinstance(e, OutputError):
                raise self._os_error(e) from e
            raise
        return done

    def _start(self) -> None:
        """Create and open the folder and take its lock."""
        try:
            self.folder.mkdir()
        except FileExistsError:
            pass
        fd = self._open_folder()
        if fd is None:  # removed between mkdir and open
            raise InputError(f"sweep folder {self._where()} vanished while it was opened")
        self._fd = fd
        try:
            lock = os.open(LOCK, os.O_RDWR | os.O_CREAT | os.O_NONBLOCK | _NOFOLLOW, 0o644,
                           dir_fd=fd)  # fmt: skip
        except OSError as e:
            if e.errno == errno.ELOOP:
                raise InputError(f"{self._where(LOCK)} is a symbolic link (not followed)") from e
            raise
        self._lock = lock
        mode = os.fstat(lock).st_mode
        if not stat.S_ISREG(mode):
            raise InputError(f"{self._where(LOCK)} is {_kind(mode)}, not a lock file")
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise InputError(
                f"another sweep is writing into {self._where()} (pid {self._holder(lock)})"
            ) from None
        self._locked = True
        os.ftruncate(lock, 0)
        os.pwrite(lock, f"{os.getpid()}\n".encode(), 0)

    @staticmethod
    def _holder(lock: int) -> str:
        """The pid the lock's holder wrote (it writes it just after taking the lock)."""
        deadline = time.monotonic() + PID_WAIT
        while True:
            text = os.pread(lock, 32, 0).decode("ascii", "replace").strip()
            if text.isdigit() or time.monotonic() > deadline:
                return text if text.isdigit() else "unknown"
            time.sleep(0.01)

    def _verified(self, listed: list[int], manifest: dict[str, Any]) -> set[int]:
        """The chunks of ``listed`` that pass their check; a warning names the others."""
        done, failed = set(), []
        for k in sorted(set(listed)):
            problem = chunk_problem(self._chunks, k, manifest)
            if problem is None:
                done.add(k)
            else:
                failed.append((k, problem))
                logger.info("chunk %d of %s %s: recomputing it", k, self._where(), problem)
        if failed:
            k, problem = failed[0]
            more = f" (and {len(failed) - 1} more)" if len(failed) > 1 else ""
            logger.warning(
                "resume: %d chunk(s) listed as done in %s failed their check and are recomputed: "
                "chunk %d %s%s",
                len(failed), self._where(MANIFEST), k, problem, more,
            )  # fmt: skip
        return done

    def _put(self, folder: str, name: str, data: bytes) -> None:
        """Write ``data`` as ``folder/name`` (see the module's rules: temp, then link or rename)."""
        fd = {CHUNKS: self._chunks, TRAJECTORIES: self._trajectories, "": self._fd}[folder]
        where = (folder, name) if folder else (name,)
        replace = name in self._replace.get(folder, ())  # else created exclusively
        temp = f".{name}.{secrets.token_hex(4)}.tmp"
        try:
            out = os.open(temp, os.O_WRONLY | os.O_CREAT | os.O_EXCL | _NOFOLLOW, 0o666,
                          dir_fd=fd)  # fmt: skip
            try:
                view = memoryview(data)
                while view:
                    view = view[os.write(out, view) :]
                os.fsync(out)
            finally:
                os.close(out)
            if replace:
                os.rename(temp, name, src_dir_fd=fd, dst_dir_fd=fd)
            else:
                self._create(fd, temp, name, where)
            os.fsync(fd)
        except OSError as e:
            with contextlib.suppress(OSError):
                os.unlink(temp, dir_fd=fd)
            raise self._os_error(e, *where) from e
        except BaseException:
            with contextlib.suppress(OSError):
                os.unlink(temp, dir_fd=fd)
            raise
        self._replace.setdefault(folder, set()).add(name)  # this run's own file from now on

    def _create(self, fd: int, temp: str, name: str, where: tuple[str, ...]) -> None:
        """Give ``temp`` the name ``name`` if nothing has it (``link``: exclusive creation)."""
        appeared = InputError(
            f"{self._where(*where)} appeared while this sweep was writing (another writer?): "
            "not replaced"
        )
        try:
            os.link(temp, name, src_dir_fd=fd, dst_dir_fd=fd, follow_symlinks=False)
        except FileExistsError:
            raise appeared from None
        except OSError as e:
            if e.errno not in _NO_LINKS:
                raise
            # a file system without hard links (FAT, some FUSE): the lock keeps other runs
            # out, and a name that is already there is refused as above
            if _lstat(name, fd) is not None:
                raise appeared from None
            os.rename(temp, name, src_dir_fd=fd, dst_dir_fd=fd)
            return
        finally:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(temp, dir_fd=fd)

    def _write_manifest(self) -> None:
        text = json.dumps(self.manifest, indent=1) + "\n"
        self._put("", MANIFEST, text.encode("utf-8"))

    def write_chunk(self, k: int, result: dict[str, Any], units: dict[str, str]) -> None:
        """Store chunk ``k`` (index, varied values, metrics) and its kept trajectories."""
        columns = {"variant": result["index"]}
        columns.update({name: col for name, col in result["values"].items()})
        columns.update(result["columns"])
        meta = {
            "rrt_pin.version": __version__,
            "rrt_pin.spec_hash": self.manifest["spec_hash"],
            "rrt_pin.units": json.dumps({n: units.get(n, "") for n in columns}),
        }
        self._put(CHUNKS, chunk_name(k), _parquet_bytes(_table(columns, meta)))
        for i, (t, q, qd, tau) in result["trajectories"].items():
            self.write_trajectory(i, t, q, qd, tau)
        self.manifest["done"] = sorted({*self.manifest["done"], k})
        self._write_manifest()

    def write_trajectory(self, i: int, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
                         tau: np.ndarray) -> None:  # fmt: skip
        """Store the dense run of variant ``i``."""
        names = self.manifest["columns"]
        cols = {"t": t}
        for k, name in enumerate(names["q"]):
            cols[name] = q[:, k]
        for k, name in enumerate(names["qd"]):
            cols[name] = qd[:, k]
        for k, name in enumerate(names["tau"]):
            cols[name] = tau[:, k]
        if self._trajectories is None:
            try:
                self._trajectories = _subfolder(self._fd, TRAJECTORIES, create=True)
            except OSError as e:
                raise self._os_error(e, TRAJECTORIES) from e
        data = _parquet_bytes(_table(cols, {"rrt_pin.variant": str(i)}))
        self._put(TRAJECTORIES, f"variant-{i}.parquet", data)

    def close(self) -> None:
        """Release the lock and the folder (the lock file stays, emptied of the pid)."""
        if self._locked and self._lock is not None:
            with contextlib.suppress(OSError):
                os.ftruncate(self._lock, 0)
            self._locked = False
        for attr in ("_chunks", "_trajectories", "_lock", "_fd"):
            fd = getattr(self, attr)
            if fd is not None:
                with contextlib.suppress(OSError):
                    os.close(fd)  # closing the lock's descriptor releases the flock
                setattr(self, attr, None)

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def write_into(folder: str | Path, name: str, data: bytes) -> Path:
    """Write ``data`` as the file ``name`` directly inside the sweep folder ``folder``.

    As the sweep's own files: a temporary file, then a rename over ``name``, so a
    link, FIFO or device node there is replaced, never written through.

    Raises:
        InputError: ``name`` is not a plain file name, the folder is missing, or the
            file cannot be written (``OutputError``).
    """
    if not name or "/" in name or name in (".", ".."):
        raise InputError(f"{name!r} is not a file name")
    store = Store(folder)
    store._fd = store._open_folder()
    if store._fd is None:
        raise InputError(f"sweep folder {store._where()} does not exist")
    try:
        store._replace[""] = {name}
        store._put("", name, data)
    finally:
        store.close()
    return store.folder / name
