"""Ahead-of-time machine code of the dynamics and of single runs: no numba in the processes that use it.

The JIT path (:mod:`rrt_pin.compiled._jit`) makes every process import numba and
load its cache before the first sample, which for a short run costs far more
than the run (``scripts/bench/aot.py``). This module builds the same functions (:data:`EXPORTS`: the
closed-form dynamics of :mod:`rrt_pin.compiled._jit_dynamics` and the single-run
integrator of :mod:`rrt_pin.compiled._jit_integrators`; the same Python source,
the same inlined callees, compiled by numba for this CPU) into a plain extension module with
``numba.pycc``, once, next to the JIT cache (same fingerprint directory, so a change
of the sources, Python, numba or CPU gets a new one and the old one is pruned with
its directory). Importing it needs numpy only: measured by ``scripts/bench/aot.py``,
a process that loads it and runs the chapter's 15,001 samples costs what
``import numpy`` does, against 0.82 s with the JIT cache, at the same ns/sample and
with the same efforts bit for bit.

The generated RNEA of any other robot (:mod:`rrt_pin.compiled.rnea`) is built the same
way when its JIT kernel is first compiled (:func:`build_kernel`, ~7–9 s for UR5 and
Panda): a module a source, under ``generated/aot/`` named by the source's SHA-256 and the
toolchain, checked bit for bit against the JIT kernel before it is kept, and loaded by
:func:`load_kernel` in about a millisecond, without numba.

Threaded batches keep the JIT: its functions release the GIL, ``pycc``'s do not.
The build needs numba (with its ``pycc``) and a C compiler; it runs in a child
process, writes into a temporary file renamed into place (a crash leaves no
partial module), and is only ever an optimisation: when it cannot be built or
loaded, the JIT path is used and nothing else changes.

A damaged module must never be loaded: the loader maps the file, and a page
beyond the end of a truncated one kills the process with SIGBUS, before any
exception can be raised. So :func:`build` records the module's size and SHA-256
beside it (``<module>.json``, written before the module is renamed into place),
and :func:`load` checks both before importing it: a module without its record,
of another size or with other contents is deleted unread (a note on the
``rrt_pin`` logger at INFO, shown by ``-v``), the JIT path runs, and the next
:func:`build` makes it again.
"""

from __future__ import annotations

import hashlib
import importlib
import importlib.machinery
import importlib.util
import json
import logging
import os
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from types import ModuleType
from typing import Any

__all__ = [
    "EXPORTS", "build", "build_kernel", "can_build", "damage", "is_built", "kernel_built",
    "can_build_kernel", "kernel_path", "load", "load_kernel", "module_path",
]  # fmt: skip

#: The functions the module exports, by JIT module (each with its JIT signature).
EXPORTS = {
    "rrt_pin.compiled._jit_dynamics": (
        "mass_matrix_batch", "bias_batch", "inverse_batch", "forward_batch",
    ),
    "rrt_pin.compiled._jit_integrators": ("integrate",),
}  # fmt: skip
_NAME = "rrt_pin_dynamics_aot"
#: Left in the cache directory when a build failed, so that later processes do not retry.
_FAILED = "AOT_FAILED"
#: Appended to the module's name for its record (size and SHA-256 when built).
_RECORD = ".json"
_logger = logging.getLogger("rrt_pin")
_loaded: ModuleType | None = None
_failed = False
_noted = False


def module_path() -> Path | None:
    """Where the module for the current sources and toolchain lives (None: no writable cache)."""
    from rrt_pin.compiled import _cache

    fp = _cache.fingerprint()
    # The exports are part of the file's name: another list is another module.
    listed = json.dumps(EXPORTS, sort_keys=True).encode()
    name = f"{_NAME}-{hashlib.sha256(listed).hexdigest()[:8]}"
    for base in _cache._base_candidates():
        path = base / fp
        if _cache._could_write(path):
            return path / (name + importlib.machinery.EXTENSION_SUFFIXES[0])
    return None


def _record_path(path: Path) -> Path:
    return path.with_name(path.name + _RECORD)


