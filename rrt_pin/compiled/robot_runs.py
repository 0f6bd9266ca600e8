"""Simulations of any supported robot in machine code: ``simulate(robot, ..., backend="compiled")``.

Each robot's integrators are generated and compiled once (:mod:`rrt_pin.compiled.robot_code`);
here a run's robot, laws, states and options become arrays, the variants of a batch are
shared out over threads, and a variant's status becomes a
:class:`~rrt_pin.core.errors.DivergenceError` naming the robot's coordinate.

Laws that run compiled (the exact classes; a subclass may override ``efforts``):

* None: no effort (passive motion);
* :class:`~rrt_pin.simulate.control.PDGravityController` compensating this robot's
  own gravity (``pd_gravity_controller(robot.model, …)``, ``regulator(robot, …)``);
* :class:`~rrt_pin.simulate.control.TrackingController` on this robot along a sampled
  :class:`~rrt_pin.dynamics.trajectory.Trajectory` (``--track FILE``), shared by a batch's variants;
* :class:`~rrt_pin.simulate.control.OpenLoop` (``--efforts FILE``), shared likewise.

Any other law (a Python function, a user's controller, a motion given as a function of
time) runs on the Pinocchio backend; here it is refused in one line saying so.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from rrt_pin.compiled import robot_code, robot_entries
from rrt_pin.compiled.lanes import MAX_STEPS, _in_slices, _raise_status, _threads_that_fit
from rrt_pin.core import cpus
from rrt_pin.core.errors import DivergenceError, InputError
from rrt_pin.dynamics.trajectory import Trajectory
from rrt_pin.robot.limits import Physical, gravity_bound, physical_model
from rrt_pin.robot.robot import Robot
from rrt_pin.simulate import codes
from rrt_pin.simulate.control import OpenLoop, PDGravityController, TrackingController
from rrt_pin.simulate.metrics import GROUPS, SETTLING_BAND, metric_columns
from rrt_pin.simulate.options import Options
from rrt_pin.simulate.results import BatchResult, SimulationResult

__all__ = ["prepare", "run_batch", "run_one", "supports"]

_KEEP = {
    "trajectories": codes.KEEP_TRAJECTORIES,
    "final": codes.KEEP_FINAL,
    "metrics": codes.KEEP_METRICS,
}
#: A batch's default thread count gives no thread fewer variants than this.
MIN_PER_THREAD = 4
_NONE = (np.zeros(1), np.zeros((1, 1)))


def supports(controller: Any) -> bool:
    """Whether ``controller``'s law runs compiled (on a robot it is built for)."""
    return controller is None or type(controller) in (
        PDGravityController, TrackingController, OpenLoop,
    )  # fmt: skip


def _law(robot: Robot, controller: Any) -> tuple[int, np.ndarray, tuple[np.ndarray, np.ndarray]]:
    """(law code, parameters, (reference times, values)) of ``controller`` on ``robot``."""
    nv = robot.nv
    kind = type(controller)
    if controller is None:
        return codes.LAW_NONE, np.zeros(3 * nv), _NONE
    if kind is PDGravityController:
        if controller.nv != nv or not controller.compensates_gravity_of(robot.model):
            raise InputError(
                "backend 'compiled' compensates the gravity of the robot simulated: the "
                "pd_gravity controller's model must be that robot's model"
            )
        return (
            codes.LAW_PD_GRAVITY,
            np.array([*controller.kp, *controller.kd, *controller.qf]),
            _NONE,
        )
    if kind is TrackingController:
        motion = controller.motion
        if not isinstance(motion, Trajectory):
            raise InputError(
                "backend 'compiled' tracks a sampled motion (a Trajectory, e.g. from "
                "read_motion); a motion given as a function of time runs on backend 'pinocchio'"
            )
        if controller.robot.nv != nv or not bool(controller.robot.model == robot.model):
            raise InputError(
                "backend 'compiled' tracks with the robot simulated: the tracking "
                "controller's robot must be that robot"
            )
        rv = np.ascontiguousarray(np.hstack([motion.q, motion.qd, motion.qdd]), dtype=float)
        c = np.concatenate([controller.kp, controller.kd, np.zeros(nv)])
        return codes.LAW_TRACKING, c, (np.ascontiguousarray(motion.t, dtype=float), rv)
    if kind is OpenLoop:
        if controller.nv != nv:
            raise InputError(f"the open-loop efforts have {controller.nv} columns, the robot {nv}")
        reference = (np.ascontiguousarray(controller.t), np.ascontiguousarray(controller.tau))
        return codes.LAW_OPEN_LOOP, np.zeros(3 * nv), reference
    raise InputError(
        "backend 'compiled' runs pd_gravity_controller(...), tracking_controller(...) of a "
        "sampled motion, OpenLoop efforts, or None (no effort) on this robot, not "
        f"{kind.__name__}; use backend 'pinocchio' for other controllers"
    )


