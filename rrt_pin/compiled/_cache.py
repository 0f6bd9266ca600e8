"""Where the compiled machine code lives on disk, and whether it is there.

Numba's own cache (``cache=True``) checks only the source file of the function
it caches, not the files that function calls into: regenerating
``rrt_pin/dynamics/_kernel_terms.py`` would leave stale machine code behind. So every compiled
function of this package is cached in a directory named by a fingerprint of
all the sources that go into the machine code (:data:`JIT_MODULES`), of where
they are, and of the Python, numba and llvmlite versions and the CPU. A new
source gets a new, empty directory; nothing stale is ever loaded.

The fingerprint also uses numba's own key, so that "is it cached?" answers
what the next process will pay: numba files its entries under the absolute
directory of each source file and, before numba 0.68, under the file's
modification time and size (from 0.68 on, a hash of its contents); its index
entries are keyed by the CPU. A fresh clone of the sources elsewhere, or a
home directory shared by two machines, therefore gets its own directory.
:func:`mark_ready` records, once every function is cached, each cache file and
its SHA-256; :func:`is_cached` requires all of them, unchanged, and
:func:`discard_damaged` deletes the ones that changed before numba reads them.
The ahead-of-time module kept in the same directory has its own record of its
size and SHA-256, checked before it is imported (:mod:`rrt_pin.compiled._aot`).

The base directory is, in order of preference:

1. ``$RRT_PIN_CACHE_DIR``;
2. ``$NUMBA_CACHE_DIR/rrt_pin`` (numba's own setting, respected);
3. ``$XDG_CACHE_HOME/rrt_pin/numba`` or ``~/.cache/rrt_pin/numba``;
4. ``<tempdir>/rrt_pin-<uid>/numba`` if none of the above is writable.

If no directory is writable, the functions are compiled in memory for the
process only. This module never imports numba (it must stay cheap: the CLI
asks :func:`is_cached` to choose a backend).
"""

from __future__ import annotations

import hashlib
import importlib.util
import json
import logging
import os
import platform
import re
import shutil
import sys
import tempfile
import warnings
from functools import lru_cache
from pathlib import Path
from typing import Any

__all__ = [
    "JIT_MODULES",
    "CacheWarning",
    "cache_dir",
    "generated_dir",
    "discard_damaged",
    "fingerprint",
    "is_cached",
    "is_ready",
    "mark_ready",
    "prune_superseded",
    "requested_dir",
    "warn_once",
]

#: Modules the machine code depends on: those defining jitted functions and those
#: whose values numba freezes into it as constants. Their text, path and (for
#: numba < 0.68) stamp are fingerprinted. Add any new such module here, e.g.
#: ``"rrt_pin.simulate.codes"``; a module ``rrt_pin.a.b`` is read from ``rrt_pin/a/b.py``.
JIT_MODULES: tuple[str, ...] = (
    "rrt_pin.dynamics._kernel_terms",
    "rrt_pin.dynamics.kernel",
    "rrt_pin.simulate.codes",
    "rrt_pin.compiled._jit_dynamics",
    "rrt_pin.compiled._jit_metrics",
    "rrt_pin.compiled._jit_integrators",
    "rrt_pin.compiled._jit_batch",
    "rrt_pin.compiled._jit",
    "rrt_pin.compiled._dop853_coefficients",
)
_READY = "READY.json"
_CACHE_SUFFIXES = (".nbi", ".nbc")
#: First numba version whose source stamp is a hash of the contents, not (mtime, size).
_NUMBA_CONTENT_STAMP = (0, 68)
_logger = logging.getLogger("rrt_pin")
_warned = False


class CacheWarning(RuntimeWarning):
    """The disk cache of machine code could not be used as is (damaged, full, read-only)."""


def _source_path(module: str) -> Path:
    """The absolute file of ``module`` without importing it (it may import numba)."""
    loaded = sys.modules.get(module)
    if loaded is not None and getattr(loaded, "__file__", None):
        return Path(os.path.abspath(loaded.__file__))
    package_dir = Path(__file__).parent.parent  # as numba: absolute, symbolic links kept
    parts = module.split(".")[1:]
    return Path(os.path.abspath(package_dir.joinpath(*parts).with_suffix(".py")))


def _version(dist: str) -> str:
    """The installed version of ``dist`` (``"absent"``), without importing it.

    Read from the name of its ``.dist-info`` directory beside the package (a few
    file-system calls); ``importlib.metadata`` (slow to import) only when
    there is none.
    """
    try:
        spec = importlib.util.find_spec(dist)
    except (ImportError, ValueError):
        spec = None
    if spec is None or not spec.origin:
        return "absent"
    site = Path(spec.origin).parent.parent
    found = sorted(site.glob(f"{dist}-*.dist-info"))
    if len(found) == 1:
        return found[0].name[len(dist) + 1 : -len(".dist-info")]
    from importlib import metadata

    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "absent"


