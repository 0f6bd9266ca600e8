"""numba's ``njit`` through this package's disk cache, robust to a damaged, full or read-only cache.

Every machine-code module of the package (:mod:`rrt_pin.compiled._jit_dynamics`,
the integrators, the sweeps' metrics) compiles through :func:`jit`, so that one
cache directory (:mod:`rrt_pin.compiled._cache`) holds all their entries and a
problem with it costs a compilation in memory and one warning, never a crash.
"""

from __future__ import annotations

import glob
import time
from pathlib import Path

import llvmlite.binding
import numba
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic

from rrt_pin.compiled import _cache

__all__ = [
    "CACHE_PROBLEMS",
    "DISPATCHERS",
    "ORIGINS",
    "ORIGIN_KINDS",
    "SECONDS",
    "SIGNATURES",
    "borrow",
    "jit",
    "keep_alive",
    "warn_problems",
    "wide_vectors",
]

#: What each origin in :data:`ORIGINS` means, for the messages.
ORIGIN_KINDS = {
    "loaded": "loaded from the cache",
    "compiled": "compiled and saved",
    "memory": "compiled in memory only",
}

# A loop over a batch's lanes (rrt_pin.compiled._jit_batch) reads a few dozen rows of
# per-variant values and writes six: LLVM vectorizes it only after checking, once per
# loop, that the rows do not overlap, and by default gives up beyond 128 such checks
# (and numba cannot declare its arrays free of aliasing). Process-wide, as numba's own
# '-vector-library' option; it only lets more loops vectorize (with the checks), the
# same operations per element. Part of the machine code: _cache fingerprints this file.
LLVM_OPTIONS = ("--vectorize-memory-check-threshold=4096", "--runtime-memory-check-threshold=512")
for _option in LLVM_OPTIONS:
    llvmlite.binding.set_option("rrt_pin", _option)

_CACHE_DIR = _cache.cache_dir()
#: Name -> signature of every function compiled here (for the cache record).
SIGNATURES: dict[str, str] = {}
#: Dispatchers compiled here, by name.
DISPATCHERS: dict[str, object] = {}
#: Seconds spent compiling (or loading from the cache) each function, by name.
SECONDS: dict[str, float] = {}

#: Where each function's machine code came from, by name: "loaded" (the disk
#: cache), "compiled" (and saved to it) or "memory" (compiled, not saved).
ORIGINS: dict[str, str] = {}
#: What went wrong with the disk cache, one short line each (reported once by
#: :func:`rrt_pin.compiled.ensure_compiled`).
CACHE_PROBLEMS: list[str] = []


def _problem(what: str, exc: BaseException | None = None) -> None:
    """Note a problem with the cache once (with the first error that showed it)."""
    if any(p.startswith(what) for p in CACHE_PROBLEMS):
        return
    if exc is not None:
        first = (str(exc).strip().splitlines() or [""])[0][:160]
        what = f"{what} ({type(exc).__name__}: {first})"
    CACHE_PROBLEMS.append(what)


_requested = _cache.requested_dir()
if _requested is not None and (_CACHE_DIR is None or _requested not in _CACHE_DIR.parents):
    _problem(f"cannot write to {_requested}")
# Damaged files of a complete cache (checked against their recorded SHA-256) are
# deleted before numba reads them; their functions are then compiled again.
_DAMAGED = _cache.discard_damaged(_CACHE_DIR) if _CACHE_DIR is not None else []
if _DAMAGED:
    _problem(f"{len(_DAMAGED)} damaged file(s) discarded")


def _dispatcher(fn, inline: bool, cached: bool):
    """A lazy numba dispatcher of ``fn``, caching in :data:`_CACHE_DIR` or not at all.

    numba reads its cache directory when a function is decorated, so the
    setting is changed only for the decoration and then restored. Returns None
    when numba would cache elsewhere (it falls back to the source tree's
    ``__pycache__`` when it cannot write to the directory given).
    """
    previous = numba.config.CACHE_DIR
    if cached:
        numba.config.CACHE_DIR = str(_CACHE_DIR)
    try:
        dispatcher = numba.njit(
            cache=cached,
            nogil=True,
            error_model="numpy",
            inline="always" if inline else "never",
        )(fn)
    finally:
        numba.config.CACHE_DIR = previous
    if cached:
        where = getattr(getattr(dispatcher, "_cache", None), "cache_path", None)
        if where is None or _CACHE_DIR not in Path(where).parents:
            _problem("numba cannot cache there")
            return None
    return dispatcher


def _discard_entries(dispatcher) -> bool:
    """Delete the index and data files of ``dispatcher``'s cache; whether that worked."""
    try:
        index = Path(dispatcher._cache._cache_file._index_path)
        base = index.name[: -len(".nbi")]
        for file in [index, *index.parent.glob(glob.escape(base) + ".*.nbc")]:
            file.unlink(missing_ok=True)
    except (AttributeError, OSError):
        return False
    return True


