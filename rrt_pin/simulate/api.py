"""``simulate`` and ``simulate_batch``: check the inputs once, then hand over to a backend."""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core import backends, cpus, validate
from rrt_pin.core.errors import DivergenceError, InputError
from rrt_pin.core.identity import IdentityCache
from rrt_pin.robot import robots
from rrt_pin.robot.params import Params, check_params
from rrt_pin.robot.robot import Robot, bare_model, params_given
from rrt_pin.simulate.control import Controller, as_controller
from rrt_pin.simulate.energy import check_energy, check_energy_batch
from rrt_pin.simulate.failures import FAILURES, one_at_a_time
from rrt_pin.simulate.options import Options, resolve
from rrt_pin.simulate.physical_runs import batch_limits, energy_law, run_physics, with_limits
from rrt_pin.simulate.results import KEEPS

if TYPE_CHECKING:
    from rrt_pin.robot.params import Params
    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate.results import BatchResult, SimulationResult

__all__ = ["as_robot", "default_threads", "simulate", "simulate_batch"]


def as_robot(model: Any, params: Params | None = None) -> Robot:
    """The :class:`~rrt_pin.robot.robot.Robot` of ``model`` (a Robot, or a Pinocchio model).

    A Pinocchio model equal to the chapter's arm built from ``params`` becomes
    that arm (so its closed-form backends apply).

    Raises:
        InputError: ``model`` is neither.
    """
    if isinstance(model, Robot):
        return model
    cached = _ROBOTS.get(model, params)
    if cached is not None:
        return cached
    return _ROBOTS.put(model, params, value=_as_robot(model, params))


#: The robots of the last few Pinocchio models given (a Robot describes the joints, which a
#: model keeps; its gravity and inertias are read from the model itself at each run).
_ROBOTS: IdentityCache[Robot] = IdentityCache(8)


def _as_robot(model: Any, params: Params | None) -> Robot:
    return robots.of_model(model, params)


def default_threads() -> int:
    """The CPUs this process may run on (at least 1), capped by ``OMP_NUM_THREADS`` if set."""
    return cpus.available()


def _runs(backend: str) -> Any:
    """The backend's runs (its ``simulate_runs`` entry), its extra checked first.

    See :mod:`rrt_pin.simulate.pinocchio_runs` for what every backend's entry offers.
    """
    b = backends.get(backend, "simulate")
    b.require()
    return b.entry("simulate_runs")


