"""The compiled backend behind the front door: the arm's closed form or a robot's generated code.

The same three functions as every backend's ``simulate_runs`` entry (see
:mod:`rrt_pin.simulate.pinocchio_runs`): ``prepare``, ``single`` and ``batch``. Which
code runs is decided here, by :func:`rrt_pin.compiled.runs_arm_kernel` (the one rule):
the chapter arm's hand-derived kernels (:mod:`rrt_pin.compiled.integrate`) for the arm
or a job given its Params, else the robot's generated integrators
(:mod:`rrt_pin.compiled.robot_runs`).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING, Any

from rrt_pin.compiled import machine_code, runs_arm_kernel
from rrt_pin.core.errors import InputError
from rrt_pin.robot.params import Params

if TYPE_CHECKING:
    import numpy as np

    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate.options import Options
    from rrt_pin.simulate.physical_runs import RunPhysics
    from rrt_pin.simulate.results import BatchResult, SimulationResult

__all__ = ["EFFORTS_ALWAYS", "RECORDS_FAILURES", "batch", "inverse", "prepare", "single"]

#: ``batch`` records each variant's failure itself (``failures="record"``).
RECORDS_FAILURES = True
#: ``batch`` computes the efforts in its kernels whether or not it returns them.
EFFORTS_ALWAYS = True


def _generated(robot: Robot, params: Any, controllers: Sequence[Any]) -> bool:
    """Whether ``robot`` runs its generated code (not the arm's kernel).

    Raises:
        InputError: the generated code does not handle one of its joints.
    """
    if runs_arm_kernel(robot, params, controllers):
        return False
    if not robot.supports("compiled", "simulate"):
        from rrt_pin.dynamics.rnea_source import unsupported_joint

        raise InputError(f"backend 'compiled': {unsupported_joint(robot.model)}; use 'pinocchio'")
    return True


def plant(robot: Robot, params: Any, controllers: Sequence[Any]) -> Params:
    """The chapter arm's Params a run of its kernel uses.

    ``params`` if given, else the robot's own, else a chapter law's.

    Raises:
        InputError: none of them is a Params.
    """
    if isinstance(params, Params):
        return params
    for candidate in (params, robot.params, *(getattr(c, "params", None) for c in controllers)):
        if isinstance(candidate, Params):
            return candidate
    if params is not None:
        raise InputError(f"params must be a Params, not {type(params).__name__}")
    raise InputError(
        "backend 'compiled' simulates the chapter's RRT arm from its Params: pass the arm "
        "(rrt_pin.robot.robots.chapter_arm(params)), params=…, or a chapter controller"
    )


def prepare(
    robot: Robot, method: Any, batch: bool, params: Any, controllers: Sequence[Any]
) -> None:  # noqa: ARG001  (the same signature as every backend's)
    """The arm's machine code loaded before the clock starts (a robot's: in ``single``/``batch``).

    A single run takes the module built ahead of time when there is one; batches run on
    threads, which need the JIT's (GIL-free) functions.
    """
    if runs_arm_kernel(robot, params, controllers):
        from rrt_pin.compiled import ensure_compiled

        ensure_compiled() if batch else machine_code()


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
) -> tuple[Callable[[Options, float], SimulationResult], Params | None]:  # noqa: ARG001
    """One run: ``(run, plant)``, the arm's Params as ``plant`` when its kernel runs.

    Raises:
        InputError: a joint or a law the compiled code does not run.
    """
    if _generated(robot, params, [controller]):
        from rrt_pin.compiled import robot_runs

        robot_runs.prepare(robot, [controller], options, rp.applied)  # before the clock starts
        physical = {} if rp.applied is None else {"physical": rp.applied}

        def run(o: Options, began: float) -> SimulationResult:
            return robot_runs.run_one(robot, controller, q0, qd0, t, o, began, **physical)

        return run, None
    from rrt_pin.compiled import integrate

    p = plant(robot, params, [controller])
    if robot.params is None or robot.params is not p:
        integrate.check_model(robot.model, p)

    def run_arm(o: Options, began: float) -> SimulationResult:
        return integrate.run_one(p, controller, q0, qd0, t, o, start=began)

    return run_arm, p


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
    """B variants: ``run(options, began, efforts, keep, main)``.

    Raises:
        InputError: a joint or a law the compiled code does not run.
    """
    if _generated(robot, params, controllers):
        from rrt_pin.compiled import robot_runs

        robot_runs.prepare(robot, controllers, options, rp.applied)  # before the clock starts
        physical = {} if rp.applied is None else {"physical": rp.applied}

        def run(o: Options, began: float, tau: bool, kept: str, main: bool = True) -> BatchResult:
            return robot_runs.run_batch(
                robot, controllers, q0s, qd0s, t, o, tau, keep=kept, threads=threads,
                start=began, failures=failures, **physical,
            )  # fmt: skip

        return run
    from rrt_pin.compiled import integrate

    plants = (
        list(params) if isinstance(params, (list, tuple)) else plant(robot, params, controllers)
    )

    def run_arm(o: Options, began: float, tau: bool, kept: str, main: bool = True) -> BatchResult:
        return integrate.run_batch(
            plants, controllers, q0s, qd0s, t, o, tau, keep=kept, threads=threads, start=began,
            failures=failures,
        )  # fmt: skip

    return run_arm


def inverse(
    b: Any,
    model: Any,
    robot: Robot | None,
    params: Any,
    q: Any,
    qd: Any,
    qdd: Any,
    num_threads: int | None,
) -> np.ndarray:
    """Inverse dynamics: the arm's kernel (the arm, or its Params given), else generated RNEA.

    Raises:
        InputError: bad samples, an unsupported joint, or non-finite efforts (named).
    """
    import numpy as np

    from rrt_pin.dynamics.inverse import arm_samples, generated_runs

    arm = runs_arm_kernel(robot, params, ()) if robot is not None else params is not None
    if not arm:
        if model is None:
            raise InputError(f"backend={b.name!r} needs a Robot, a Pinocchio model or Params")
        return generated_runs(b, model, robot, q, qd, qdd, num_threads)
    params, q, qd, qdd, single = arm_samples(b.name, model, robot, params, q, qd, qdd, False)
    b.require()
    tau = np.asarray(b.entry("inverse")(q, qd, qdd, params), dtype=float)
    return tau[0] if single else tau
