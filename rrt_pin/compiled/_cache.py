"""Where the compiled machine code lives on disk, and whether it is there.

Numba's own cache (``cache=True``) checks only the source file of the function
it caches, not the files that function calls into: regenerating
``rrt_pin/kernel.py`` would leave stale machine code behind. So every compiled
function of this package is cached in a directory named by a fingerprint of
all the sources that go into the machine code (the kernel, the jitted modules)
and of the Python, numba and llvmlite versions. A new source gets a new,
empty directory; nothing stale is ever loaded.

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
import json
import os
import platform
import sys
import tempfile
from functools import lru_cache
from importlib import metadata
from pathlib import Path

__all__ = ["JIT_MODULES", "cache_dir", "fingerprint", "is_cached", "mark_ready"]

#: Modules whose source is compiled to machine code (their text is fingerprinted).
JIT_MODULES = (
    "rrt_pin.kernel",
    "rrt_pin.compiled.codes",
    "rrt_pin.compiled._jit_dynamics",
    "rrt_pin.compiled._jit_integrators",
)
_COEFFS = "_dop853_coefficients.py"
_READY = "READY.json"


def _source_path(module: str) -> Path:
    """The file of ``module`` without importing it (it may import numba)."""
    loaded = sys.modules.get(module)
    if loaded is not None and getattr(loaded, "__file__", None):
        return Path(loaded.__file__)
    if module.startswith("rrt_pin.compiled."):
        return Path(__file__).with_name(module.rsplit(".", 1)[1] + ".py")
    return Path(__file__).parent.parent / (module.rsplit(".", 1)[1] + ".py")


def _version(dist: str) -> str:
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "absent"


@lru_cache(maxsize=1)
def _fingerprint_inputs() -> tuple[str, dict[str, str]]:
    digest = hashlib.sha256()
    described: dict[str, str] = {}
    paths = [_source_path(m) for m in JIT_MODULES] + [Path(__file__).with_name(_COEFFS)]
    for path in paths:
        try:
            data = path.read_bytes()
        except OSError:
            data = b"<missing>"
        digest.update(path.name.encode() + b"\0" + data + b"\0")
        described[path.name] = hashlib.sha256(data).hexdigest()[:16]
    for key, value in (
        ("python", sys.version),
        ("numba", _version("numba")),
        ("llvmlite", _version("llvmlite")),
        ("machine", platform.machine()),
    ):
        digest.update(f"{key}={value}\0".encode())
        described[key] = value
    return digest.hexdigest()[:20], described


def fingerprint() -> str:
    """The fingerprint of the compiled sources and toolchain (20 hex digits)."""
    return _fingerprint_inputs()[0]


def _base_candidates() -> list[Path]:
    out: list[Path] = []
    env = os.environ.get("RRT_PIN_CACHE_DIR")
    if env:
        out.append(Path(env))
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        out.append(Path(numba_dir) / "rrt_pin")
    xdg = os.environ.get("XDG_CACHE_HOME")
    home_cache = Path(xdg) if xdg else Path.home() / ".cache"
    out.append(home_cache / "rrt_pin" / "numba")
    uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
    out.append(Path(tempfile.gettempdir()) / f"rrt_pin-{uid}" / "numba")
    return out


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


def is_cached() -> bool:
    """Whether a complete compiled cache for the current sources exists on disk.

    Looks where :func:`cache_dir` would put it. Cheap: reads a few files,
    creates nothing, never imports numba and never compiles.
    """
    fp = fingerprint()
    for base in _base_candidates():
        path = base / fp
        if _could_write(path):
            return (path / _READY).is_file()
    return False


def mark_ready(path: Path, signatures: dict[str, list[str]]) -> None:
    """Record that every function in ``signatures`` was compiled and saved in ``path``."""
    record = {"fingerprint": fingerprint(), "inputs": _fingerprint_inputs()[1], **signatures}
    tmp = path / f".{_READY}.{os.getpid()}.tmp"
    try:
        tmp.write_text(json.dumps(record, indent=1, sort_keys=True), encoding="utf-8")
        os.replace(tmp, path / _READY)
    except OSError:
        tmp.unlink(missing_ok=True)
