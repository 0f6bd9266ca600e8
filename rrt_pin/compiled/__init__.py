"""Compiled fast path for the RRT arm: the generated closed-form kernel and integrators under numba.

``numba`` is an optional extra (``pip install rrt-pin[fast]``); importing this
package does not import it. The first call that needs machine code imports
numba and compiles every function (about 15–25 s, once per version of the
sources), or loads them from the disk cache (about 0.7–1 s per process:
importing numba, then numba's own start-up on the first load); see
:func:`ensure_compiled` and :mod:`rrt_pin.compiled._cache` for where the cache
lives. :func:`is_compiled` says, without importing numba or compiling, whether
that first call will be cheap — the CLI uses it to pick a backend.

Public API (SI units throughout):

* dynamics of one state (3,) or N states (N, 3): :func:`mass_matrix`,
  :func:`nonlinear_effects`, :func:`coriolis`, :func:`gravity`,
  :func:`inverse_dynamics`, :func:`forward_dynamics`;
* whole simulations: :func:`simulate_compiled` (the ``backend="compiled"`` of
  :func:`rrt_pin.simulate.simulate`) and :func:`simulate_batch_compiled` (many
  chapter variants: gains, targets, initial states and masses per variant);
* forward dynamics, M(q), bias and gravity of any such robot:
  :func:`rrt_pin.compiled.forward.forward_kernel_for`;
* simulations of any such robot (``simulate``, ``simulate_batch`` with
  ``backend="compiled"``): its generated dynamics inside the integrators of
  :mod:`rrt_pin.compiled._robot_template` (:mod:`rrt_pin.compiled.robot_code`,
  :mod:`rrt_pin.compiled.robot_runs`);
* inverse dynamics of any other fixed-base robot with revolute, prismatic or
  continuous joints: :mod:`rrt_pin.compiled.rnea` (the RNEA generated from its
  Pinocchio model by :mod:`rrt_pin.dynamics.rnea_source`, compiled once per model and cached
  on disk by the hash of its source; not loaded by :func:`ensure_compiled`);
* methods: those of :data:`rrt_pin.simulate.methods.METHODS` that run compiled
  (``rrt_pin.simulate.methods.names("compiled")``): ``RK45``, ``DOP853`` (adaptive,
  step by step as SciPy's ``solve_ivp``), ``symplectic_euler``, ``rk4``,
  ``verlet`` (fixed steps, as :mod:`rrt_pin.simulate.integrators`).

May import: rrt_pin.core, rrt_pin.io, rrt_pin.robot, rrt_pin.dynamics, rrt_pin.simulate.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "CompileReport",
    "aot_built",
    "available",
    "build_state",
    "compile_report",
    "coriolis",
    "ensure_compiled",
    "forward_dynamics",
    "gravity",
    "inverse_dynamics",
    "is_compiled",
    "is_loaded",
    "machine_code",
    "mass_matrix",
    "nonlinear_effects",
    "refusal",
    "runs_arm_kernel",
    "simulate_batch_compiled",
    "simulate_compiled",
    "state_for",
]


_LAZY = {
    "mass_matrix": "rrt_pin.compiled.dynamics",
    "nonlinear_effects": "rrt_pin.compiled.dynamics",
    "coriolis": "rrt_pin.compiled.dynamics",
    "gravity": "rrt_pin.compiled.dynamics",
    "inverse_dynamics": "rrt_pin.compiled.dynamics",
    "forward_dynamics": "rrt_pin.compiled.dynamics",
    "simulate_compiled": "rrt_pin.compiled.integrate",
    "simulate_batch_compiled": "rrt_pin.compiled.integrate",
}
_JIT = "rrt_pin.compiled._jit_batch"
#: Where a function's machine code can come from (:attr:`CompileReport.origins`).
_logger = logging.getLogger("rrt_pin")
_available: bool | None = None
_report: CompileReport | None = None


@dataclass(frozen=True)
class CompileReport:
    """What the first use of the compiled backend in this process cost.

    Attributes:
        numba_import: seconds to import numba [s].
        compile: seconds to compile or load all functions, numba's import excluded [s].
        from_cache: every function came from the disk cache (nothing compiled).
        cache_dir: where the machine code is cached, or None (memory only).
        functions: seconds per function [s].
        origins: where each function's machine code came from: "loaded" (disk
            cache), "compiled" (and saved) or "memory" (compiled, not saved: the
            cache was damaged, full or read-only; a warning said so).
    """

    numba_import: float
    compile: float
    from_cache: bool
    cache_dir: Path | None
    functions: dict[str, float] = field(default_factory=dict)
    origins: dict[str, str] = field(default_factory=dict)

    def describe(self) -> str:
        """One line: how long, from where."""
        how = "loaded from the cache" if self.from_cache else "compiled"
        where = str(self.cache_dir) if self.cache_dir is not None else "memory only, no cache"
        return (
            f"compiled backend {how} in {self.compile:.2f} s "
            f"(+ {self.numba_import:.2f} s importing numba; {where})"
        )


def available() -> bool:
    """Whether numba imports (the first call imports it: about 0.5 s; the answer is kept)."""
    global _available
    if _available is None:
        if importlib.util.find_spec("numba") is None:
            _available = False
        else:
            try:
                import numba  # noqa: F401
            except Exception:  # numba present but broken (e.g. an unsupported numpy)
                _available = False
            else:
                _available = True
    return _available


def is_loaded() -> bool:
    """Whether this process has already loaded the machine code (its start-up is paid)."""
    return _JIT in sys.modules


def is_compiled() -> bool:
    """Whether the compiled backend is ready without compiling: loaded, or complete on disk.

    Cheap (no numba import, no compilation): true when this process has
    already loaded the machine code, or when the disk cache holds all of it,
    unchanged, under the key numba will look it up by: the sources' contents
    and location, Python, numba, llvmlite and the CPU (see
    :mod:`rrt_pin.compiled._cache`). Using the backend then costs about 1 s
    (importing numba and loading), not a compilation.
    """
    if _JIT in sys.modules:
        return True
    if importlib.util.find_spec("numba") is None:
        return False
    from rrt_pin.compiled._cache import is_cached

    return is_cached()


def build_state() -> tuple[bool, bool, bool]:
    """(loaded in this process, built ahead of time, ready without compiling): cheap.

    What :func:`rrt_pin.core.backends.choose` needs to cost a start-up; no numba import.
    """
    aot = aot_built()
    loaded = is_loaded()
    return loaded, aot, loaded or aot or is_compiled()


def state_for(
    robot: Any,
    task: str,
    batch: bool = False,
    arm: bool = True,
    method: str | None = None,
    controllers: Any = (),
    numeric: bool | None = None,
) -> tuple[bool, bool, bool]:
    """(loaded in this process, built ahead of time, ready without compiling) for one job.

    ``arm``: the job runs the chapter arm's closed-form code (else ``robot``'s generated
    code: its RNEA for ``inverse``, its integrators for ``simulate``: the entry that
    ``method`` and ``controllers``, the laws, run on; ``numeric``: whether BDF's Jacobian
    will be numerical, None if not known). A ``batch`` runs on the JIT's threads, never
    on code built ahead of time. Cheap: no numba import, nothing generated or compiled.
    """
    if arm:
        from rrt_pin.compiled import _aot

        if not batch and _aot._loaded is not None:
            return True, True, True  # loaded ahead of time: nothing to look at on disk
        if is_loaded():
            return True, False, True
        aot = not batch and aot_built()
        return False, aot, aot or is_compiled()
    if importlib.util.find_spec("numba") is None:
        return False, False, False
    if task == "inverse":
        from rrt_pin.compiled import rnea

        return rnea.state(robot.model)
    from rrt_pin.compiled import robot_code, robot_entries
    from rrt_pin.simulate import methods

    code = methods.get(method).code if method is not None else None
    laws = list(controllers)
    if laws and not any(robot_entries.pd_only([c]) for c in laws):
        numeric = True  # no PD law: nothing to take a generated Jacobian of
    return robot_code.state(robot.model, batch, code, robot_entries.pd_only(laws), numeric)


def refusal(
    robot: Any, controllers: Any, params: Any = None, method: str | None = None
) -> str | None:
    """Why compiled code would refuse to simulate ``robot`` under ``controllers`` (None: it would not).

    Checks each law, and the method if one is named, as the run would (the chapter's
    arm: :mod:`rrt_pin.compiled.integrate`; another robot:
    :mod:`rrt_pin.compiled.robot_runs`), without compiling anything.
    """
    from rrt_pin.core.errors import InputError
    from rrt_pin.robot.params import Params

    laws = list(controllers)
    try:
        if runs_arm_kernel(robot, params, laws):
            from rrt_pin.compiled import integrate
            from rrt_pin.simulate import methods

            if method is not None:
                integrate._arm_method(methods.get(method))
            given = list(params) if isinstance(params, (list, tuple)) else [params]
            candidates = [*given, robot.params, *(getattr(c, "params", None) for c in laws)]
            plant = next((p for p in candidates if isinstance(p, Params)), None)
            if plant is None:
                return "the chapter's arm runs compiled from its Params"
            for law in laws:
                integrate._law(law, plant)
        else:
            from rrt_pin.compiled import robot_runs

            robot_runs._laws(robot, laws)
    except InputError as e:
        return str(e)
    return None


def runs_arm_kernel(robot: Any, params: Any, controllers: Any) -> bool:
    """Whether a compiled run of ``robot`` runs the arm's closed-form code (not generated code).

    The chapter's arm, or any robot given the arm's Params (``params=``, a list of them,
    or a chapter law's).
    """
    from rrt_pin.robot.params import Params

    if robot.is_chapter_arm or params is not None:
        return True
    return any(isinstance(getattr(c, "params", None), Params) for c in controllers)


def ensure_compiled() -> CompileReport:
    """Import numba and compile (or load from the cache) every function, once per process.

    Returns:
        The cost of doing so (the first call's report on later calls).

    Raises:
        ImportError: numba is not installed or does not import.
    """
    global _report
    if _report is not None:
        return _report
    start = time.perf_counter()
    try:
        import numba  # noqa: F401
    except ImportError as e:
        from rrt_pin.core import backends

        backends.get("compiled").require(e)
    imported = time.perf_counter()
    jit = importlib.import_module(_JIT)
    done = time.perf_counter()
    from rrt_pin.compiled import _cache
    from rrt_pin.compiled import _jit as dyn

    origins = set(dyn.ORIGINS.values())
    cache_dir = dyn._CACHE_DIR if origins - {"memory"} else None
    if cache_dir is not None and origins <= {"loaded", "compiled"}:
        if not _cache.is_ready(cache_dir):
            _cache.mark_ready(cache_dir, {"signatures": dict(dyn.SIGNATURES)})
            _cache.prune_superseded(cache_dir)
        _build_ahead_of_time()
    dyn.warn_problems()
    _report = CompileReport(
        numba_import=imported - start,
        compile=done - imported,
        from_cache=origins == {"loaded"} and cache_dir is not None,
        cache_dir=cache_dir,
        functions=dict(dyn.SECONDS),
        origins=dict(dyn.ORIGINS),
    )
    del jit
    _logger.info(_report.describe())
    return _report


def _build_ahead_of_time() -> None:
    """Build the closed-form dynamics ahead of time once (see :mod:`rrt_pin.compiled._aot`)."""
    from rrt_pin.compiled import _aot

    if _aot.is_built() or not _aot.can_build():
        return
    start = time.perf_counter()
    _logger.info("building the ahead-of-time dynamics module (once for these sources)")
    built = _aot.build()
    _logger.info(
        "ahead-of-time dynamics module %s in %.1f s",
        "built" if built else "not built (the JIT is used)",
        time.perf_counter() - start,
    )


def aot_built() -> bool:
    """Whether the closed-form dynamics and single runs load without numba.

    Cheap: looks for the ahead-of-time module of the current sources
    (:mod:`rrt_pin.compiled._aot`); :func:`inverse_dynamics`,
    :func:`forward_dynamics` and :func:`simulate_compiled` then start without
    importing numba (batches still load numba's JIT; ``scripts/bench/aot.py``
    measures both).
    """
    from rrt_pin.compiled import _aot

    return _aot.is_built()


def machine_code() -> Any:
    """The compiled functions of the dynamics and of single runs, by name.

    The ahead-of-time module when it is built (no numba import), else numba's
    JIT functions (imported, loaded or compiled by :func:`ensure_compiled`); the
    choice is made once per process (every run asks).

    Raises:
        ImportError: numba is not installed and nothing is built ahead of time.
    """
    global _code
    if _code is None:
        from rrt_pin.compiled import _aot

        code = _aot.load()
        if code is None:
            ensure_compiled()
            from rrt_pin.compiled import _jit

            code = _Functions(_jit.DISPATCHERS)
        _code = code
    return _code


#: What :func:`machine_code` chose in this process.
_code: Any = None


class _Functions:
    """Attribute access to a dict of functions (the JIT's dispatchers, by name)."""

    def __init__(self, functions: dict[str, Any]) -> None:
        self.__dict__.update(functions)
        self.__name__ = "rrt_pin.compiled._jit"


def compile_report() -> CompileReport | None:
    """The report of :func:`ensure_compiled` in this process, or None if not yet loaded."""
    return _report


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rrt_pin.compiled' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
