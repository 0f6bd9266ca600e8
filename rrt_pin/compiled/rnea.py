"""Inverse dynamics of any supported fixed-base robot in machine code, generated from its model.

:func:`rrt_pin.dynamics.rnea_source.rnea_source` turns a ``pin.Model`` into the straight-line
RNEA of one sample; :func:`module_source` makes of it a kernel over a batch,
``kernel(Q (N, nq), V (N, nv), A (N, nv), out (N, nv))``, vectorised across samples
(:mod:`rrt_pin.compiled.rnea_vector`: blocks of samples as structure of arrays, the
polynomial sine and cosine over a block, several samples an instruction), which is written to a
file named by the SHA-256 of that source, imported from there and compiled by
numba with ``cache=True`` and ``nogil=True`` (:func:`kernel_for`). The file's
directory is ``generated/`` under the base cache directory of
:mod:`rrt_pin.compiled._cache` (``$RRT_PIN_CACHE_DIR``, ``$NUMBA_CACHE_DIR/rrt_pin``,
``~/.cache/rrt_pin/numba``, …); numba keeps the machine code beside it, in
``__pycache__`` (or under ``$NUMBA_CACHE_DIR``), keyed by the file's contents, the
CPU and the toolchain, so a second process loads it instead of compiling. The
SHA-256 of numba's files is recorded beside the source when a kernel is compiled
(``rnea_<digest>.cache.json``) and checked before numba reads them: a damaged or
unrecorded file is deleted and the kernel compiled again. Each
process keeps one kernel per source in memory.

:func:`inverse_dynamics` splits a batch over threads as the compiled batches do
(:func:`rrt_pin.compiled.lanes._in_slices`). Each call of the kernel
returns 0.0 when every input and effort of its samples is finite, else NaN (one
test a sample, OR-ed without a branch), so non-finite values are searched only then.

Units: Q in rad or m (continuous joints: cos θ, sin θ), V in rad/s or m/s, A in
rad/s² or m/s²; efforts in N·m (revolute) or N (prismatic).
"""

from __future__ import annotations

import glob
import hashlib
import importlib.util
import json
import logging
import os
import sys
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.compiled import _models, rnea_vector
from rrt_pin.core import backends, cpus
from rrt_pin.core._logging import note
from rrt_pin.core.errors import InputError
from rrt_pin.core.identity import IdentityCache
from rrt_pin.dynamics import rnea_source
from rrt_pin.simulate.codes import SINCOS_FLOPS

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "MIN_SAMPLES_PER_THREAD",
    "MIN_SECONDS_PER_THREAD",
    "Kernel",
    "generated_dir",
    "inverse_dynamics",
    "kernel_for",
    "module_source",
]

#: Work a thread needs to be worth starting [s]: handing slices to a second thread
#: costs tens of microseconds, more on a busy machine (``scripts/bench/threads.py``
#: measures it), so each thread gets at least this much.
MIN_SECONDS_PER_THREAD = 150e-6
#: The fewest samples a thread takes, whatever the kernel.
MIN_SAMPLES_PER_THREAD = 256
#: Costs of the thread estimate (:attr:`Kernel.min_per_thread`) [ns]: an operation of a
#: one-sample kernel, a libm sine or cosine, an operation of a vectorised kernel.
_NS_PER_OP = 0.3
_NS_PER_SINCOS = 10.0
_NS_PER_LANE_OP = 0.035
_logger = logging.getLogger("rrt_pin")
_lock = threading.Lock()