def _describe(path: Path) -> dict[str, object]:
    """The size [bytes] and SHA-256 of ``path`` (raises OSError)."""
    data = path.read_bytes()
    return {"size": len(data), "sha256": hashlib.sha256(data).hexdigest()}


def _recorded(path: Path) -> dict[str, object] | None:
    """The size and SHA-256 recorded for the module at ``path`` when it was built, or None."""
    try:
        record = json.loads(_record_path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict):
        return None
    size, digest = record.get("size"), record.get("sha256")
    if not isinstance(size, int) or isinstance(size, bool) or not isinstance(digest, str):
        return None
    return {"size": size, "sha256": digest}


def damage(path: Path, contents: bool = True) -> str | None:
    """What is wrong with the module file at ``path`` (None: it is the one built).

    Compares its size, and with ``contents`` its SHA-256 (reading the whole file,
    under a megabyte), with its record; never imports it.
    """
    record = _recorded(path)
    if record is None:
        return "it has no record of its size and SHA-256"
    try:
        found = _describe(path) if contents else {"size": path.stat().st_size}
    except OSError as e:
        return f"it cannot be read ({e.strerror or e})"
    if found["size"] != record["size"]:
        return f"it has {found['size']} bytes, {record['size']} when built (truncated or grown)"
    if contents and found["sha256"] != record["sha256"]:
        return "its contents changed since it was built (SHA-256)"
    return None


def _discard(path: Path, problem: str) -> None:
    """Say why the module at ``path`` is not used (once), then delete it and its record.

    What cannot be deleted stays, unread.
    """
    global _noted
    if not _noted:
        _noted = True
        _logger.info(
            "ahead-of-time module %s not loaded: %s; deleted, the JIT is used and the "
            "module is built again",
            path,
            problem,
        )
    for file in (path, _record_path(path)):
        try:
            file.unlink(missing_ok=True)
        except OSError:
            pass


def is_built() -> bool:
    """Whether the module for the current sources exists with its record, of the recorded size.

    Cheap (no import, no numba, no hashing): :func:`load` checks the contents too.
    """
    return _intact(module_path())


def _intact(path: Path | None) -> bool:
    """Whether a module file is there with its record, of the recorded size (else discarded)."""
    if path is None or not path.is_file():
        return False
    problem = damage(path, contents=False)
    if problem is not None:
        _discard(path, problem)
        return False
    return True


def load() -> ModuleType | None:
    """The ahead-of-time module if it is built and loads (once per process), else None."""
    global _loaded, _failed
    if _loaded is not None or _failed:
        return _loaded
    path = module_path()
    if path is None or not path.is_file():
        return None
    problem = damage(path)
    if problem is not None:  # never mapped: a truncated file would end the process (SIGBUS)
        _failed = True
        _discard(path, problem)
        return None
    try:
        spec = importlib.util.spec_from_file_location(_NAME, path)
        if spec is None or spec.loader is None:
            raise ImportError(f"no loader for {path}")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        names = [n for group in EXPORTS.values() for n in group]
        if not all(callable(getattr(module, name, None)) for name in names):
            raise ImportError("a function is missing")
    except Exception as e:  # a damaged file: the JIT path takes over, the next build replaces it
        _failed = True
        _discard(path, f"it does not import ({e})")
        return None
    _loaded = module
    return module


def can_build() -> bool:
    """Whether :func:`build` would try: a cache directory, and no failed build for these sources."""
    path = module_path()
    return path is not None and not (path.parent / _FAILED).exists()


def build(timeout: float = 600.0) -> bool:
    """Build the module for the current sources (in a child process); whether it exists now.

    Does nothing when it is already built, when an earlier build failed for these
    sources (no C compiler, no ``numba.pycc``: a marker file says so) or when no
    cache directory is writable.
    """
    path = module_path()
    if path is None:
        return False
    if is_built():
        return True
    return _build_into(path, _NAME, [], timeout)