def simulate(
    model: Any,
    controller: Any,
    q0: Sequence[float] | np.ndarray,
    qd0: Sequence[float] | np.ndarray | None = None,
    t_eval: Sequence[float] | np.ndarray | None = None,
    *,
    method: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    backend: str | None = None,
    step: float | None = None,
    jacobian: str = "analytic",
    params: Params | None = None,
    estimate_error: bool = True,
    accuracy: float | None = None,
    effort_limits: bool = True,
    position_limits: bool = True,
    losses: bool = True,
) -> SimulationResult:
    """Simulate a robot under ``controller`` from (q0, qd0), sampled at ``t_eval``.

    Args:
        model: a :class:`~rrt_pin.robot.robot.Robot` (revolute, continuous, prismatic
            joints…); a bare Pinocchio model is deprecated (pass
            ``Robot.from_model(model)``).
        controller: a :class:`~rrt_pin.simulate.control.Controller`, an object with
            ``efforts(t, q, qd)``, a function ``f(t, q, qd)`` (or ``f(q, qd)``),
            or None (no effort: passive motion).
        q0: initial joint coordinates (nv,) [rad or m] (angles for continuous
            joints; Pinocchio's (nq,) configuration is accepted too).
        qd0: initial velocities (nv,) [rad/s or m/s]; None (the default) for rest.
        t_eval: increasing output times [s] (required; e.g.
            ``rrt_pin.time_grid(15.0, 0.01)``); the run starts at ``t_eval[0]``.
        method: a method of :data:`rrt_pin.simulate.methods.METHODS` that the backend
            runs (default: the backend's, ``odepack`` on Pinocchio, ``DOP853``
            compiled; the result says which).
        rtol: relative tolerance of the adaptive methods, in (0, 1) (default:
            chosen for ``accuracy``); given alone it sets atol to rtol/100 too.
        atol: absolute tolerance [rad, m, rad/s, m/s], in (0, 1) (default:
            chosen for ``accuracy``, rtol/100).
        backend: ``pinocchio``, ``compiled`` or ``auto``; default ``auto`` (or
            ``$RRT_PIN_BACKEND``): compiled when its code is built and it runs this
            robot, law and method, else pinocchio (:func:`rrt_pin.core.backends.choose`;
            ``result.backend`` says which, ``-v`` logging why).
        step: longest step of the fixed-step methods [s]; default the shortest
            interval of ``t_eval``.
        jacobian: ``analytic`` or ``finite-difference`` for LSODA, Radau, BDF.
        params: the arm's parameters for the compiled backend (default: the
            robot's, or the controller's).
        estimate_error: also estimate the global error of q (``result.error_estimate``
            [rad or m]) from a companion run of the same method at looser
            tolerances, with the rate of error ∝ tolᵖ measured for the method
            (twice or half the step for fixed-step methods, Richardson's formula;
            see :mod:`rrt_pin.simulate.estimate`), and warn (``AccuracyWarning``)
            when it exceeds the accuracy asked for. False skips it.
        accuracy: the accuracy asked for, max |q − q_exact| over the output times
            [rad or m], in (0, 1) (default 1e-8). An adaptive method's rtol and atol
            are then the loosest that keep it on the calibration's problems, with a
            measured safety factor (:func:`rrt_pin.simulate.methods.tolerances`);
            ``rtol`` or ``atol`` given explicitly win. Without ``accuracy``, a run at
            explicit tolerances asks for max(1e-8, rtol, atol).
        effort_limits: saturate the law's efforts at the URDF's ``<limit effort>`` [N·m or N].
        position_limits: compliant limits at the URDF's ``<limit lower upper>`` [rad or m]:
            past one, a spring–damper that only pushes back, k = m·ω², b = 2·m·ω,
            ω = 200 rad/s, m = 1/(M⁻¹)_kk at q0 (a fixed step must be ≤ 0.5/ω).
        losses: the URDF's ``<dynamics damping friction>``: −d·q̇ and Coulomb friction
            −f·tanh(q̇ / 1e-3 rad/s or m/s) [N·m or N]. The three apply to URDF robots
            (the chapter's arm states no binding limit; :mod:`rrt_pin.robot.limits`).

    Returns:
        States and the actuators' efforts at ``t_eval``, evaluation count and wall time
        (of the first run), the error estimate, and ``limits``: what the run crossed
        at its output samples (:class:`~rrt_pin.simulate.crossings.LimitEvent`).

    Raises:
        InputError: a bad robot, controller, state, time grid or option (named); a
            fixed step too long for the position limits.
        DivergenceError: the state became non-finite or the integrator failed.
    """
    if t_eval is None:
        raise InputError("simulate needs t_eval, the output times [s]: e.g. time_grid(15.0, 0.01)")
    bare_model("simulate", model)
    params_given("simulate", params)
    robot = as_robot(model, _checked_params(params))
    t = validate.times(t_eval)
    backend = backends.decide(robot, backend, "simulate", method, float(t[-1] - t[0]),
                              controllers=[controller], params=params,
                              numeric_jacobian=_numeric_jacobian(robot, method, jacobian,
                                                                 effort_limits, position_limits,
                                                                 losses)).name  # fmt: skip
    runs = _runs(backend)
    runs.prepare(robot, method, False, params, [controller])  # not simulation time
    q0 = robot.as_coordinates("q0", q0)
    qd0 = (
        np.zeros(robot.nv) if qd0 is None else validate.vector("qd0", qd0, robot.nv, "rad/s or m/s")
    )
    options = resolve(
        t, backend=backend, method=method, rtol=rtol, atol=atol, step=step, jacobian=jacobian,
        accuracy=accuracy,
    )  # fmt: skip
    _refuse_ignored(robot, params, options.backend)
    # the same checks on both backends; the law's results are checked (rrt_pin.simulate.control)
    checked = (
        None if controller is None else as_controller(controller, robot.nv, robot.effort_names)
    )
    rp = run_physics(robot, q0[None], [checked], options, effort_limits=effort_limits,
                     position_limits=position_limits, losses=losses)  # fmt: skip
    law = _passive(robot) if checked is None else checked
    run, plant = runs.single(robot, controller, law, q0, qd0, t, params, options, rp)
    start = time.perf_counter()
    result = with_limits(_with_units(run(options, start), robot), rp, checked)
    check_energy(result, robot, energy_law(checked, result.limits, rp), plant)
    return _with_estimate(result, options, run) if estimate_error else result


