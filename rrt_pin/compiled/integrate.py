"""Whole simulations of the RRT arm in machine code: ``simulate(..., backend="compiled")``.

The integration loop, the controller, the dense output at the requested times
and the efforts at those times all run in compiled code (see
:mod:`rrt_pin.compiled._jit_integrators`); Python only validates the inputs
and wraps the arrays. Results are the same types as :mod:`rrt_pin.simulate`'s
(:class:`~rrt_pin.simulate.SimulationResult`, :class:`~rrt_pin.simulate.BatchResult`).

Methods (those of :data:`rrt_pin.simulate.methods.METHODS` whose backends include ``compiled``):

* ``DOP853`` (default) and ``RK45``: SciPy's ``solve_ivp`` algorithms step for
  step (same initial step, error norm, step-size control and dense output), so
  with the same tolerances they take the same steps as the Pinocchio backend's
  ``solve_ivp`` runs, up to round-off;
* ``symplectic_euler``, ``rk4``, ``verlet``: the formulas of
  :mod:`rrt_pin.simulate.integrators`, at most ``step`` [s] per step, landing on every
  output time.

Controllers: :func:`~rrt_pin.simulate.control.chapter_controller` (eq. (31), with its own
parameters, which may differ from the plant's), :func:`~rrt_pin.simulate.control.pd_gravity_controller`
on the RRT arm built from the plant's parameters, or None (no effort: passive
motion). When eq. (31)'s g, m2, m3, L2 are the plant's, its gravity terms are
exactly the plant's G(q) and are taken from the kernel's evaluation (one sine
and cosine per evaluation, as the Pinocchio backend folds them); the efforts
reported are eq. (31) as printed. A batch runs its variants one after the
other, each with its own step control, so every variant is held to the
tolerance, and each may have its own parameters (masses, lengths, inertias),
gains, target and initial state.

Failures never return NaN: a non-finite state, a step size below 10 ulp of t,
a singular mass matrix, a diverging Verlet half kick or an exhausted step
budget raise :class:`~rrt_pin.core.errors.DivergenceError` with the time and the
coordinate, as reported by the compiled loop.
"""

from __future__ import annotations

import functools
import math
import operator
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.compiled import ensure_compiled
from rrt_pin.compiled.dynamics import param_array
from rrt_pin.compiled.lanes import (
    MAX_STEPS,
    MIN_PER_THREAD,
    _atol_vector,
    _raise_status,
    _table,
    _threads_that_fit,
    failure,
    integrate_arrays,
)
from rrt_pin.core import validate
from rrt_pin.core.errors import InputError
from rrt_pin.core.identity import IdentityCache
from rrt_pin.core.text import argument
from rrt_pin.dynamics.kernel import PARAM_ORDER
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import CHAPTER_COLUMNS
from rrt_pin.simulate import codes, methods
from rrt_pin.simulate.control import ChapterController, PDGravityController
from rrt_pin.simulate.metrics import GROUPS, SETTLING_BAND, metric_columns
from rrt_pin.simulate.options import resolve
from rrt_pin.simulate.results import KEEPS, BatchResult, SimulationResult

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.simulate.options import Options

__all__ = [
    "DEFAULT_METHOD",
    "MAX_STEPS",
    "MIN_PER_THREAD",
    "check_model",
    "failure",
    "integrate_arrays",
    "run_batch",
    "run_one",
    "simulate_batch_compiled",
    "simulate_compiled",
]

#: Method used when none is given.
DEFAULT_METHOD = "DOP853"
#: SciPy's floor on the relative tolerance (100 machine epsilons): tighter is refused.
RTOL_FLOOR = methods.RTOL_FLOOR
_EFFORTS = CHAPTER_COLUMNS[3]


# --------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------
def _rows(name: str, value: Any, unit: str, batch: bool) -> np.ndarray:
    if batch:
        return validate.states(name, value, 3, unit)
    return validate.vector(name, value, 3, unit)