def _laws(robot: Robot, controllers: Sequence[Any]) -> tuple[np.ndarray, np.ndarray, tuple]:
    """(codes (B,), parameters (B, 3·nv), the shared reference) of a batch's laws."""
    count = len(controllers)
    laws = np.empty(count, dtype=np.int64)
    C = np.empty((count, 3 * robot.nv))
    seen: dict[int, tuple] = {}
    reference: tuple | None = None
    for i, controller in enumerate(controllers):
        key = id(controller)
        if key not in seen:
            try:
                seen[key] = _law(robot, controller)
            except InputError as e:
                raise InputError(f"controllers[{i}]: {e}" if count > 1 else str(e)) from e
        laws[i], C[i], ref = seen[key]
        if ref is not _NONE:
            if reference is None:
                reference = ref
            elif ref is not reference and not (
                np.array_equal(ref[0], reference[0]) and np.array_equal(ref[1], reference[1])
            ):
                raise InputError(
                    f"controllers[{i}]: backend 'compiled' runs a batch along one motion "
                    "(or one set of open-loop efforts) shared by its variants; use backend "
                    "'pinocchio' for variants with motions of their own"
                )
    return laws, C, reference or _NONE


def _entry(count: int, options: Options, laws: np.ndarray, physical: Physical | None) -> str:
    """The compiled entry a batch runs (:func:`rrt_pin.compiled.robot_entries.entry`).

    Adaptive PD variants run side by side in lanes; Adams's method, BDF and anything else
    one after the other, on the entry bound to PD plus gravity when every law is that.
    BDF's Jacobian is numerical for every variant (its entry then has no generated one)
    under a physical model, with ``jacobian="finite-difference"``, or with no PD law.
    """
    pd_laws = laws == codes.LAW_PD_GRAVITY
    pd = bool(laws.size) and bool(np.all(pd_laws))
    numeric = numeric_jacobian(options.jacobian, physical) or not bool(np.any(pd_laws))
    return robot_entries.entry(options.method.code, count, pd, numeric)


def numeric_jacobian(jacobian: str | None, physical: Physical | None) -> bool:
    """Whether BDF's Jacobian is SciPy's ``num_jac`` whatever the law.

    So when it is asked for, or a physical model is applied (the generated one is the
    law's alone).
    """
    return jacobian == "finite-difference" or (physical is not None and physical.active)


def _room(robot: Robot, physical: Physical) -> np.ndarray:
    """Per joint, how large a PD effort may be with PD plus G(q) unsaturated (nv,) [N·m or N].

    The effort limit less a bound of |G| over the joints' ranges
    (:func:`rrt_pin.robot.limits.gravity_bound`); −inf where no bound is known. Where
    every joint's PD effort is within it and no joint is past a limit, the lanes leave
    G(q) out (it cancels to rounding).
    """
    room = physical.effort - gravity_bound(robot.model, physical)
    return np.where(np.isnan(room), np.inf, room)


def prepare(
    robot: Robot,
    controllers: Sequence[Any],
    options: Options,
    physical: Physical | None = None,
) -> tuple:
    """Compile (or load) the one entry these runs need, before any run's clock starts.

    A single run needs ``run_many`` (or its copy for PD plus gravity); a batch of adaptive
    PD variants only ``run_lanes``: a robot's first use compiles one entry, not all.
    ``physical``: the model the runs apply (BDF's entry depends on it).

    Returns:
        The laws as arrays (:func:`_laws`), for the run.

    Raises:
        InputError: a law that does not run compiled (refused before anything compiles).
    """
    arrays = _laws(robot, controllers)
    code = robot_code.integrators_for(robot.model, robot.name)
    code.entry(_entry(len(controllers), options, arrays[0], physical))
    return arrays