def _build_into(
    path: Path,
    name: str,
    args: list[str],
    timeout: float,
    check: Callable[[Path], bool] | None = None,
) -> bool:
    """Run the child that builds module ``name`` (``args`` after its work directory) into ``path``.

    ``check(built)`` may refuse the module built (it is then not kept). A failed build
    leaves a marker beside ``path`` so that later processes do not retry.
    """
    marker = path.parent / _FAILED if name == _NAME else path.with_name(path.name + ".failed")
    if marker.exists():
        return False
    path.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=path.parent, prefix=".aot-") as work:
        env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
        try:
            done = subprocess.run(
                [sys.executable, "-m", "rrt_pin.compiled._aot", work, *args],
                capture_output=True, text=True, timeout=timeout, env=env, check=False,
            )  # fmt: skip
        except (OSError, subprocess.TimeoutExpired) as e:
            _logger.debug("ahead-of-time build failed: %s", e)
            return False
        built = Path(work) / (name + importlib.machinery.EXTENSION_SUFFIXES[0])
        failed = done.returncode != 0 or not built.is_file()
        if not failed and check is not None and not check(built):
            done = subprocess.CompletedProcess(done.args, 1, "", "it differs from the JIT's")
            failed = True
        if failed:
            last = (done.stderr.strip().splitlines() or ["no output"])[-1]
            _logger.debug("ahead-of-time build failed: %s", last)
            try:
                marker.write_text(last + "\n", encoding="utf-8")
            except OSError:
                pass
            return False
        # The record first, then the module: a module is never there without its
        # record (one left from a crash, without its module, is rewritten next time).
        record = _record_path(path)
        tmp = Path(work) / record.name
        try:
            tmp.write_text(json.dumps(_describe(built)) + "\n", encoding="utf-8")
            os.replace(tmp, record)
            os.replace(built, path)  # same directory: atomic
        except OSError as e:
            _logger.debug("ahead-of-time module not saved: %s", e)
            for file in (path, record):
                try:
                    file.unlink(missing_ok=True)
                except OSError:
                    pass
            return False
    return True


# ---------------------------------------------------------------- generated kernels
def _toolchain() -> str:
    """Python, numba, llvmlite and the CPU (12 hex digits): a generated module's other key."""
    from rrt_pin.compiled._cache import _cpu, _version

    parts = (sys.version, _version("numba"), _version("llvmlite"), _cpu())
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:12]


def _kernel_name(digest: str) -> str:
    return f"rrt_pin_rnea_aot_{digest[:24]}"


#: Set to ``0`` to build no generated kernel ahead of time (their JIT kernels serve alone).
ENABLE_VARIABLE = "RRT_PIN_AOT"


def enabled() -> bool:
    """Whether generated kernels are built ahead of time (``$RRT_PIN_AOT`` is not ``0``)."""
    return os.environ.get(ENABLE_VARIABLE, "1").strip() != "0"


def kernel_path(digest: str) -> Path | None:
    """Where the ahead-of-time module of the generated RNEA of source ``digest`` lives."""
    from rrt_pin.compiled._cache import generated_dir

    where = generated_dir()
    if where is None:
        return None
    name = f"{_kernel_name(digest)}-{_toolchain()}"
    return where / "aot" / (name + importlib.machinery.EXTENSION_SUFFIXES[0])


def kernel_built(digest: str) -> bool:
    """Whether the generated RNEA of source ``digest`` is built ahead of time (cheap: no hashing)."""
    return _intact(kernel_path(digest))


def can_build_kernel(digest: str) -> bool:
    """Whether :func:`build_kernel` would try (a cache directory, no failed build of it)."""
    path = kernel_path(digest)
    return path is not None and not path.with_name(path.name + ".failed").exists()


#: Generated kernels loaded ahead of time in this process, by source digest.
_KERNELS: dict[str, Any] = {}