@functools.lru_cache(maxsize=16)
def _rrt_model(params: Params) -> pin.Model:

    from rrt_pin.robot.model import rrt_model

    return rrt_model(params)


def _law(controller: Any, plant: Params) -> tuple[int, np.ndarray, np.ndarray]:
    """(kind, c, p): ``controller`` and ``plant`` compiled; kept for chapter laws and None.

    A :class:`~rrt_pin.simulate.control.ChapterController` is immutable (frozen, compared by
    identity) and so is :class:`~rrt_pin.robot.params.Params`, so their arrays are kept
    (read-only) in :data:`_LAWS`, by identity (no hashing of parameters); a pd_gravity
    controller's model is a mutable Pinocchio object and is checked at every call.
    """
    kept = _LAWS.get(controller, plant)
    if kept is not None:
        return kept
    p = param_array(plant)
    kind, c = _controller_arrays(controller, plant, p)
    if controller is None or type(controller) is ChapterController:
        c.setflags(write=False)
        _LAWS.put(controller, plant, value=(kind, c, p))
    return kind, c, p


#: The arrays of the last few (immutable) chapter laws and plants, by their identities.
_LAWS: IdentityCache[tuple[int, np.ndarray, np.ndarray]] = IdentityCache(256)


def _controller_arrays(controller: Any, plant: Params, p: np.ndarray) -> tuple[int, np.ndarray]:
    """(kind, c): the compiled form of ``controller`` on the arm of ``plant`` (parameters ``p``)."""
    c = np.zeros(24)
    if controller is None:
        return codes.KIND_NONE, c

    # The exact classes only: a subclass may override efforts() with another law.
    if type(controller) is ChapterController:
        c[:3], c[3:6], c[6:9] = controller.kp, controller.kd, controller.qf
        law = controller.params
        if (law.g, law.m2, law.m3, law.L2) == (plant.g, plant.m2, plant.m3, plant.L2):
            # Eq. (31)'s gravity terms are then exactly the plant's G(q) (they depend
            # on g, m2, m3, L2 only): fold them into the kernel's evaluation.
            c[9:] = p
            return codes.KIND_CHAPTER_FOLDED, c
        c[9:] = param_array(controller.params)
        return codes.KIND_CHAPTER, c
    if type(controller) is PDGravityController:
        if controller.nv != 3 or not controller.compensates_gravity_of(_rrt_model(plant)):
            raise InputError(
                "backend 'compiled' compensates the gravity of the RRT arm only: the "
                "pd_gravity controller's model must be rrt_model(params) of the simulated arm"
            )
        c[:3], c[3:6], c[6:9] = controller.kp, controller.kd, controller.qf
        c[9:] = p
        return codes.KIND_PD_PLANT_GRAVITY, c
    raise InputError(
        "backend 'compiled' runs chapter_controller(...), pd_gravity_controller(...) on the "
        f"RRT arm, or None (no effort), not {type(controller).__name__}; use backend "
        "'pinocchio' for other controllers"
    )


def _params(params: Any) -> Params:
    if not isinstance(params, Params):
        raise InputError(f"params must be a Params, not {type(params).__name__}")
    return params


def _arm_method(method: methods.Method) -> None:
    """Refuse a method the arm's kernel does not run (Adams's and BDF run generated code only)."""
    if method.code in (codes.METHOD_ADAMS, codes.METHOD_BDF, codes.METHOD_DOP853_RKC):
        raise InputError(
            f"{argument('method')} {method.name} runs the generated integrators of other "
            f"robots, not the chapter's arm's own kernel: use {argument('method')} DOP853 or "
            f"RK45 on {argument('backend')} compiled"
        )


def check_model(model: Any, params: Params) -> None:
    """Refuse a ``model`` that is not the RRT arm of ``params`` (the kernel's arm)."""
    if model is not None and not bool(model == _rrt_model(params)):
        raise InputError(
            "backend 'compiled' simulates rrt_model(params); the model given differs "
            "(another URDF, or other parameters): use backend 'pinocchio'"
        )