def _run(
    robot: Robot,
    controllers: Sequence[Any],
    Y0: np.ndarray,
    t: np.ndarray,
    options: Options,
    keep: str,
    threads: int,
    band: float,
    max_steps: int,
    physical: Physical | None = None,
    law_arrays: tuple | None = None,
) -> tuple[np.ndarray, ...]:
    code = robot_code.integrators_for(robot.model, robot.name)
    nv = robot.nv
    if physical is not None and physical.active:
        if physical.nv != nv:
            raise InputError(f"the physical model has {physical.nv} coordinates, the robot {nv}")
        P, phys = physical.as_array(), np.ones(1, dtype=np.int64)
    else:
        P, phys = np.zeros((8, nv)), np.zeros(1, dtype=np.int64)
    stated = physical_model(robot)  # what the metrics measure against, applied or not
    laws, C, (rt, rv) = law_arrays or _laws(robot, controllers)
    count, n = Y0.shape[0], Y0.shape[1]
    entry = _entry(count, options, laws, physical)
    lanes = entry.startswith("run_lanes")
    room = _room(robot, physical) if lanes and phys[0] else np.full(nv, -np.inf)
    P = np.ascontiguousarray(np.vstack([P, stated.lower, stated.upper, stated.effort, room]))
    keep_code = _KEEP[keep]
    rows = t.size if keep == "trajectories" else 1
    out_y = np.empty((count, rows, n))
    out_tau = np.empty((count, rows, nv))
    metrics = np.full((count, codes.metric_start(codes.METRIC_WIDTH, nv)), np.nan)
    info = np.zeros((count, 3), dtype=np.int64)
    reached = np.empty(count)
    atol = np.full(n, options.atol if options.atol is not None else 0.0)
    rtol = options.rtol if options.rtol is not None else 0.0
    step = options.step if options.step is not None else 0.0
    method = options.method.code
    if method == codes.METHOD_BDF and options.jacobian == "finite-difference":
        method = codes.METHOD_BDF_NUMERIC  # SciPy's num_jac whatever the law
    if lanes:
        # side by side in vector lanes: the same steps, each variant its own
        lanes = code.entry(entry)
        args = (
            method, Y0, t, atol, rtol, math.inf, max_steps, C, keep_code, band,
            out_y, out_tau, metrics, info, reached,
        )  # fmt: skip

        def run(a: int, b: int) -> None:
            lanes(*args, a, b, P, phys)
    else:
        many = code.entry(_entry(count, options, laws, physical))
        args = (
            method, Y0, t, step, atol, rtol, math.inf, max_steps, laws, C, rt, rv,
            keep_code, band, out_y, out_tau, metrics, info, reached,
        )  # fmt: skip

        def run(a: int, b: int) -> None:
            many(*args, a, b, P, phys)

    used = _in_slices(run, count, threads)
    return out_y, out_tau, metrics, info, reached, np.int64(used)


def _raise(info: np.ndarray, reached: np.ndarray, tau: np.ndarray, robot: Robot,
           options: Options, max_steps: int, batch: bool) -> None:  # fmt: skip
    failed = np.flatnonzero(info[:, 0] != codes.STATUS_OK)
    if failed.size:
        b = int(failed[0])
        names = (*robot.q_names, *robot.qd_names)
        _raise_status(
            info[b], reached[b], options.method.name, options.step, max_steps,
            b if batch else None, tau[b], names=names, effort_names=robot.effort_names,
        )  # fmt: skip


def _failures(info: np.ndarray, reached: np.ndarray, tau: np.ndarray, robot: Robot,
              options: Options, max_steps: int) -> list[DivergenceError | None]:  # fmt: skip
    """Each variant's DivergenceError (named as a single run's), or None."""
    out: list[DivergenceError | None] = [None] * info.shape[0]
    for b in np.flatnonzero(info[:, 0] != codes.STATUS_OK):
        try:
            _raise(info[b : b + 1], reached[b : b + 1], tau[b : b + 1], robot, options,
                   max_steps, False)  # fmt: skip
        except DivergenceError as e:
            out[int(b)] = e
    return out


def run_one(
    robot: Robot,
    controller: Any,
    q0: np.ndarray,
    qd0: np.ndarray,
    t: np.ndarray,
    options: Options,
    start: float | None = None,
    max_steps: int = MAX_STEPS,
    physical: Physical | None = None,
) -> SimulationResult:
    """One run of ``robot`` on inputs already checked by :func:`rrt_pin.simulate.simulate`.

    Args:
        robot: the robot (its joints revolute, prismatic or continuous).
        controller: a law that runs compiled (see the module), or None.
        q0: initial coordinates (nv,) [rad or m].
        qd0: initial velocities (nv,) [rad/s or m/s].
        t: output times [s], as :func:`rrt_pin.core.validate.times` returns them.
        options: as :func:`rrt_pin.simulate.options.resolve` returns them for this backend.
        start: ``time.perf_counter()`` when the caller's call began (for ``wall_time``).
        max_steps: step budget (accepted and rejected steps).
        physical: the limits and losses the joints get beyond the law
            (:func:`rrt_pin.robot.limits.physical_model`, with ``.at(...)``); None or an
            inactive one: the law's efforts alone. The efforts returned are the law's,
            saturated at the effort limits.

    Raises:
        InputError: a law that does not run compiled.
        DivergenceError: the run failed (time and coordinate named).
    """
    arrays = prepare(robot, [controller], options, physical)  # compiled before the clock starts
    start = time.perf_counter() if start is None else start
    Y0 = np.concatenate([q0, qd0])[None, :]
    y, tau, _, info, reached, _ = _run(
        robot, [controller], Y0, t, options, "trajectories", 1, SETTLING_BAND, max_steps,
        physical, arrays,
    )  # fmt: skip
    _raise(info, reached, tau, robot, options, max_steps, False)
    nv = robot.nv
    return SimulationResult(
        t=t,
        q=y[0, :, :nv],
        qd=y[0, :, nv:],
        tau=tau[0],
        n_evals=int(info[0, 2]),
        wall_time=time.perf_counter() - start,
        method=options.method.name,
        backend="compiled",
        rtol=options.rtol,
        atol=options.atol,
        step=options.step,
        q_names=robot.q_names,
        qd_names=robot.qd_names,
        tau_names=robot.effort_names,
    )