def _numba_stamps_mtime(numba_version: str) -> bool:
    """Whether numba keys its cache by the source files' (mtime, size) (before 0.68)."""
    found = re.match(r"(\d+)\.(\d+)", numba_version)
    if found is None:
        return True  # unknown: the conservative answer (more misses, never a false hit)
    return (int(found[1]), int(found[2])) < _NUMBA_CONTENT_STAMP


def _cpu() -> str:
    """The CPU as numba's cache key sees it (cheap stand-in for LLVM's host name and features).

    Reads the first processor's model and flags from ``/proc/cpuinfo`` where there
    is one, and numba's overrides ``NUMBA_CPU_NAME`` and ``NUMBA_CPU_FEATURES``.
    """
    fields = [os.environ.get("NUMBA_CPU_NAME", ""), os.environ.get("NUMBA_CPU_FEATURES", "")]
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as f:
            for line in f:
                if not line.strip():
                    break  # end of the first processor's block
                key = line.split(":", 1)[0].strip()
                if key in ("vendor_id", "model name", "flags", "Features", "CPU part", "isa"):
                    fields.append(line.strip())
    except OSError:
        fields.append(platform.processor())
    return hashlib.sha256("\n".join(fields).encode()).hexdigest()[:16]


@lru_cache(maxsize=1)
def _fingerprint_inputs() -> tuple[str, dict[str, Any]]:
    numba_version = _version("numba")
    with_stamps = _numba_stamps_mtime(numba_version)
    sources: dict[str, dict[str, Any]] = {}
    for module in JIT_MODULES:
        path = _source_path(module)
        entry: dict[str, Any] = {"path": str(path)}
        try:
            data = path.read_bytes()
            st = path.stat()
        except OSError:
            entry["sha256"] = "<missing>"
        else:
            entry["sha256"] = hashlib.sha256(data).hexdigest()
            if with_stamps:
                entry["stamp"] = [st.st_mtime_ns, st.st_size]
        sources[module] = entry
    toolchain = {
        "python": sys.version,
        "numba": numba_version,
        "llvmlite": _version("llvmlite"),
        "machine": platform.machine(),
        "cpu": _cpu(),
    }
    described = {"sources": sources, "toolchain": toolchain}
    text = json.dumps(described, sort_keys=True).encode()
    return hashlib.sha256(text).hexdigest()[:20], described


def fingerprint() -> str:
    """The fingerprint of the compiled sources, their location and the toolchain (20 hex digits)."""
    return _fingerprint_inputs()[0]


def _location(described: dict[str, Any]) -> list[str]:
    """The source paths of a fingerprint's description (what tells two checkouts apart)."""
    return sorted(entry["path"] for entry in described["sources"].values())


def _base_candidates() -> list[Path]:
    out: list[Path] = []
    requested = requested_dir()
    if requested is not None:
        out.append(requested)
    xdg = os.environ.get("XDG_CACHE_HOME")
    home_cache = Path(xdg) if xdg else Path.home() / ".cache"
    out.append(home_cache / "rrt_pin" / "numba")
    uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
    out.append(Path(tempfile.gettempdir()) / f"rrt_pin-{uid}" / "numba")
    return out


def requested_dir() -> Path | None:
    """The base directory the user asked for, if any (``$RRT_PIN_CACHE_DIR``, ``$NUMBA_CACHE_DIR``)."""
    env = os.environ.get("RRT_PIN_CACHE_DIR")
    if env:
        return Path(env)
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        return Path(numba_dir) / "rrt_pin"
    return None


def _writable(path: Path) -> bool:
    try:
        path.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=path):
            pass
    except OSError:
        return False
    return True


def _could_write(path: Path) -> bool:
    """Whether ``path`` is, or could be created as, a writable directory (creates nothing)."""
    probe = path
    while not probe.exists():
        if probe.parent == probe:
            return False
        probe = probe.parent
    return probe.is_dir() and os.access(probe, os.W_OK | os.X_OK)


@lru_cache(maxsize=1)
def cache_dir() -> Path | None:
    """The writable directory for this fingerprint's machine code, or None.

    Creates the directory. None means no candidate is writable: compile in
    memory only.
    """
    fp = fingerprint()
    for base in _base_candidates():
        path = base / fp
        if _writable(path):
            return path
    return None


def _cache_files(path: Path) -> list[Path]:
    """Numba's index and data files under ``path``."""
    try:
        return sorted(p for p in path.rglob("*") if p.suffix in _CACHE_SUFFIXES and p.is_file())
    except OSError:
        return []


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _read_record(path: Path) -> dict[str, Any] | None:
    """The READY record of ``path`` if it is one for the current fingerprint, else None."""
    try:
        record = json.loads((path / _READY).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict) or record.get("fingerprint") != fingerprint():
        return None
    if not isinstance(record.get("files"), dict):
        return None
    return record


def _damaged(path: Path, record: dict[str, Any]) -> list[Path]:
    """The recorded cache files of ``path`` that are missing or whose contents changed."""
    out = []
    for name, digest in record["files"].items():
        file = path / name
        try:
            same = _sha256(file) == digest
        except OSError:
            same = False
        if not same:
            out.append(file)
    return out