# --------------------------------------------------------------------------
# Status codes of the compiled loop -> DivergenceError
# --------------------------------------------------------------------------


# --------------------------------------------------------------------------
# Public API
# --------------------------------------------------------------------------
def simulate_compiled(
    params: Params,
    controller: Any,
    q0: Any,
    qd0: Any,
    t_eval: Any,
    method: str | None = DEFAULT_METHOD,
    rtol: float | None = None,
    atol: float | None = None,
    step: float | None = None,
    *,
    model: pin.Model | None = None,
    max_steps: int = MAX_STEPS,
    start: float | None = None,
) -> SimulationResult:
    """Simulate the RRT arm of ``params`` under ``controller``, sampled at ``t_eval``.

    Args:
        params: the arm (the plant) [SI units].
        controller: ``chapter_controller(...)``, ``pd_gravity_controller(rrt_model(params), ...)``
            or None (no effort).
        q0: initial positions (3,) [rad, rad, m].
        qd0: initial velocities (3,) [rad/s, rad/s, m/s].
        t_eval: increasing output times [s]; the run starts at ``t_eval[0]``.
        method: a method of :data:`rrt_pin.simulate.methods.METHODS` that runs compiled (default DOP853).
        rtol: relative tolerance of DOP853/RK45 (default that of
            :func:`rrt_pin.simulate.simulate`, 1e-10).
        atol: absolute tolerance [rad, m, rad/s, m/s] (default 1e-12).
        step: longest step of the fixed-step methods [s]; default the shortest
            interval of ``t_eval``.
        model: if given, checked to be ``rrt_model(params)`` (the arm this backend simulates).
        max_steps: step budget (accepted and rejected steps).
        start: ``time.perf_counter()`` when the caller's call began (for ``wall_time``).

    Returns:
        States and applied efforts at ``t_eval``; ``wall_time`` excludes the
        one-time compilation (see :func:`rrt_pin.compiled.compile_report`).

    Raises:
        InputError: a bad parameter set, state, time grid, method, option or controller.
        DivergenceError: the compiled loop reported a failure (time, coordinate).
        ImportError: numba is not installed.
    """
    from rrt_pin.compiled import machine_code

    machine_code()  # loaded (or compiled) before the run's clock starts
    start = time.perf_counter() if start is None else start
    params = _params(params)
    check_model(model, params)
    q0 = _rows("q0", q0, "rad, rad, m", False)
    qd0 = _rows("qd0", qd0, "rad/s, rad/s, m/s", False)
    t = validate.times(t_eval)

    options = resolve(t, backend="compiled", method=method, rtol=rtol, atol=atol, step=step)
    return run_one(params, controller, q0, qd0, t, options, _max_steps(max_steps), start)


