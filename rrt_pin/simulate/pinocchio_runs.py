"""The Pinocchio backend behind the front door: what ``simulate`` and ``simulate_batch`` run.

Every backend's ``simulate_runs`` entry (:data:`rrt_pin.core.backends.BACKENDS`) offers
the same three functions, so that :mod:`rrt_pin.simulate.api` checks the inputs once and
hands over without asking which backend it has:

* ``prepare(robot, method, batch, params, controllers)``: imports and models, before the
  clock starts;
* ``single(...)``: one run, as ``(run, plant)``: ``run(options, began)`` makes the
  result (called again at other options by the error estimate); ``plant`` the arm's
  Params whose M(q) the energy check uses, or None;
* ``batch(...)``: ``run(options, began, efforts, keep, main)`` for B variants.

:data:`RECORDS_FAILURES`: whether ``batch`` records each variant's failure itself
(``failures="record"``); if not, the front door runs the variants one by one when one fails.
:data:`EFFORTS_ALWAYS`: whether ``batch`` computes the efforts whether or not it returns
them (then the front door measures limit events from them instead of computing them again).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core import cpus, memory
from rrt_pin.simulate import methods
from rrt_pin.simulate.kept import reduced, targets
from rrt_pin.simulate.physical_runs import RunPhysics, batch_limits

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate.options import Options
    from rrt_pin.simulate.results import BatchResult, SimulationResult

__all__ = ["EFFORTS_ALWAYS", "RECORDS_FAILURES", "batch", "prepare", "single"]

#: ``batch`` raises at a variant's failure; the front door then runs them one by one.
RECORDS_FAILURES = False
#: ``batch(efforts=False)`` computes no efforts (a limit check computes a variant's alone).
EFFORTS_ALWAYS = False


def prepare(
    robot: Robot, method: Any, batch: bool, params: Any, controllers: Sequence[Any]
) -> None:  # noqa: ARG001  (the same signature as every backend's)
    """Imports and model building, which are not simulation time.

    Only what the method runs on is imported: ODEPACK's extension alone for
    ``odepack``, all of ``scipy.integrate`` (much slower to import) for ``solve_ivp``'s
    methods.
    """
    family = methods.get(method).family if method in methods.METHODS else "odepack"
    if family == "odepack":
        from rrt_pin.simulate._odepack import load

        load()
    elif family == "scipy":
        import scipy.integrate  # noqa: F401

    import rrt_pin.simulate.pinocchio_backend  # noqa: F401

    robot.model  # noqa: B018  (builds the generated arm's model once)


def single(
    robot: Robot,
    controller: Any,
    law: Any,
    q0: np.ndarray,
    qd0: np.ndarray,
    t: np.ndarray,
    params: Any,
    options: Options,
    rp: RunPhysics,
) -> tuple[Callable[[Options, float], SimulationResult], None]:  # noqa: ARG001
    """One run of ``law`` (the checked controller, or the passive law) on Pinocchio's ABA."""
    from rrt_pin.simulate.pinocchio_backend import run_one

    def run(o: Options, began: float) -> SimulationResult:
        return run_one(robot, law, q0, qd0, t, o, began, rp.applied)

    return run, None


def batch(
    robot: Robot,
    controllers: Sequence[Any],
    laws: Sequence[Any],
    q0s: np.ndarray,
    qd0s: np.ndarray,
    t: np.ndarray,
    params: Any,
    options: Options,
    rp: RunPhysics,
    *,
    keep: str,
    threads: int | None,
    failures: str,
) -> Callable[..., BatchResult]:  # noqa: ARG001
    """B variants on one model (``pin.abaInParallel`` over a ``ModelPool``); metrics reduced.

    Raises:
        MemoryLimitError: not even one thread's copy of the model's data fits.
    """
    from rrt_pin.simulate.pinocchio_backend import run_batch

    qf = targets(laws) if keep == "metrics" else None
    chosen = _pool_threads(robot, threads)

    def measured(full: BatchResult) -> Any:
        return batch_limits(full.t, full.q, full.qd, full.tau, laws, rp)

    def run(o: Options, began: float, tau: bool, kept: str, main: bool = True) -> BatchResult:
        wants = tau or kept == "metrics" or (main and rp.needs_demand)
        full = run_batch(robot, laws, q0s, qd0s, t, o, chosen, wants, began, rp.applied)
        return reduced(full, kept, qf, tau, measured if main else None, rp, laws)

    return run


def _pool_threads(robot: Robot, chosen: int | None) -> int | None:
    """The threads of a Pinocchio batch whose ``ModelPool`` fits in memory.

    The pool holds a copy of the model's data a thread (one more while it is made):
    the asked count, or the default (None: as many copies as CPUs), is cut to what
    fits (:mod:`rrt_pin.core.memory`).

    Raises:
        MemoryLimitError: not even one thread's copy fits.
    """
    wanted = chosen if chosen is not None else cpus.available()
    data = memory.data_bytes(robot.model)
    fit = memory.threads_that_fit(
        wanted,
        memory.Cost(data) + memory.thread_cost(),
        fixed=memory.Cost(data),
        what=f"a batch of a {robot.nv}-joint model",
        each=f"{memory.describe(data)} a copy of Pinocchio's Data: one a thread, one more "
        "while they are made",
        name=None if chosen is None else "threads",
    )
    return chosen if fit == wanted else fit