def _build(fn, signature: object, inline: bool) -> tuple[object, str]:
    """Compile ``fn`` for ``signature``, through the disk cache when it works.

    Returns:
        The dispatcher (compiled, further compilation disabled) and its origin
        (see :data:`ORIGINS`).

    Raises:
        Exception: the compilation itself failed (an error in the code, not in the cache).
    """
    if _CACHE_DIR is not None:
        for _ in range(2):
            dispatcher = _dispatcher(fn, inline, cached=True)
            if dispatcher is None:
                break
            try:
                dispatcher.compile(signature)
            except Exception as exc:
                if dispatcher.overloads:  # compiled, then saving failed (disk full, read-only)
                    _problem("cannot save", exc)
                    dispatcher.disable_compile()
                    return dispatcher, "memory"
                if sum(dispatcher.stats.cache_misses.values()):
                    raise  # numba found no entry and compiled: the code itself is wrong
                # Loading an entry failed: it is truncated or corrupt. Drop it, recompile.
                _problem("unreadable entries discarded", exc)
                if not _discard_entries(dispatcher):
                    break
                continue
            dispatcher.disable_compile()
            hits = sum(dispatcher.stats.cache_hits.values())
            return dispatcher, "loaded" if hits else "compiled"
    dispatcher = _dispatcher(fn, inline, cached=False)
    dispatcher.compile(signature)
    dispatcher.disable_compile()
    return dispatcher, "memory"


def jit(signature: object, inline: bool = False):
    """``numba.njit(signature, cache=True)`` with this package's cache directory.

    With a signature the function is compiled (or loaded) now, and a damaged
    cache entry, a full disk or an unwritable directory only costs a
    compilation in memory (see :data:`CACHE_PROBLEMS`); ``inline`` functions
    (``signature=None``) are inlined into their jitted callers at numba's IR
    level and compiled only as part of them (never cached on their own).
    """

    def wrap(fn):
        start = time.perf_counter()
        if signature is None:
            return _dispatcher(fn, inline, cached=False)
        dispatcher, origin = _build(fn, signature, inline)
        SIGNATURES[fn.__name__] = str(signature)
        DISPATCHERS[fn.__name__] = dispatcher
        ORIGINS[fn.__name__] = origin
        SECONDS[fn.__name__] = time.perf_counter() - start
        return dispatcher

    return wrap


def warn_problems() -> None:
    """Say once, in one line, what went wrong with the cache (nothing when all went well)."""
    if not CACHE_PROBLEMS:
        return
    counts = {o: sum(v == o for v in ORIGINS.values()) for o in ORIGIN_KINDS}
    where = f" {_CACHE_DIR}" if _CACHE_DIR is not None else ""
    _cache.warn_once(
        f"compiled-code cache{where}: {'; '.join(CACHE_PROBLEMS)}; functions: "
        + ", ".join(f"{n} {ORIGIN_KINDS[o]}" for o, n in counts.items() if n)
    )


# numba counts references to an array's memory: every assignment of an array to a
# variable, every argument of an inlined function, every view takes one and gives
# it back, an atomic increment and decrement each (~20 cycles apiece, and they order
# the loads and stores around them). In the lanes' loop of _jit_batch these were
# ~16 % of a batch's time. A borrowed view holds no reference: its reference
# counting is a test of a null pointer.


@intrinsic
def borrow(typingctx, array):
    """A view of ``array`` that holds no reference to its memory (nor do views of it).

    Only for arrays that outlive every use of the view: a function's array
    arguments (the caller holds them), or arrays it allocates and passes to
    :func:`keep_alive` after the last use (numba frees an array after the last
    use of the variable that owns it).
    """
    sig = array(array)

    def codegen(context, builder, signature, args):
        source = context.make_array(signature.args[0])(context, builder, args[0])
        view = context.make_array(signature.return_type)(context, builder)
        view.meminfo = cgutils.get_null_value(view.meminfo.type)
        view.parent = cgutils.get_null_value(view.parent.type)
        view.nitems = source.nitems
        view.itemsize = source.itemsize
        view.data = source.data
        view.shape = source.shape
        view.strides = source.strides
        return view._getvalue()

    return sig, codegen


@intrinsic
def keep_alive(typingctx, owners):
    """Nothing, but a use of ``owners`` (a tuple of arrays): numba keeps them until here."""
    sig = types.none(owners)

    def codegen(context, builder, signature, args):
        return context.get_dummy_value()

    return sig, codegen


#: The vector width (bits) :func:`wide_vectors` asks of LLVM's vectorizers.
WIDE_VECTOR_BITS = 512


@intrinsic
def wide_vectors(typingctx):
    """Nothing, but the function that calls it prefers vectors of WIDE_VECTOR_BITS bits.

    LLVM vectorizes for 256-bit registers on CPUs whose 512-bit instructions once
    lowered the clock (its ``prefer-256-bit`` tuning); the batch's loops over lanes and
    samples are long and regular enough to gain from 512 bits (8 doubles) where the
    CPU has them (measured in docs/benchmarks.md, "512-bit vectors"). A function attribute: only the calling function's
    loops (with what is inlined into it), not other code of the process, and the same
    operations per element (the same bits). Without AVX-512 it changes nothing.
    """
    sig = types.none()

    def codegen(context, builder, signature, args):
        # llvmlite only lets known attribute names through its add(); a string
        # attribute is written into the IR as given.
        set.add(builder.function.attributes, f'"prefer-vector-width"="{WIDE_VECTOR_BITS}"')
        return context.get_dummy_value()

    return sig, codegen