def run_batch(
    robot: Robot,
    controllers: Sequence[Any],
    q0s: np.ndarray,
    qd0s: np.ndarray,
    t: np.ndarray,
    options: Options,
    efforts: bool = True,
    *,
    keep: str = "trajectories",
    threads: int | None = None,
    band: float = SETTLING_BAND,
    max_steps: int = MAX_STEPS,
    start: float | None = None,
    failures: str = "raise",
    physical: Physical | None = None,
) -> BatchResult:
    """B variants of ``robot`` (laws and initial states), on inputs already checked.

    Args:
        robot: the robot, shared by the variants.
        controllers: B laws that run compiled (see the module); a tracking or open-loop
            law's motion is shared by the batch.
        q0s: initial coordinates (B, nv) [rad or m].
        qd0s: initial velocities (B, nv) [rad/s or m/s].
        t: output times [s].
        options: as for :func:`run_one`.
        efforts: return the efforts (they are computed in any case).
        keep: ``"trajectories"``, ``"final"`` or ``"metrics"`` (as
            :func:`rrt_pin.simulate.simulate_batch`; metrics need PD laws, their target qf).
        threads: threads sharing the variants; default every CPU this process may use, none
            with
            fewer than :data:`MIN_PER_THREAD` variants. The numbers do not depend on it.
        band: the settling band of ``keep="metrics"`` (share of |q0 − qf|).
        max_steps: step budget of each variant.
        start: ``time.perf_counter()`` when the caller's call began.
        failures: ``"raise"`` the first variant's failure, or ``"record"`` each in
            ``result.failures`` (its rows NaN) and go on.
        physical: as :func:`run_one`'s, shared by the variants.

    Raises:
        InputError: a law that does not run compiled; metrics without PD laws.
        DivergenceError: a variant failed (named, with its coordinate and time), with
            ``failures="raise"``.
    """
    # refused before anything is compiled
    if keep == "metrics" and any(type(c) is not PDGravityController for c in controllers):
        raise InputError(
            "keep='metrics' measures each variant against its controller's target qf: "
            "every controller needs one (or keep='final')"
        )
    arrays = prepare(robot, controllers, options, physical)
    start = time.perf_counter() if start is None else start
    count = q0s.shape[0]
    if threads is None:  # the slices are shared as threads finish (_in_slices)
        threads = cpus.threads_for(count, MIN_PER_THREAD, shared=True)
    else:
        threads = _threads_that_fit(threads, count)
    Y0 = np.ascontiguousarray(np.concatenate([q0s, qd0s], axis=1))
    y, tau, rows, info, reached, used = _run(
        robot, controllers, Y0, t, options, keep, threads, band, max_steps, physical, arrays
    )
    recorded = None
    if failures == "record":
        recorded = tuple(_failures(info, reached, tau, robot, options, max_steps))
        bad = info[:, 0] != codes.STATUS_OK
        y[bad], tau[bad] = np.nan, np.nan
    else:
        _raise(info, reached, tau, robot, options, max_steps, True)
    nv = robot.nv
    metrics = None
    if keep == "metrics":
        metrics = metric_columns(GROUPS, rows, robot.q_names, robot.effort_names, width=nv)
    return BatchResult(
        t=t if keep == "trajectories" else t[-1:],
        q=y[:, :, :nv],
        qd=y[:, :, nv:],
        tau=tau if efforts else None,
        n_evals=int(info[:, 2].sum()),
        wall_time=time.perf_counter() - start,
        method=options.method.name,
        backend="compiled",
        rtol=options.rtol,
        atol=options.atol,
        step=options.step,
        q_names=robot.q_names,
        qd_names=robot.qd_names,
        tau_names=robot.effort_names,
        threads=int(used),
        keep=keep,
        metrics=metrics,
        evaluations=info[:, 2].copy(),
        failures=recorded,
    )