def run_one(
    params: Params,
    controller: Any,
    q0: np.ndarray,
    qd0: np.ndarray,
    t: np.ndarray,
    options: Options,
    max_steps: int = MAX_STEPS,
    start: float | None = None,
) -> SimulationResult:
    """:func:`simulate_compiled` on inputs already checked (by it, or by :func:`rrt_pin.simulate.simulate`).

    Args:
        params: the arm (a :class:`~rrt_pin.robot.params.Params`) [SI units].
        controller: as :func:`simulate_compiled`'s (checked here: its kind and arm).
        q0: initial positions (3,), finite [rad, rad, m].
        qd0: initial velocities (3,), finite [rad/s, rad/s, m/s].
        t: output times, as :func:`rrt_pin.core.validate.times` returns them [s].
        options: as :func:`rrt_pin.simulate.options.resolve` returns them for this backend.
        max_steps: step budget (accepted and rejected steps).
        start: ``time.perf_counter()`` when the caller's call began (for ``wall_time``).
    """
    start = time.perf_counter() if start is None else start
    _arm_method(options.method)
    kind, c, p = _law(controller, params)
    from rrt_pin.compiled import machine_code

    jit = machine_code()  # built ahead of time, or the JIT's
    y0 = np.empty(6)
    y0[:3] = q0
    y0[3:] = qd0
    out_y = np.empty((t.size, 6))
    out_tau = np.empty((t.size, 3))
    method = options.method
    rtol, atol, step = options.rtol, options.atol, options.step
    status, coordinate, n_evals, _, _, _, t_reached = jit.integrate(
        method.code,
        y0,
        t,
        step if step is not None else 0.0,
        _atol_vector(atol),
        rtol if rtol is not None else 0.0,
        math.inf,
        max_steps,
        p,
        kind,
        c,
        out_y,
        out_tau,
    )
    if status != codes.STATUS_OK:
        _raise_status((status, coordinate), t_reached, method.name, step, max_steps, None, out_tau)
    return SimulationResult(
        t=t,
        q=out_y[:, :3],
        qd=out_y[:, 3:],
        tau=out_tau,
        n_evals=int(n_evals),
        wall_time=time.perf_counter() - start,
        method=method.name,
        backend="compiled",
        rtol=rtol,
        atol=atol,
        step=step,
    )


def _max_steps(value: Any) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise InputError(f"max_steps={value!r} must be an integer >= 1")
    return int(value)


def _per_variant(name: str, value: Any, count: int) -> list[Any]:
    if isinstance(value, (list, tuple)):
        if len(value) != count:
            raise InputError(f"{len(value)} {name} for {count} variants")
        return list(value)
    return [value] * count


def simulate_batch_compiled(
    params: Params | Sequence[Params],
    controllers: Any,
    q0s: Any,
    qd0s: Any,
    t_eval: Any,
    method: str | None = DEFAULT_METHOD,
    rtol: float | None = None,
    atol: float | None = None,
    step: float | None = None,
    efforts: bool = True,
    *,
    keep: str = "trajectories",
    threads: int | None = None,
    band: float = SETTLING_BAND,
    max_steps: int = MAX_STEPS,
    start: float | None = None,
) -> BatchResult:
    """Simulate B variants of the RRT arm in machine code, on one or more threads.

    Args:
        params: one :class:`~rrt_pin.robot.params.Params` for all variants, or one per
            variant (masses, lengths, inertias, g may differ) [SI units].
        controllers: one controller for all, or a list of B (see
            :func:`simulate_compiled`; a pd_gravity controller must be built on
            its own variant's ``rrt_model``).
        q0s: initial positions (B, 3) [rad, rad, m].
        qd0s: initial velocities (B, 3) [rad/s, rad/s, m/s].
        t_eval: increasing output times [s], shared by the variants.
        method: a method of :data:`rrt_pin.simulate.methods.METHODS` that runs compiled (default DOP853).
        rtol: relative tolerance (default 1e-10; each variant has its own steps).
        atol: absolute tolerance [rad, m, rad/s, m/s] (default 1e-12).
        step: longest step of the fixed-step methods [s].
        efforts: return the applied efforts (they are computed in any case).
        keep: what is kept of each variant (one of :data:`rrt_pin.simulate.results.KEEPS`):

            * ``"trajectories"`` (default): states and efforts at every output time,
              shapes (B, T, 3);
            * ``"final"``: the states and efforts at the last output time only,
              shapes (B, 1, 3) (``result.t`` is that one time). DOP853 and RK45 skip
              the dense output altogether (the same steps; the state is the last
              step's end, equal to the trajectories' last row to round-off);
            * ``"metrics"``: the final states as ``"final"``, and ``result.metrics``:
              the per-variant columns of :func:`rrt_pin.simulate.metrics.batch_metrics`
              (final_error [rad or m], settling_time [s], peak_effort [N·m or N] and
              peak_effort_time [s], excursion [rad or m], control_energy [J]) of the
              samples at every output time, computed as they are made and not kept.
              The target is each controller's ``qf`` (a controller is required).

        threads: threads sharing the batch's variants (the loop releases the GIL;
            each takes the next variant when a lane falls free); default
            :func:`rrt_pin.core.cpus.threads_for` (the CPUs free now, no thread with fewer
            than :data:`MIN_PER_THREAD` variants). The results
            do not depend on it, bit for bit. At most :func:`rrt_pin.core.cpus.max_threads`
            (256); a count whose stacks and malloc arenas do not fit in the address
            space left (``ulimit -v``) is cut to one that does, with a warning
            (:mod:`rrt_pin.core.memory`).
        band: the settling band of ``keep="metrics"`` (share of |q0 − qf|).
        max_steps: step budget of each variant.
        start: ``time.perf_counter()`` when the caller's call began (for ``wall_time``).

    Returns:
        A :class:`~rrt_pin.simulate.BatchResult`: q, qd, tau of shape (B, T, 3)
        (or (B, 1, 3)); ``n_evals`` is the total over the variants; ``threads``
        the threads used; ``keep`` and ``metrics`` as asked.

    Raises:
        InputError: bad shapes, values, controllers or options, an unknown ``keep``,
            ``keep="metrics"`` without a controller.
        DivergenceError: a variant failed (the message names it and the coordinate).
    """
    ensure_compiled()
    start = time.perf_counter() if start is None else start
    q0s = _rows("q0s", q0s, "rad, rad, m", True)
    qd0s = _rows("qd0s", qd0s, "rad/s, rad/s, m/s", True)
    if q0s.shape[0] != qd0s.shape[0]:
        raise InputError(f"q0s has {q0s.shape[0]} rows but qd0s has {qd0s.shape[0]}")
    t = validate.times(t_eval)

    options = resolve(t, backend="compiled", method=method, rtol=rtol, atol=atol, step=step)
    return run_batch(
        params, controllers, q0s, qd0s, t, options, efforts, keep=keep,
        threads=threads, band=band, max_steps=max_steps, start=start,
    )  # fmt: skip