def _numeric_jacobian(robot: Robot, method: Any, jacobian: Any, *switches: Any) -> bool | None:
    """Whether an implicit method's Jacobian will be numerical (for ``auto``), None if unknown.

    Finite differences asked for, or a physical model applied (the generated Jacobian is
    the law's alone). Looked at only for BDF, whose compiled code differs by it.
    """
    if method != "BDF" or not all(isinstance(s, (bool, np.bool_)) for s in switches):
        return None
    if jacobian == "finite-difference":
        return True
    from rrt_pin.robot.limits import physical_model

    effort, position, losses = switches
    return physical_model(
        robot, effort_limits=effort, position_limits=position, losses=losses
    ).active


def _checked_params(params: Any, name: str = "params") -> Any:
    """``params`` if None or a Params (a dict is refused: :func:`rrt_pin.robot.params.check_params`)."""
    if params is None:
        return None

    return check_params(params, name)


def _refuse_ignored(robot: Robot, params: Any, backend: str) -> None:
    """:func:`rrt_pin.robot.model.refuse_ignored`, imported only when ``params`` are given."""
    if params is not None:
        from rrt_pin.robot.model import refuse_ignored  # XML and models: not for every run

        refuse_ignored(robot, params, backend)


def _with_estimate(result: Any, options: Options, run: Any) -> Any:
    """``result`` with its error estimate (a companion run), warning when it exceeds the accuracy.

    ``run(options, began)`` runs the same problem at other options.
    """
    from dataclasses import replace

    from rrt_pin.simulate.estimate import attempt, warn_if_exceeded

    est, why = attempt(result, options, lambda o: run(o, time.perf_counter()), stacklevel=5)
    if est is None:
        return replace(result, estimate_failure=why)
    result = replace(result, estimate=est)
    warn_if_exceeded(result, stacklevel=4)
    return result


def _with_units(result: Any, robot: Robot) -> Any:
    """The result, knowing its robot and its coordinate units (for ``to_frame``, ``show``)."""
    import dataclasses

    units = tuple(robot.coordinate_units)
    if tuple(result.coordinate_units) != units:
        result = dataclasses.replace(result, coordinate_units=units)
    object.__setattr__(result, "robot", robot)  # a result just made, shared with no one
    return result