def is_cached() -> bool:
    """Whether a complete compiled cache for the current sources exists on disk.

    Looks where :func:`cache_dir` would put it: true when it holds a READY
    record for the current fingerprint and every cache file it lists, unchanged
    (about 1.5 MB hashed). Creates nothing, never imports numba and never compiles.
    """
    fp = fingerprint()
    for base in _base_candidates():
        path = base / fp
        if _could_write(path):
            return is_ready(path)
    return False


def is_ready(path: Path) -> bool:
    """Whether ``path`` holds a READY record for the current fingerprint and every file it lists."""
    record = _read_record(path)
    return record is not None and not _damaged(path, record)


def discard_damaged(path: Path) -> list[Path]:
    """Delete the cache files of ``path`` that changed since :func:`mark_ready` recorded them.

    Numba would otherwise read them: a truncated file makes it raise, a corrupt
    one may load wrong machine code. Without a record there is nothing to check.
    The READY record is removed too when anything was damaged.

    Returns:
        The damaged files (deleted when possible).
    """
    record = _read_record(path)
    if record is None:
        return []
    damaged = _damaged(path, record)
    if damaged:
        for file in [*damaged, path / _READY]:
            try:
                file.unlink(missing_ok=True)
            except OSError:
                pass
    return damaged


def mark_ready(path: Path, signatures: dict[str, Any]) -> None:
    """Record that every function in ``signatures`` was compiled and saved in ``path``.

    The record lists every cache file under ``path`` with its SHA-256. Failing to
    write it (disk full, read-only) is ignored: the cache then counts as absent.
    """
    described = _fingerprint_inputs()[1]
    try:
        files = {str(f.relative_to(path)): _sha256(f) for f in _cache_files(path)}
    except OSError:
        return
    record = {
        "fingerprint": fingerprint(),
        "inputs": described,
        "location": _location(described),
        "files": files,
        **signatures,
    }
    tmp = path / f".{_READY}.{os.getpid()}.tmp"
    try:
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True), encoding="utf-8")
        os.replace(tmp, path / _READY)
    except OSError:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass


def prune_superseded(path: Path) -> list[Path]:
    """Delete the sibling cache directories that no process can load any more.

    A sibling is superseded when its READY record has the same source location
    and toolchain as ``path``'s but another fingerprint: the sources there have
    changed since (numba would not load those entries either). Directories of
    other checkouts, Python or numba versions, or without a record, are kept.

    Returns:
        The directories deleted.
    """
    described = _fingerprint_inputs()[1]
    location, toolchain = _location(described), described["toolchain"]
    removed = []
    try:
        siblings = [p for p in path.parent.iterdir() if p.is_dir() and p != path]
    except OSError:
        return removed
    for sibling in siblings:
        try:
            record = json.loads((sibling / _READY).read_text(encoding="utf-8"))
            inputs = record["inputs"]
            superseded = (
                record["fingerprint"] == sibling.name != path.name
                and record["location"] == location
                and inputs["toolchain"] == toolchain
            )
        except (OSError, ValueError, KeyError, TypeError):
            continue
        if superseded:
            shutil.rmtree(sibling, ignore_errors=True)
            removed.append(sibling)
    return removed


def _has_handler(logger: logging.Logger) -> bool:
    """Whether a record on ``logger`` reaches a handler that shows it (not a NullHandler)."""
    current: logging.Logger | None = logger
    while current is not None:
        if any(not isinstance(h, logging.NullHandler) for h in current.handlers):
            return True
        current = current.parent if current.propagate else None
    return False


def warn_once(message: str) -> None:
    """Say ``message`` (one line) once per process.

    On the ``rrt_pin`` logger at WARNING when logging is configured (the CLI
    does), else as a :class:`CacheWarning`, so that a library user sees it too
    (attributed to ``rrt_pin.compiled``, without a source line: one line on stderr).
    """
    global _warned
    if _warned:
        return
    _warned = True
    message = " ".join(message.split())
    if _has_handler(_logger):
        _logger.warning(message)
    else:
        warnings.warn_explicit(
            message, CacheWarning, filename="rrt_pin.compiled", lineno=0, module=__name__
        )


#: The generated modules' directory found writable, by the variables that name the candidates.
_GENERATED: dict[tuple[str | None, ...], Path] = {}
_NAMING = ("RRT_PIN_CACHE_DIR", "NUMBA_CACHE_DIR", "XDG_CACHE_HOME", "HOME")


def generated_dir() -> Path | None:
    """The writable directory of the generated modules (created), or None.

    A directory found writable is remembered for the same environment (which names the
    candidates) while it exists: asked before every run, it costs one ``stat``, not a
    probe file.
    """
    key = tuple(os.environ.get(name) for name in _NAMING)
    known = _GENERATED.get(key)
    if known is not None and os.path.isdir(known):
        return known
    for base in _base_candidates():
        path = base / "generated"
        if _writable(path):
            _GENERATED[key] = path
            return path
    return None