def run_batch(
    params: Params | Sequence[Params],
    controllers: Any,
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
) -> BatchResult:
    """:func:`simulate_batch_compiled` on states, times and options already checked.

    ``q0s`` and ``qd0s`` as :func:`rrt_pin.core.validate.states` returns them (B, 3), ``t``
    as :func:`rrt_pin.core.validate.times`, ``options`` as :func:`rrt_pin.simulate.options.resolve`
    for this backend; the other arguments are checked here. ``failures``: ``"raise"``
    the first variant's failure, or ``"record"`` each variant's in ``result.failures``
    (its rows NaN) and keep the others.
    """
    start = time.perf_counter() if start is None else start
    _arm_method(options.method)
    count = q0s.shape[0]
    keep = validate.choice("keep", keep, KEEPS)
    band = validate.real("band", band, positive=True)
    if threads is not None:
        threads = _threads_that_fit(validate.positive_int("threads", threads), count)
    max_steps = _max_steps(max_steps)
    plants = [_params(v) for v in _per_variant("params", params, count)]
    laws = _per_variant("controllers", controllers, count)
    if keep == "metrics" and any(law is None for law in laws):
        raise InputError(
            "keep='metrics' measures each variant against its controller's target qf: "
            "give every variant a controller (or keep='final')"
        )
    # The variants' arrays, filled by integrate_arrays as it goes (the first rows
    # integrate on other threads while the rest are laid out).
    P, kinds, C = np.empty((count, 15)), np.empty(count, dtype=np.int64), np.empty((count, 24))
    fill = functools.partial(_fill_rows, plants, laws, P, kinds, C)
    Y0 = np.concatenate((q0s, qd0s), axis=1)
    method, rtol, atol, step = options.method.name, options.rtol, options.atol, options.step
    y, tau, metrics, info, t_reached, used = integrate_arrays(
        P, kinds, C, Y0, t, method, rtol, atol, step, max_steps,
        keep=keep, band=band, threads=threads, detail=True, fill=fill,
    )  # fmt: skip
    failed = np.flatnonzero(info[:, 0] != codes.STATUS_OK)
    recorded = None
    if failures == "record":
        recorded = [None] * count
        for b in failed:
            recorded[b] = failure(info[b], t_reached[b], method, step, max_steps)
        y[failed], tau[failed] = np.nan, np.nan
        if metrics is not None:
            metrics[failed] = np.nan
    elif failed.size:
        b = int(failed[0])
        _raise_status(info[b], t_reached[b], method, step, max_steps, b, tau[b])
    columns = None
    if metrics is not None:
        columns = metric_columns(GROUPS, metrics, CHAPTER_COLUMNS[0], _EFFORTS)
    return BatchResult(
        t=t if keep == "trajectories" else t[-1:],
        q=y[:, :, :3],
        qd=y[:, :, 3:],
        tau=tau if efforts else None,
        n_evals=int(info[:, 2].sum()),
        wall_time=time.perf_counter() - start,
        method=method,
        backend="compiled",
        rtol=rtol,
        atol=atol,
        step=step,
        threads=used,
        keep=keep,
        metrics=columns,
        evaluations=info[:, 2].copy(),
        failures=None if recorded is None else tuple(recorded),
    )