@dataclass(frozen=True)
class Kernel:
    """One model's compiled RNEA over a batch.

    Attributes:
        digest: SHA-256 of the module's source (its file is ``rnea_<digest[:24]>.py``).
        kernel: ``kernel(Q, V, A, out) -> 0.0 or nan`` (numba dispatcher).
        nq: configuration size; nv: efforts per sample.
        flops: arithmetic operations a sample (sines and cosines apart).
        transcendentals: sines and cosines a sample.
        path: the module's file, or None (compiled in memory only).
        origin: ``loaded`` (numba's disk cache), ``compiled`` (and saved), ``memory`` or
            ``ahead of time`` (:mod:`rrt_pin.compiled._aot`: no numba, one thread).
        seconds: what importing and compiling (or loading) took [s].
        vectorised: the kernel runs several samples an instruction (the RNEA's).
        sincos: angles a sample whose sine and cosine the kernel computes by polynomial
            (below ``rnea_vector.SINCOS_LIMIT``; libm's beyond).
    """

    @property
    def min_per_thread(self) -> int:
        """The fewest samples worth a thread: :data:`MIN_SECONDS_PER_THREAD` of estimated work.

        The estimate is what the generated kernels of the chapter's arm, UR5 and Panda
        take on one core (within 40 %): :data:`_NS_PER_OP` an operation and
        :data:`_NS_PER_SINCOS` a libm sine or cosine one sample at a time; vectorised,
        :data:`_NS_PER_LANE_OP` an operation, polynomial sines and cosines included
        (:attr:`all_flops`).
        """
        if self.vectorised:
            ns = _NS_PER_LANE_OP * self.all_flops + 2.0
        else:
            ns = _NS_PER_OP * self.flops + _NS_PER_SINCOS * self.transcendentals + 1.0
        return max(MIN_SAMPLES_PER_THREAD, int(MIN_SECONDS_PER_THREAD * 1e9 / ns))

    @property
    def all_flops(self) -> int:
        """Operations a sample with the polynomial sines and cosines (:attr:`sincos` pairs)."""
        return self.flops + SINCOS_FLOPS * self.sincos

    digest: str
    kernel: Any
    nq: int
    nv: int
    flops: int
    transcendentals: int
    path: Path | None
    origin: str
    seconds: float
    vectorised: bool = False
    sincos: int = 0


#: Kernels of this process, by the SHA-256 of their source.
_KERNELS: dict[str, Kernel] = {}
#: Models already generated, by identity: (a copy to notice changes, its kernel).
_MODELS: IdentityCache[tuple[Any, Kernel]] = IdentityCache(16)


#: A balanced sum of terms (a short dependency chain); the other generated kernels use it.
_pairwise_sum = rnea_vector.pairwise_sum


def module_source(gen: rnea_source.GeneratedRnea) -> str:
    """The Python module of the batch kernel around ``gen``'s straight-line RNEA.

    ``kernel(Q, V, A, out)`` writes the efforts of each row into ``out`` and returns
    0.0 when every entry of Q, V, A and out is finite, else NaN; it is vectorised
    across samples (:func:`rrt_pin.compiled.rnea_vector.vector_source`).
    """
    return rnea_vector.vector_source(gen)[0]


def generated_dir() -> Path | None:
    """The writable directory of the generated modules (created), or None."""
    from rrt_pin.compiled._cache import generated_dir as found

    return found()


def _write(path: Path, text: str) -> bool:
    """Write ``text`` to ``path`` unless it already holds it (atomically); whether it does now."""
    try:
        if path.read_text(encoding="utf-8") == text:
            return True
    except (OSError, UnicodeDecodeError):
        pass
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    except OSError:
        tmp.unlink(missing_ok=True)
        return False
    return True


def _import(path: Path, name: str) -> Any:
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)  # type: ignore[arg-type]
    spec.loader.exec_module(module)  # type: ignore[union-attr]
    sys.modules[name] = module
    return module


def _numba_files(dispatcher: Any) -> Callable[[], list[Path]]:
    """The index and data files numba keeps for ``dispatcher`` (a function listing them now)."""
    index = Path(dispatcher._cache._cache_file._index_path)
    stem = index.name[: -len(".nbi")]

    def files() -> list[Path]:  # those on disk now (the index too, once written)
        found = [index, *index.parent.glob(glob.escape(stem) + ".*.nbc")]
        return sorted(f for f in found if f.is_file())

    return files