def _passive(robot: Robot) -> Any:

    class Passive(Controller):
        nv = robot.nv  # type: ignore[assignment]

        def efforts(self, t: float, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
            return np.zeros(robot.nv)

        def efforts_many(self, t: Any, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
            return np.zeros(np.shape(q))

    return Passive()


def simulate_batch(
    model: Any,
    controllers: Any,
    q0s: np.ndarray,
    qd0s: np.ndarray | None,
    t_eval: Sequence[float] | np.ndarray,
    *,
    method: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    backend: str | None = None,
    step: float | None = None,
    threads: int | None = None,
    efforts: bool = True,
    params: Params | Sequence[Params] | None = None,
    estimate_error: bool = True,
    keep: str = "trajectories",
    accuracy: float | None = None,
    failures: str = "raise",
    effort_limits: bool = True,
    position_limits: bool = True,
    losses: bool = True,
) -> BatchResult:
    """Simulate B variants of a robot at once; the same defaults as :func:`simulate`.

    Pinocchio backend: one model for every variant (``pin.abaInParallel`` over a
    ``ModelPool``); variants differ in controllers (gains, targets, any law
    following the contract) and initial states. Laws whose
    :meth:`~rrt_pin.simulate.control.Controller.feedback` share a gravity term are
    evaluated as arrays; others variant by variant. ``odepack``'s max-norm
    error test holds every variant to the tolerance.

    Compiled backend (the chapter's arm): variants run in machine code, each with
    its own step control, on ``threads`` threads, and may also differ in
    parameters (``params``: one Params per variant).

    Args:
        model: a Robot or a Pinocchio model, shared by the variants.
        controllers: one controller for all, or one per variant (see :func:`simulate`).
        q0s: initial joint coordinates, shape (B, nv) [rad or m].
        qd0s: initial velocities, shape (B, nv) [rad/s or m/s]; None for rest.
        t_eval: increasing output times [s].
        method: a method that runs in a batch on the backend (default: the backend's).
        rtol: relative tolerance, in (0, 1) (default: chosen for ``accuracy``, as
            :func:`simulate`).
        atol: absolute tolerance [rad, m, rad/s, m/s], in (0, 1) (default: chosen
            for ``accuracy``).
        backend: ``pinocchio``, ``compiled`` or ``auto`` (the default, as :func:`simulate`'s).
        step: longest step of the fixed-step methods [s].
        threads: threads of the batch, at most :func:`rrt_pin.core.cpus.max_threads`
            (256); default: the CPUs free now (compiled: all, they share the work), none with
            too little work, capped by ``OMP_NUM_THREADS``; the numbers do not depend on it.
            Each thread reserves a stack (and, Pinocchio backend, holds a copy of the
            model's data): a count that does not fit in the memory left is cut to
            one that does, with a warning on the ``rrt_pin`` logger
            (:mod:`rrt_pin.core.memory`). Pinocchio backend: OpenMP threads of
            ``pin.abaInParallel``, the free CPUs looked up again every 50 ms of the run,
            at least 32 variants a thread; compiled backend: threads sharing the
            variants, each taking the next one when it has room.
        efforts: also return the applied efforts at every output time.
        params: the arm's Params for the compiled backend: one, or one per variant.
        estimate_error: also estimate the global error of q, per variant and over
            all (a companion batch, states only; see :func:`simulate`); False skips it.
            With ``keep="final"`` or ``"metrics"`` it estimates the final states' error.
        accuracy: the accuracy asked for, max |q − q_exact| over the output times
            [rad or m], in (0, 1) (default 1e-8): chooses the tolerances as
            :func:`simulate` does.
        keep: what is kept of each variant, one of :data:`~rrt_pin.simulate.results.KEEPS`:
            ``"trajectories"`` (default), ``"final"`` (the last output time only,
            shapes (B, 1, nv)) or ``"metrics"`` (the same, and ``result.metrics``:
            the columns of :func:`rrt_pin.simulate.metrics.batch_metrics` against each
            controller's target ``qf``; every controller must have one). The
            compiled backend then stores no trajectory (``"final"`` also skips
            the dense output of DOP853 and RK45); the Pinocchio backend computes
            the trajectories and reduces them.
        failures: ``"raise"`` (default) the first variant that fails, or ``"record"``
            each variant's :class:`~rrt_pin.core.errors.DivergenceError` in
            ``result.failures`` (None where it succeeded; its rows and metrics NaN) and
            run the others (:mod:`rrt_pin.simulate.failures`); the error estimate is then
            skipped if a variant failed.
        effort_limits: saturate the laws' efforts at the URDF's effort limits (as
            :func:`simulate`).
        position_limits: the URDF's compliant position limits (as :func:`simulate`;
            the limits' stiffness from M at the first variant's q0).
        losses: the URDF's damping and Coulomb friction (as :func:`simulate`).

    Returns:
        States (B, T, nv) and efforts; ``result.variant(i)`` is one run;
        ``result.limits`` each variant's limit events (None: a compiled batch that
        kept no trajectories).

    Raises:
        InputError: bad shapes, values, controllers or options; an unknown ``keep``;
            ``threads`` not from 1 to :func:`rrt_pin.core.cpus.max_threads`.
        MemoryLimitError: not even one thread's copy of the model's data fits in
            the memory left (the need and the limit named).
        DivergenceError: a variant's state became non-finite or the integrator
            failed (the message names the coordinate and the variant), with
            ``failures="raise"``.
    """
    failures = validate.choice("failures", failures, FAILURES)
    bare_model("simulate_batch", model)
    params_given("simulate_batch", params)
    if isinstance(params, (list, tuple)):
        params = [_checked_params(p, f"params[{i}]") for i, p in enumerate(params)]
    else:
        params = _checked_params(params)
    first_params = params[0] if isinstance(params, list) and params else params
    robot = as_robot(model, first_params)  # type: ignore[arg-type]
    n = robot.nv
    q0s = validate.states("q0s", q0s, n, "rad or m")
    B = q0s.shape[0]
    qd0s = np.zeros((B, n)) if qd0s is None else validate.states("qd0s", qd0s, n, "rad/s or m/s")
    if qd0s.shape[0] != B:
        raise InputError(f"q0s has {B} rows but qd0s has {qd0s.shape[0]}")
    if controllers is None or callable(controllers) or not isinstance(controllers, Sequence):
        controllers = [controllers] * B
    controllers = list(controllers)
    if len(controllers) != B:
        raise InputError(f"{len(controllers)} controllers for {B} initial states")
    t = validate.times(t_eval)
    backend = backends.decide(robot, backend, "simulate", method, B * float(t[-1] - t[0]),
                              controllers=controllers, params=params, batch=True,
                              numeric_jacobian=_numeric_jacobian(robot, method, "analytic",
                                                                 effort_limits, position_limits,
                                                                 losses)).name  # fmt: skip
    runs = _runs(backend)
    runs.prepare(robot, method, True, params, controllers)  # not simulation time
    options = resolve(
        t, backend=backend, method=method, rtol=rtol, atol=atol, step=step, batch=True,
        accuracy=accuracy,
    )  # fmt: skip
    keep = validate.choice("keep", keep, KEEPS)
    _refuse_ignored(robot, params, options.backend)
    chosen = None if threads is None else _threads(threads)
    laws = []
    for i, c in enumerate(controllers):
        try:
            law = None if c is None else as_controller(c, n, robot.effort_names)
            laws.append(_passive(robot) if law is None else law)
        except InputError as e:
            raise InputError(f"controllers[{i}]: {e}") from e
    rp = run_physics(robot, q0s, laws, options, effort_limits=effort_limits,
                     position_limits=position_limits, losses=losses, name="q0s")  # fmt: skip
    run = runs.batch(robot, controllers, laws, q0s, qd0s, t, params, options, rp, keep=keep,
                     threads=chosen, failures=failures)  # fmt: skip
    # the limit events need the demanded efforts: taken from the run where it makes them anyway
    events = keep == "trajectories" and rp.measures and rp.needs_demand
    asked = efforts or (events and runs.EFFORTS_ALWAYS)
    start = time.perf_counter()
    if failures == "record" and not runs.RECORDS_FAILURES:
        try:
            result = run(options, start, asked, keep)
        except DivergenceError:  # which: each variant alone

            def alone(i: int) -> BatchResult:
                return simulate_batch(
                    robot, [controllers[i]], q0s[i : i + 1], qd0s[i : i + 1], t,
                    method=options.method.name, rtol=rtol, atol=atol, backend=options.backend,
                    step=step, threads=1, efforts=efforts, estimate_error=False, keep=keep,
                    accuracy=accuracy, effort_limits=effort_limits,
                    position_limits=position_limits, losses=losses,
                    params=params[i] if isinstance(params, list) else params,
                )  # fmt: skip

            result = one_at_a_time(alone, B, t.size if keep == "trajectories" else 1, n)
        if result.failures is None:
            result = dataclasses.replace(result, failures=(None,) * B)
    else:
        result = run(options, start, asked, keep)
    if keep == "trajectories" and not result.limits and rp.measures:
        result = dataclasses.replace(
            result, limits=batch_limits(t, result.q, result.qd, result.tau, laws, rp)
        )
    if asked and not efforts:
        result = dataclasses.replace(result, tau=None)
    result = _with_units(result, robot)
    if result.failures is not None and any(f is not None for f in result.failures):
        why = "a variant failed" if estimate_error else None
        return dataclasses.replace(result, estimate_failure=why)
    if not isinstance(params, list):  # variants with parameters of their own: not checked
        given = [
            None if c is None else energy_law(law, events, rp)
            for c, law, events in zip(controllers, laws, result.limits or [()] * B, strict=True)
        ]
        check_energy_batch(result, robot, given, q0s, qd0s)
    if not estimate_error:
        return result
    second = "trajectories" if keep == "trajectories" else "final"
    return _with_estimate(result, options, lambda o, began: run(o, began, False, second, False))


def _threads(threads: Any) -> int:
    """``threads=`` as an int from 1 to :func:`rrt_pin.core.cpus.max_threads` (256)."""
    return cpus.check_threads("threads", validate.positive_int("threads", threads))
