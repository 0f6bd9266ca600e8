"""The registry of dynamics backends: which engine computes, what it can do, whether it is here.

The CLI's ``--backend`` choices and help, ``auto``'s choice, the benchmark's
plan and the library's dispatch all read :data:`BACKENDS`.
"""

from __future__ import annotations

import importlib
import importlib.util
import logging
import os
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from rrt_pin.core.errors import InputError
from rrt_pin.core.extras import MissingExtra
from rrt_pin.core.text import duration

__all__ = [
    "BACKENDS", "DEFAULT_VARIABLE", "Backend", "Choice", "choose", "decide", "default",
    "estimated_seconds", "get", "names",
]  # fmt: skip


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
        startup: what a process pays once before the first use [s] (Pinocchio's
            import; numba's import and the machine code's load from the disk cache),
            beyond what every run pays.
        aot_startup: the same when the dynamics and single runs are built ahead of
            time (:func:`rrt_pin.compiled.aot_built`: the module's load, no numba) [s].
        inverse_cost: inverse dynamics of the chapter's arm [s per sample] (for
            ``compiled``, its closed-form kernel).
        simulate_cost: the chapter's direct run with the backend's default method
            [s per simulated second].
        robot_inverse_cost: inverse dynamics of another robot [s per sample and
            coordinate] (UR5's and Panda's, per coordinate: the larger).
        robot_simulate_cost: another robot's run under PD + gravity with the
            default method at the default accuracy [s per simulated second and coordinate].
        independent_variants: a batch's variant gets the same numbers whatever else is
            in the batch (each its own steps; Pinocchio's batch holds them all to one
            error test, so its numbers depend on the batch's composition).
        variant_params: ``simulate_batch`` takes the chapter arm's Params a variant
            (``params=[...]``); elsewhere a variant with parameters of its own is its own
            model.
        entries: where its code for each job lives, ``(job, "module:name")`` (or
            ``"module"``): the front doors (:func:`rrt_pin.inverse_dynamics`,
            :func:`rrt_pin.simulate`, the metrics and energy checks) reach a backend
            only through :meth:`entry`, so the layers below ``rrt_pin.compiled``
            never import it.

    The costs are medians on the reference machine (``docs/benchmarks.md``,
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
    robot_inverse_cost: float | None = None
    robot_simulate_cost: float | None = None
    independent_variants: bool = False
    variant_params: bool = False
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
            startup=0.06,
            inverse_cost=220e-9,
            simulate_cost=0.48e-3,
            robot_inverse_cost=76e-9,
            robot_simulate_cost=2.7e-3,
            entries=(
                ("inverse_runs", "rrt_pin.dynamics.inverse:pinocchio_runs"),
                ("simulate_runs", "rrt_pin.simulate.pinocchio_runs"),
            ),
        ),
        Backend(
            "symbolic",
            "the chapter arm's generated closed-form numpy kernel",
            any_robot=(),
            tasks=("inverse",),
            default_method=None,
            requires="numpy",
            inverse_cost=100e-9,
            entries=(("inverse_runs", "rrt_pin.dynamics.inverse:symbolic_runs"),),
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
            startup=0.7,
            aot_startup=0.017,
            inverse_cost=10e-9,
            simulate_cost=0.04e-3,
            robot_inverse_cost=5e-9,
            robot_simulate_cost=0.21e-3,
            independent_variants=True,
            variant_params=True,
            entries=(
                ("inverse", "rrt_pin.compiled:inverse_dynamics"),  # the arm's kernel
                ("inverse_generated", "rrt_pin.compiled.rnea:inverse_dynamics"),
                ("unsupported_joint", "rrt_pin.dynamics.rnea_source:unsupported_joint"),
                ("inverse_runs", "rrt_pin.compiled.runs:inverse"),  # the front door's
                ("simulate_runs", "rrt_pin.compiled.runs"),  # prepare, single, batch
                ("load_batch", "rrt_pin.compiled:ensure_compiled"),
                ("load_single", "rrt_pin.compiled:machine_code"),
                ("mass_matrix", "rrt_pin.compiled.dynamics:mass_matrix"),
                ("metrics", "rrt_pin.compiled._jit_metrics:run"),
                ("state", "rrt_pin.compiled:state_for"),  # (loaded, ahead of time, built)
                ("refusal", "rrt_pin.compiled:refusal"),  # why a law would not run compiled
                ("arm_kernel", "rrt_pin.compiled:runs_arm_kernel"),
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
    backend: Backend,
    task: str,
    work: float,
    started: bool,
    aot: bool = False,
    arm: bool = True,
    nv: int = 3,
) -> float | None:
    """What ``task`` would take on ``backend`` [s]; None when its costs are not known.

    Args:
        backend: the backend.
        task: ``inverse`` or ``simulate``.
        work: samples (``inverse``) or simulated seconds (``simulate``).
        started: the process already paid the backend's start-up.
        aot: the code is built ahead of time (a cheaper start-up).
        arm: the chapter's arm (its closed-form costs), else a robot of ``nv``
            coordinates (the per-coordinate costs of generated code or Pinocchio).
        nv: the robot's coordinates.
    """
    if arm:
        rate = backend.inverse_cost if task == "inverse" else backend.simulate_cost
    else:
        per = backend.robot_inverse_cost if task == "inverse" else backend.robot_simulate_cost
        rate = None if per is None else per * nv
    if rate is None:
        return None
    startup = backend.aot_startup if aot else backend.startup
    return (0.0 if started else startup) + rate * work


def names(task: str | None = None) -> tuple[str, ...]:
    """Names of the backends (that compute ``task``)."""
    return tuple(b.name for b in BACKENDS.values() if task is None or b.runs(task))


@dataclass(frozen=True)
class Choice:
    """What ``auto`` chose, and why (for ``-v`` and the run's metadata).

    Attributes:
        name: the backend.
        reason: why, in words.
        estimates: the estimated seconds of the whole job per backend considered
            (start-up included), None where a cost is not known.
    """

    name: str
    reason: str
    estimates: tuple[tuple[str, float | None], ...] = ()


#: The variable that sets the library's and the CLI's default backend (``auto`` when unset).
DEFAULT_VARIABLE = "RRT_PIN_BACKEND"


def default() -> str:
    """The default backend: ``$RRT_PIN_BACKEND`` if set (a backend's name or ``auto``), else ``auto``.

    Raises:
        InputError: the variable names no backend.
    """
    value = os.environ.get(DEFAULT_VARIABLE, "").strip() or "auto"
    if value != "auto" and value not in BACKENDS:
        raise InputError(f"{DEFAULT_VARIABLE}={value!r} is not one of {', '.join(BACKENDS)}, auto")
    return value


#: Per (task, robot name): the seconds this process spent on jobs beyond what ``compiled``
#: (built in numba's disk cache, not loaded) would have taken. When they reach its
#: start-up, ``auto`` loads it (rent or buy: a loop of short jobs never pays more than
#: twice the better of the two in hindsight).
_FORGONE: dict[tuple[str, str], float] = {}


def forget_forgone() -> None:
    """Start :data:`_FORGONE` afresh (as a new process would)."""
    _FORGONE.clear()


def choose(
    robot: Any,
    task: str,
    method: str | None = None,
    work: float = 0.0,
    *,
    controllers: Sequence[Any] = (),
    params: Any = None,
    batch: bool = False,
    build: bool = False,
    numeric_jacobian: bool | None = None,
) -> Choice:
    """The one ``auto`` policy (the default backend): the backend a job of ``work`` runs on.

    ``compiled`` is chosen when it computes the job the same way within the accuracy
    asked (the robot's joints, the method if one is named, every law in
    ``controllers``: :func:`rrt_pin.compiled.refusal`) and its machine code is built
    (looked at without importing numba; ``auto`` never compiles): always when it is
    already loaded in this process or built ahead of time (it loads in milliseconds);
    from the JIT's disk cache (numba's import and the load: :attr:`Backend.startup`)
    only when the whole job, start-ups included, is estimated no slower than the
    others (:func:`estimated_seconds`: ``work`` is samples for ``inverse``, simulated
    seconds for ``simulate``, all variants' for a ``batch``), or when this process's
    earlier such jobs, run elsewhere, already cost its start-up more than compiled
    would have (:data:`_FORGONE`: a loop of short jobs loads it after a while). Otherwise the cheaper by
    the estimate of ``pinocchio``, the engine of record, and (the chapter arm's inverse
    dynamics) ``symbolic``, its numpy kernel: the same efforts without Pinocchio's
    import. A method left unnamed is the chosen backend's default, at the tolerances
    chosen for the accuracy asked.

    Args:
        robot: a :class:`~rrt_pin.robot.robot.Robot`.
        task: ``inverse`` or ``simulate``.
        method: the integration method asked for (None: the chosen backend's default).
        work: the job's size (see above).
        controllers: the laws of a simulation (one a variant).
        params: the chapter arm's Params given with the job, if any.
        batch: a ``simulate_batch`` (its compiled code is never built ahead of time).
        build: the job may build the compiled code (a sweep: long, and it says so when
            it compiles): ``compiled`` whenever it computes the job as asked, whatever
            is built, so that every process of the job chooses alike.
        numeric_jacobian: whether an implicit method's Jacobian will be numerical (a
            physical model applied, or finite differences asked for), None if not known:
            the compiled code built for it differs.
    """
    engine, fast, numpy_kernel = BACKENDS["pinocchio"], BACKENDS["compiled"], BACKENDS["symbolic"]
    why = _cannot(fast, robot, task, method)
    arm = task == "inverse" and robot.supports(fast.name)
    loaded = aot = built = False
    if why is None and build:  # nothing looked up that differs between processes
        why = (
            fast.entry("refusal")(robot, controllers, params, method)
            if task == "simulate"
            else None
        )
        if why is None:
            return Choice(fast.name, "the job may build it (long; it says so when it does)")
    elif why is None:
        if task == "simulate":
            arm = fast.entry("arm_kernel")(robot, params, controllers)
        loaded, aot, built = fast.entry("state")(
            robot, task, batch, arm, method, controllers, numeric_jacobian
        )
        if not built:
            why = "compiled code not built (auto never compiles: ask for backend 'compiled')"
        elif task == "simulate":  # the laws last: checking them imports the integrators
            why = fast.entry("refusal")(robot, controllers, params, method)
    # every backend that can run the job as asked, with its estimate (start-up included)
    found = [(engine, estimated_seconds(engine, task, work, "pinocchio" in sys.modules, False,
                                        arm, robot.nv))]  # fmt: skip
    if numpy_kernel.runs(task) and robot.supports(numpy_kernel.name):
        found.append((numpy_kernel, estimated_seconds(numpy_kernel, task, work, True)))
    if why is None:
        found.append((fast, estimated_seconds(fast, task, work, loaded, aot, arm, robot.nv)))
    estimates = tuple((b.name, sec) for b, sec in found)
    if why is None and (loaded or aot):
        why = "already loaded" if loaded else "built ahead of time (loads in milliseconds)"
        return Choice(fast.name, why, estimates)
    known = [(sec, i) for i, (_, sec) in enumerate(found) if sec is not None]
    best = found[min(known)[1]][0] if known else engine
    if best is fast:
        return Choice(fast.name, "in the disk cache, and faster by the estimate", estimates)
    if why is None and known:  # built, not loaded: rent or buy its start-up
        running = estimated_seconds(fast, task, work, True, aot, arm, robot.nv)
        if running is not None and found[-1][1] is not None:
            key, paid = (task, robot.name), _FORGONE.get((task, robot.name), 0.0)
            if paid >= found[-1][1] - running:
                return Choice(fast.name, f"this process has spent ~{paid:.2g} s more on such "
                              "jobs than compiled would: its start-up pays", estimates)  # fmt: skip
            _FORGONE[key] = paid + max(0.0, min(known)[0] - running)
    if best is numpy_kernel:
        return Choice(best.name, "the same efforts, faster by the estimate (no import)", estimates)
    if why is None:
        why = "compiled would not be faster (numba's start-up)"
    return Choice(engine.name, why, estimates)


def decide(
    robot: Any,
    requested: str | None,
    task: str,
    method: str | None = None,
    work: float = 0.0,
    **job: Any,
) -> Choice:
    """The backend a job runs on and why: ``requested``, or the default (:func:`default`) if None.

    ``auto`` is decided by :func:`choose` (``job``: its keyword arguments) and said on
    the ``rrt_pin`` logger at INFO (``-v``) with the estimates; a backend named is
    "asked for" (by ``$RRT_PIN_BACKEND`` when that named it).

    Raises:
        InputError: ``$RRT_PIN_BACKEND`` names no backend.
    """
    name = default() if requested is None else requested
    if name != "auto":
        return Choice(name, f"{DEFAULT_VARIABLE}={name}" if requested is None else "asked for")
    choice = choose(robot, task, method, work, **job)
    log = logging.getLogger("rrt_pin")
    if choice.estimates and log.isEnabledFor(logging.INFO):
        costs = ", ".join(
            f"{b} ~{'?' if sec is None else duration(sec)}" for b, sec in choice.estimates
        )
        log.info("backend auto: %s", costs)
    log.info("backend auto chose %s (%s)", choice.name, choice.reason)
    return Choice(choice.name, f"auto: {choice.reason}", choice.estimates)


def _cannot(fast: Backend, robot: Any, task: str, method: str | None) -> str | None:
    """Why ``fast`` cannot compute this job as asked, its laws apart (None: it can)."""
    if not fast.available():
        return f"{fast.requires} is not installed (pip extra {fast.extra!r})"
    if not robot.supports(fast.name, task):
        return "compiled does not handle one of this robot's joints"
    if method is not None and not _method_runs(method, fast.name):
        return f"method {method!r} does not run compiled"
    return None


def _method_runs(method: str, backend: str) -> bool:
    """Whether ``method`` runs on ``backend`` (the methods' registry, one layer up, by name)."""
    methods = importlib.import_module("rrt_pin.simulate.methods")
    return bool(methods.get(method).runs_on(backend))