def _record_path(path: Path) -> Path:
    return path.with_name(f"{path.stem}.cache.json")


def _digests(files: list[Path]) -> dict[str, str]:
    return {str(f): hashlib.sha256(f.read_bytes()).hexdigest() for f in files if f.is_file()}


def _record(path: Path, files: Callable[[], list[Path]]) -> None:
    """Record the SHA-256 of numba's files of a kernel just compiled (beside its source)."""
    record = _record_path(path)
    tmp = record.with_name(f".{record.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        tmp.write_text(json.dumps(_digests(files()), indent=1), encoding="utf-8")
        os.replace(tmp, record)
    except OSError:
        tmp.unlink(missing_ok=True)


def _discard_unverified(path: Path, files: Callable[[], list[Path]]) -> None:
    """Delete numba's files of a kernel unless they are the ones recorded when it was compiled.

    numba would read a truncated or altered file (a crash, a full disk, another
    program): only files whose SHA-256 match the record are loaded; others, and
    files without a record, are deleted, and the kernel is compiled again.
    """
    present = files()
    if not present:
        return
    try:
        recorded = json.loads(_record_path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        recorded = None
    try:
        if isinstance(recorded, dict) and _digests(present) == recorded:
            return
    except OSError:
        pass
    for f in [*present, _record_path(path)]:
        f.unlink(missing_ok=True)
    _logger.info(
        "generated kernel %s: numba's cached files did not match their record; compiling again",
        path.stem,
    )


_signature = rnea_vector.kernel_signature


def _compile(
    source: str,
    digest: str,
    gen: Any,
    kind: str = "rnea",
    signature: Callable[[Any], Any] = _signature,
    sincos: int | None = None,
) -> Kernel:
    """Compile (or load) the ``kernel`` of a generated module (``gen``: its sizes and flops).

    ``kind`` prefixes the module's file (``<kind>_<digest[:24]>.py``); ``signature``
    makes numba's signature of ``kernel`` from the numba module; ``sincos``: for a
    vectorised kernel, its polynomial sine-cosine pairs a sample (None: not vectorised).
    """
    try:
        import numba
    except ImportError as e:
        backends.get("compiled").require(e)
        raise  # not reached: require raises
    start = time.perf_counter()
    sig = signature(numba)
    name = f"rrt_pin_{kind}_{digest[:24]}"
    where = generated_dir()
    path = where / f"{name.removeprefix('rrt_pin_')}.py" if where is not None else None
    dispatcher, origin = None, "memory"
    if path is not None and _write(path, source):
        try:
            fn = _import(path, name).kernel
            # Lazy, so that numba's files are checked before it reads them; then
            # compiled for the one signature, as njit(signature) does.
            dispatcher = numba.njit(cache=True, nogil=True, error_model="numpy")(fn)
            files = _numba_files(dispatcher)
            _discard_unverified(path, files)
            dispatcher.compile(sig.args)
            dispatcher.disable_compile()
            origin = "loaded" if sum(dispatcher.stats.cache_hits.values()) else "compiled"
            if origin == "compiled":
                _record(path, files)
            if kind == "rnea":
                _build_ahead(path, digest, dispatcher, gen.nq, gen.nv)
        except Exception as exc:  # a damaged or unwritable numba cache: compile in memory
            from rrt_pin.compiled._cache import warn_once

            warn_once(f"generated RNEA cache {path.parent}: {type(exc).__name__}: {exc}"[:300])
            dispatcher = None
    if dispatcher is None:
        namespace: dict[str, Any] = {}
        exec(compile(source, f"<{name}>", "exec"), namespace)  # noqa: S102 - our own source
        fn = namespace["kernel"]
        dispatcher = numba.njit(sig, cache=False, nogil=True, error_model="numpy")(fn)
        path, origin = None, "memory"
    seconds = time.perf_counter() - start
    what = "RNEA" if kind == "rnea" else kind
    _logger.info("generated %s %s: %s in %.2f s", what, digest[:12], origin, seconds)
    return Kernel(
        digest=digest,
        kernel=dispatcher,
        nq=gen.nq,
        nv=gen.nv,
        flops=gen.flops,
        transcendentals=gen.transcendentals,
        path=path,
        origin=origin,
        seconds=seconds,
        vectorised=sincos is not None,
        sincos=sincos or 0,
    )


def _build_ahead(path: Path, digest: str, jit: Any, nq: int, nv: int) -> None:
    """Build the kernel just compiled ahead of time too (unless ``RRT_PIN_AOT=0``).

    The module is kept only if it gives the JIT kernel's efforts bit for bit on random
    samples; when it cannot be built (no C compiler), the JIT kernel serves as before.
    """
    from rrt_pin.compiled import _aot

    if not _aot.enabled() or _aot.kernel_built(digest) or not _aot.can_build_kernel(digest):
        return
    note(f"building the generated inverse dynamics ({nv} joints) ahead of time once (~5 s)")
    rng = np.random.default_rng(0)
    Q, V, A = rng.uniform(-2.0, 2.0, (67, nq)), *rng.uniform(-2.0, 2.0, (2, 67, nv))

    def agrees(kernel: Any) -> bool:
        a, b = np.empty((67, nv)), np.empty((67, nv))
        jit(Q, V, A, a)
        kernel(Q, V, A, b)
        return bool(np.array_equal(a, b))

    start = time.perf_counter()
    built = _aot.build_kernel(path, digest, agrees)
    _logger.info(
        "generated RNEA %s ahead of time: %s in %.1f s",
        digest[:12], "built" if built else "not built", time.perf_counter() - start,
    )  # fmt: skip


def kernel_for(model: pin.Model) -> Kernel:
    """The compiled RNEA of ``model`` (generated, written, loaded or compiled once per process).

    A model seen before and unchanged (compared with a copy kept) costs a dict
    look-up and a model comparison (a few microseconds). A model whose kernel was
    built ahead of time (:func:`rrt_pin.compiled._aot.build_kernel`, when its JIT
    kernel was first compiled) loads that module, without numba and without
    generating its source (:mod:`rrt_pin.compiled._models` says which it is).

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
        MissingExtra: numba is not installed.
    """
    entry = _MODELS.get(model)
    if entry is not None and bool(entry[0] == model):
        return entry[1]
    import pinocchio as pin

    kernel = _ahead_of_time(model)
    if kernel is None:
        gen = rnea_source.rnea_source(model)
        source, sincos = rnea_vector.vector_source(gen)
        digest = hashlib.sha256(source.encode()).hexdigest()
        with _lock:
            kernel = _KERNELS.get(digest)
            if kernel is None:
                kernel = _KERNELS[digest] = _compile(source, digest, gen, sincos=sincos)
        sizes = ("nq", "nv", "flops", "transcendentals", "sincos")
        _models.remember(
            "rnea", model, {"digest": digest, **{k: getattr(kernel, k) for k in sizes}}
        )
    _MODELS.put(model, value=(pin.Model(model), kernel))
    return kernel


def _ahead_of_time(model: pin.Model) -> Kernel | None:
    """``model``'s kernel built ahead of time, if the index knows it and it loads."""
    from rrt_pin.compiled import _aot

    record = _models.recall("rnea", model)
    if record is None:
        return None
    digest = record["digest"]
    found = _KERNELS.get(digest)
    if found is not None:
        return found
    try:
        sizes = {k: int(record[k]) for k in ("nq", "nv", "flops", "transcendentals", "sincos")}
    except (KeyError, TypeError, ValueError):
        return None
    if sizes["nq"] != model.nq or sizes["nv"] != model.nv:
        return None
    start = time.perf_counter()
    fn = _aot.load_kernel(digest)  # the sizes first: a record that does not fit loads nothing
    if fn is None:
        return None
    seconds = time.perf_counter() - start
    _logger.info("generated RNEA %s: ahead of time in %.3f s", digest[:12], seconds)
    kernel = Kernel(
        digest=digest, kernel=fn, path=None, origin="ahead of time", seconds=seconds,
        vectorised=True, **sizes,
    )  # fmt: skip
    with _lock:
        return _KERNELS.setdefault(digest, kernel)


def state(model: pin.Model) -> tuple[bool, bool, bool]:
    """(loaded in this process, built ahead of time, ready without compiling) for ``model``'s RNEA.

    Cheap: no numba import, no source generated (the index of :mod:`rrt_pin.compiled._models`).
    """
    entry = _MODELS.get(model)
    if entry is not None and bool(entry[0] == model):
        return True, entry[1].origin == "ahead of time", True
    record = _models.recall("rnea", model)
    if record is None:
        return False, False, False
    from rrt_pin.compiled import _aot

    digest = record["digest"]
    if digest in _KERNELS:
        return True, _KERNELS[digest].origin == "ahead of time", True
    if _aot.kernel_built(digest):
        return False, True, True
    where = generated_dir()
    jit = where is not None and _record_path(where / f"rnea_{digest[:24]}.py").is_file()
    return False, False, jit


def _c_array(x: np.ndarray) -> np.ndarray:
    """``x`` as the kernel takes it: float64, C-ordered (copied only if needed; read-only is fine)."""
    return np.ascontiguousarray(x, dtype=np.float64)


def inverse_dynamics(
    model: pin.Model,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    num_threads: int | None = None,
) -> tuple[np.ndarray, bool]:
    """Efforts of a batch with ``model``'s generated kernel, and whether all was finite.

    Args:
        model: a fixed-base Pinocchio model with supported joints.
        q: configurations (N, nq) [rad or m; cos θ, sin θ for continuous joints].
        qd: velocities (N, nv) [rad/s or m/s].
        qdd: accelerations (N, nv) [rad/s² or m/s²].
        num_threads: threads; default: the CPUs free now
            (:func:`rrt_pin.core.cpus.threads_for`); never a thread with fewer samples
            than :attr:`Kernel.min_per_thread`; one for a kernel built ahead of time.

    Returns:
        The efforts (N, nv) [N·m or N] and whether every input and effort is finite
        (when not, the caller names the first bad value).

    Raises:
        InputError: bad ``num_threads`` or shapes that do not fit the model.
        UnsupportedJoint: a joint the generated RNEA does not handle.
    """
    kernel = kernel_for(model)
    q, qd, qdd = _c_array(q), _c_array(qd), _c_array(qdd)
    n = q.shape[0]
    if q.shape != (n, kernel.nq) or qd.shape != (n, kernel.nv) or qdd.shape != (n, kernel.nv):
        raise InputError(
            f"{q.shape=}, {qd.shape=}, {qdd.shape=} do not fit the model "
            f"(nq={kernel.nq}, nv={kernel.nv})"
        )
    if num_threads is None:
        threads = cpus.threads_for(n, kernel.min_per_thread)
    else:
        if isinstance(num_threads, bool) or not isinstance(num_threads, (int, np.integer)):
            raise InputError(f"num_threads={num_threads!r} must be an integer >= 1")
        if num_threads < 1:
            raise InputError(f"num_threads={num_threads!r} must be >= 1")
        threads = int(max(1, min(num_threads, n // kernel.min_per_thread)))
    if kernel.origin == "ahead of time":
        threads = 1  # numba.pycc's functions hold the GIL: a second thread would wait
    out = np.empty((n, kernel.nv))
    if n == 0:
        return out, True
    fn = kernel.kernel
    if threads == 1:
        return out, fn(q, qd, qdd, out) == 0.0
    checks: list[float] = []

    def run(a: int, b: int) -> None:
        checks.append(fn(q[a:b], qd[a:b], qdd[a:b], out[a:b]))

    from rrt_pin.compiled.lanes import _in_slices

    _in_slices(run, n, threads)
    return out, not any(c != 0.0 for c in checks)
