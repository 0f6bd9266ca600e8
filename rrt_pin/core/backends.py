"""The registry of dynamics backends: which engine computes, what it can do, whether it is here.

The CLI's ``--backend`` choices and help, ``auto``'s choice, the benchmark's
plan and the library's dispatch all read :data:`BACKENDS`.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
from dataclasses import dataclass
from typing import Any

from rrt_pin.core.errors import InputError
from rrt_pin.core.extras import MissingExtra

__all__ = ["BACKENDS", "Backend", "Choice", "choose", "estimated_seconds", "get", "names"]


#: The packages :meth:`Backend.available` has found.
_FOUND: set[str] = set()
#: The modules :meth:`Backend.entry` has imported and the names in them, by (backend,
#: job): a run asks at every call.
_ENTRIES: dict[tuple[str, str], tuple[Any, str]] = {}


@dataclass(frozen=True)
class Backend:
    """One dynamics engine.

    Attributes:
        name: ``pinocchio``, ``symbolic`` or ``compiled``.
        summary: one line for help texts.
        any_robot: the tasks it computes for any fixed-base robot whose joints it
            handles (the others: the chapter's RRT arm only, by its closed-form kernel).
        tasks: ``inverse`` and/or ``simulate``.
        default_method: the integration method ``simulate`` uses when none is given.
        requires: the module that must import (``pinocchio``, ``numpy``, ``numba``).
        extra: the pip extra that installs it.
        startup: what a process pays once before the first use [s] (numba's import and
            the machine code's load from the disk cache), beyond what every run pays.
        aot_startup: the same when the dynamics and single runs are built ahead of
            time (:func:`rrt_pin.compiled.aot_built`: the module's load, no numba) [s].
        inverse_cost: inverse dynamics of the chapter's arm [s per sample] (for
            ``compiled``, its closed-form kernel: other robots' generated kernels
            have no cost here, so ``auto`` does not choose them).
        simulate_cost: the chapter's direct run with the backend's default method
            [s per simulated second].
        entries: where its code for each job lives, ``(job, "module:name")`` (or
            ``"module"``): the front doors (:func:`rrt_pin.inverse_dynamics`,
            :func:`rrt_pin.simulate`, the metrics and energy checks) reach a backend
            only through :meth:`entry`, so the layers below ``rrt_pin.compiled``
            never import it.

    The three costs are medians on the reference machine (``docs/benchmarks.md``,
    ``scripts/bench/auto.py`` measures them); ``auto`` compares them, nothing else.
    """

    name: str
    summary: str
    any_robot: tuple[str, ...]
    tasks: tuple[str, ...]
    default_method: str | None
    requires: str
    extra: str | None = None
    startup: float = 0.0
    aot_startup: float = 0.0
    inverse_cost: float | None = None
    simulate_cost: float | None = None
    entries: tuple[tuple[str, str], ...] = ()

    def available(self) -> bool:
        """Whether its package is installed (cheap: looks, does not import).

        A package found once is taken as installed for the rest of the process
        (runs ask at every call), unless ``sys.modules`` blocks it (None there: the
        way to make an import fail); one not found is looked for again.
        """
        if self.requires in _FOUND and sys.modules.get(self.requires, True) is not None:
            return True
        if importlib.util.find_spec(self.requires) is None:
            return False
        _FOUND.add(self.requires)
        return True

    def entry(self, job: str) -> Any:
        """The function (or module) that does ``job`` on this backend, imported on first use.

        Raises:
            KeyError: the backend has no such job (a programming error).
        """
        key = (self.name, job)
        found = _ENTRIES.get(key)
        if found is None:
            module, _, name = dict(self.entries)[job].partition(":")
            found = _ENTRIES[key] = (importlib.import_module(module), name)
        module, name = found
        return getattr(module, name) if name else module  # looked up at each call

    def require(self, cause: BaseException | None = None) -> None:
        """Raise :class:`~rrt_pin.core.extras.MissingExtra` unless its package is installed.

        The one place that says a backend's extra is missing (the hint names the pip
        extra and the command that installs it here). ``cause``: the ImportError met
        while loading it (raised then even if the package looked installed).
        """
        if cause is None and self.available():
            return
        error = MissingExtra(self.requires, self.extra or "", f"backend {self.name!r}")
        raise error from cause

    def runs(self, task: str) -> bool:
        """Whether it computes ``task`` (``inverse`` or ``simulate``)."""
        return task in self.tasks

    def runs_any_robot(self, task: str) -> bool:
        """Whether it computes ``task`` for robots other than the chapter's arm."""
        return task in self.any_robot


#: Every backend, by name; the first is the default and the engine of record.
BACKENDS: dict[str, Backend] = {
    b.name: b
    for b in (
        Backend(
            "pinocchio",
            "Pinocchio's RNEA/ABA in C++, any URDF (the engine of record)",
            any_robot=("inverse", "simulate"),
            tasks=("inverse", "simulate"),
            default_method="odepack",
            requires="pinocchio",
            inverse_cost=300e-9,
            simulate_cost=0.21e-3,
        ),
        Backend(
            "symbolic",
            "the chapter arm's generated closed-form numpy kernel",
            any_robot=(),
            tasks=("inverse",),
            default_method=None,
            requires="numpy",
        ),
        Backend(
            "compiled",
            "machine code (numba): the chapter arm's kernel and integrators; inverse "
            "dynamics and simulations of any robot with revolute, prismatic or continuous "
            "joints, generated from its model",
            any_robot=("inverse", "simulate"),
            tasks=("inverse", "simulate"),
            default_method="DOP853",
            requires="numba",
            extra="fast",
            startup=0.8,
            aot_startup=0.02,
            inverse_cost=14e-9,
            simulate_cost=0.0086e-3,
            entries=(
                ("inverse", "rrt_pin.compiled:inverse_dynamics"),  # the arm's kernel
                ("inverse_generated", "rrt_pin.compiled.rnea:inverse_dynamics"),
                ("unsupported_joint", "rrt_pin.dynamics.rnea_source:unsupported_joint"),
                ("simulate", "rrt_pin.compiled.integrate"),  # run_one, run_batch, check_model
                ("simulate_generated", "rrt_pin.compiled.robot_runs"),  # run_one, run_batch
                ("load_batch", "rrt_pin.compiled:ensure_compiled"),
                ("load_single", "rrt_pin.compiled:machine_code"),
                ("mass_matrix", "rrt_pin.compiled.dynamics:mass_matrix"),
                ("metrics", "rrt_pin.compiled._jit_metrics:run"),
                ("state", "rrt_pin.compiled:build_state"),  # (loaded, ahead of time, built)
            ),
        ),
    )
}


def get(name: object, task: str | None = None) -> Backend:
    """The backend called ``name`` (that computes ``task``, if given).

    Raises:
        InputError: unknown name, or a backend without that task.
    """
    backend = BACKENDS.get(name) if isinstance(name, str) else None
    if backend is None or (task is not None and not backend.runs(task)):
        valid = [b.name for b in BACKENDS.values() if task is None or b.runs(task)]
        raise InputError(f"backend={name!r} is not one of {', '.join(valid)}")
    return backend


def estimated_seconds(
    backend: Backend, task: str, work: float, started: bool, aot: bool = False
) -> float | None:
    """What ``task`` would take on ``backend`` [s]; None when its costs are not known.

    Args:
        backend: the backend.
        task: ``inverse`` or ``simulate``.
        work: samples (``inverse``) or simulated seconds (``simulate``).
        started: the process already paid the backend's start-up.
        aot: the code is built ahead of time (a cheaper start-up).
    """
    rate = backend.inverse_cost if task == "inverse" else backend.simulate_cost
    if rate is None:
        return None
    startup = backend.aot_startup if aot else backend.startup
    return (0.0 if started else startup) + rate * work


def names(task: str | None = None) -> tuple[str, ...]:
    """Names of the backends (that compute ``task``)."""
    return tuple(b.name for b in BACKENDS.values() if task is None or b.runs(task))


@dataclass(frozen=True)
class Choice:
    """What ``auto`` chose, and why (for ``-v``).

    Attributes:
        name: the backend.
        reason: why, in words.
        estimates: the estimated seconds of the whole job per backend considered
            (start-up included), None where a cost is not known.
    """

    name: str
    reason: str
    estimates: tuple[tuple[str, float | None], ...] = ()


def choose(robot: Any, task: str, method: str | None = None, work: float = 0.0) -> Choice:
    """The one ``auto`` policy: the backend a job of ``work`` should run on.

    ``compiled`` is chosen only for a robot whose closed-form kernels it has (the
    chapter's arm: their costs are known; other robots' generated kernels are left
    to an explicit ``compiled``), for a method it runs (``auto`` never changes the
    method or the tolerances), when its machine code is already built (in this
    process, ahead of time or in the disk cache: looked at without importing numba),
    and when the whole job, start-up included, is estimated at most half of
    ``pinocchio``'s (:func:`estimated_seconds`; ``work``: samples for ``inverse``,
    simulated seconds for ``simulate``). Otherwise ``pinocchio``, the engine of record.

    Args:
        robot: a :class:`~rrt_pin.robot.robot.Robot`.
        task: ``inverse`` or ``simulate``.
        method: the integration method asked for (None: the backend's default).
        work: the job's size (see above).
    """
    engine, fast = BACKENDS["pinocchio"], BACKENDS["compiled"]
    wanted = method or (engine.default_method if task == "simulate" else None)
    runs = wanted is None or _method_runs(wanted, fast.name)
    started = aot = built = False
    if robot.supports(fast.name) and runs and fast.available():
        started, aot, built = fast.entry("state")()
    if not built:
        if robot.supports(fast.name) and runs:
            why = "compiled code not built"
        elif robot.supports(fast.name, task):
            why = "auto leaves this robot's generated inverse dynamics to backend 'compiled'"
        else:
            why = "compiled cannot run this robot or method"
        return Choice(engine.name, why)
    mine = estimated_seconds(fast, task, work, started, aot)
    theirs = estimated_seconds(engine, task, work, True)
    saves = mine is not None and theirs is not None and 2.0 * mine <= theirs
    estimates = ((fast.name, mine), (engine.name, theirs))
    if saves:
        return Choice(fast.name, "faster by the estimate", estimates)
    return Choice(engine.name, "compiled would not be faster", estimates)


def _method_runs(method: str, backend: str) -> bool:
    """Whether ``method`` runs on ``backend`` (the methods' registry, one layer up, by name)."""
    methods = importlib.import_module("rrt_pin.simulate.methods")
    return bool(methods.get(method).runs_on(backend))