def load_kernel(digest: str) -> Any:
    """The ahead-of-time ``kernel`` of the generated RNEA of source ``digest``, or None.

    Checked against its record first (size and SHA-256), as the chapter's module is.
    """
    found = _KERNELS.get(digest)
    if found is not None:
        return found
    path = kernel_path(digest)
    if path is None or not path.is_file():
        return None
    problem = damage(path)
    if problem is not None:
        _discard(path, problem)
        return None
    try:
        kernel = _import_kernel(path, _kernel_name(digest))
    except Exception as e:  # a damaged file: the JIT path takes over
        _discard(path, f"it does not import ({e})")
        return None
    _KERNELS[digest] = kernel
    return kernel


def _import_kernel(path: Path, name: str) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"no loader for {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    kernel = getattr(module, "kernel", None)
    if not callable(kernel):
        raise ImportError("its kernel is missing")
    return kernel


def build_kernel(
    source: Path, digest: str, agrees: Callable[[Any], bool], timeout: float = 600.0
) -> bool:
    """Build the generated RNEA of ``source`` (SHA-256 ``digest``) ahead of time; whether it is.

    ``agrees(kernel)`` compares the module's kernel with the JIT's (bit for bit) before
    it is kept. Never raises: the JIT kernel stays in use when this fails.
    """
    path = kernel_path(digest)
    if path is None:
        return False
    if kernel_built(digest):
        return True
    name = _kernel_name(digest)

    def check(built: Path) -> bool:
        try:
            return bool(agrees(_import_kernel(built, name)))
        except Exception as e:  # noqa: BLE001 - any failure: not kept
            _logger.debug("ahead-of-time kernel %s not kept: %s", name, e)
            return False

    return _build_into(path, name, ["--kernel", str(source), name], timeout, check)


def _compile_kernel_into(out_dir: str, source: str, name: str) -> None:
    """Compile the generated module ``source``'s ``kernel`` with ``numba.pycc`` (in the child)."""
    import warnings

    import numba
    from numba.pycc import CC

    from rrt_pin.compiled.rnea_vector import kernel_signature

    warnings.simplefilter("ignore")
    spec = importlib.util.spec_from_file_location(f"{name}_source", source)
    if spec is None or spec.loader is None:
        raise SystemExit(f"cannot read {source}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    cc = CC(name)
    cc.output_dir = out_dir
    cc.target_cpu = "host"
    cc.verbose = False
    cc.export("kernel", kernel_signature(numba))(module.kernel)
    cc.compile()


def _compile_into(out_dir: str) -> None:
    """Compile :data:`EXPORTS` with ``numba.pycc`` into ``out_dir`` (run in the child)."""
    import warnings

    from numba.pycc import CC

    warnings.simplefilter("ignore")  # pycc's deprecation notice: this is the measured choice
    cc = CC(_NAME)
    cc.output_dir = out_dir
    cc.target_cpu = "host"  # the module lives in this CPU's cache directory
    cc.verbose = False
    for module_name, names in EXPORTS.items():
        source = importlib.import_module(module_name)
        for name in names:
            dispatcher = getattr(source, name)
            signature = dispatcher.overloads[dispatcher.signatures[0]].signature
            cc.export(name, signature)(dispatcher.py_func)
    cc.compile()
    # The module must load and agree with the JIT's functions before it is kept.
    import numpy as np

    from rrt_pin.compiled import _jit_dynamics as jd

    sys.path.insert(0, out_dir)
    module = importlib.import_module(_NAME)
    rng = np.random.default_rng(0)
    q, qd, qdd = (rng.uniform(-2.0, 2.0, (300, 3)) for _ in range(3))
    p = rng.uniform(0.5, 2.0, 15)
    a, b = np.empty((300, 3)), np.empty((300, 3))
    jd.inverse_batch(q, qd, qdd, p, a)
    module.inverse_batch(q, qd, qdd, p, b)
    if not np.array_equal(a, b):
        raise SystemExit("the ahead-of-time inverse_batch differs from the JIT's")


if __name__ == "__main__":
    if len(sys.argv) == 5 and sys.argv[2] == "--kernel":
        _compile_kernel_into(sys.argv[1], sys.argv[3], sys.argv[4])
    else:
        _compile_into(sys.argv[1])