def _fill_rows(
    plants: list[Params], laws: list[Any], P: np.ndarray, kinds: np.ndarray, C: np.ndarray,
    a: int, b: int,
) -> None:  # fmt: skip
    """Rows a..b of P (B, 15), kinds (B,) and C (B, 24), as :func:`_law` makes them one by one.

    Chapter laws are laid out column by column (the batch's preparation is serial
    work, done while other threads integrate the rows before; see
    :func:`integrate_arrays`); other laws go through :func:`_law` one by one.
    """
    plants, laws, count = plants[a:b], laws[a:b], b - a
    if not all(type(law) is ChapterController for law in laws):
        for i, (plant, law) in enumerate(zip(plants, laws, strict=True)):
            try:
                kinds[a + i], C[a + i], P[a + i] = _law(law, plant)
            except InputError as e:
                raise InputError(f"controllers[{a + i}]: {e}") from e
        return
    rows: dict[int, int] = {}
    unique: list[Params] = []
    which: list[int] = []
    unfolded: list[int] = []  # eq. (31) with another arm's gravity terms (see _law)
    for i, (plant, law) in enumerate(zip(plants, laws, strict=True)):
        k = rows.get(id(plant))
        if k is None:
            k = rows[id(plant)] = len(unique)
            unique.append(plant)
        which.append(k)
        own = law.params
        if own is not plant and (own.g, own.m2, own.m3, own.L2) != (
            plant.g, plant.m2, plant.m3, plant.L2,
        ):  # fmt: skip
            unfolded.append(i)
    table = _table(map(operator.attrgetter(*PARAM_ORDER), unique), len(unique), 15)
    P[a:b] = table if len(unique) == count else table[which]
    c = C[a:b]
    c[:, 0:3] = _table((law.kp for law in laws), count, 3)
    c[:, 3:6] = _table((law.kd for law in laws), count, 3)
    c[:, 6:9] = _table((law.qf for law in laws), count, 3)
    c[:, 9:] = P[a:b]
    kinds[a:b] = codes.KIND_CHAPTER_FOLDED
    for i in unfolded:
        kinds[a + i] = codes.KIND_CHAPTER
        c[i, 9:] = param_array(laws[i].params)


def _batch_arrays(plants: list[Params], laws: list[Any]) -> tuple[np.ndarray, ...]:
    """(P (B, 15), kinds (B,), C (B, 24)) of the variants, as :func:`_law` makes them one by one."""
    count = len(laws)
    P, kinds, C = np.empty((count, 15)), np.empty(count, dtype=np.int64), np.empty((count, 24))
    _fill_rows(plants, laws, P, kinds, C, 0, count)
    return P, kinds, C
