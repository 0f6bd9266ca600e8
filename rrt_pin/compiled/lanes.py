"""Batches of the arm's runs in machine code: arrays in, lanes on threads, failures named.

What :func:`rrt_pin.compiled.integrate.run_batch` and the sweeps hand over is arrays
(one row a variant: parameters, law, initial state, tolerances); here they are
split over threads in parts (:func:`integrate_arrays`), each thread runs the
compiled lanes (:mod:`rrt_pin.compiled._jit_batch`), and a variant's status
code becomes a :class:`~rrt_pin.core.errors.DivergenceError` (:func:`failure`).
"""

from __future__ import annotations

import functools
import itertools
import math
import threading
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from rrt_pin.compiled import ensure_compiled
from rrt_pin.core import cpus, memory
from rrt_pin.core.errors import DivergenceError
from rrt_pin.core.text import argument
from rrt_pin.robot.robot import CHAPTER_COLUMNS
from rrt_pin.simulate import codes, methods
from rrt_pin.simulate.metrics import SETTLING_BAND

_NAMES = (*CHAPTER_COLUMNS[0], *CHAPTER_COLUMNS[1])
_EFFORTS = CHAPTER_COLUMNS[3]

#: Step budget of one run (accepted plus rejected steps); machine code cannot be interrupted.
MAX_STEPS = 10_000_000


_KEEP_CODES = {
    "trajectories": codes.KEEP_TRAJECTORIES,
    "final": codes.KEEP_FINAL,
    "metrics": codes.KEEP_METRICS,
}


#: A batch's default thread count gives no thread fewer variants than this.
MIN_PER_THREAD = 16


def _raise_status(
    info: Sequence[int],
    t_fail: float,
    method: str,
    step: float | None,
    max_steps: int,
    variant: int | None,
    tau: np.ndarray | None = None,
    names: Sequence[str] = _NAMES,
    effort_names: Sequence[str] = _EFFORTS,
) -> None:
    """Raise the DivergenceError of a run's status (the chapter arm's names unless given)."""
    status, coordinate = int(info[0]), int(info[1])
    nv = len(effort_names)
    if status == codes.STATUS_OK:
        return
    if status == codes.STATUS_EFFORT_NONFINITE:
        row, k = divmod(coordinate, nv)
        where = f" (variant {variant})" if variant is not None else ""
        value = f" {float(tau[row, k])!r}" if tau is not None and row < tau.shape[0] else " nan"
        raise DivergenceError(
            float(t_fail), f"{effort_names[k]}{where}", f"the controller returned{value}"
        )
    name = names[coordinate] if 0 <= coordinate < len(names) else names[0]
    if variant is not None:
        name = f"{name} (variant {variant})"
    stiff = (  # not measured here: both causes named
        f"{method} is explicit: either the scene is stiff (large gains or damping against "
        f"small masses), which needs an implicit method ({argument('backend')} pinocchio with "
        f"{argument('method')} "
        "odepack, Radau or BDF), or the tolerances are tighter than the motion allows"
    )
    if methods.METHODS.get(method) is not None and methods.METHODS[method].implicit:
        stiff = (
            f"{method} could not keep the error within the tolerances: they are tighter "
            "than the motion allows, or its Newton iterations fail (a law whose efforts "
            "jump); loosen them, or try another method"
        )
    if step is not None:
        stiff = (
            f"the step {step:g} s is too long for this scene: a fixed explicit step must "
            "resolve its fastest mode (large gains or damping against small masses); use a "
            f"shorter {argument('step')}, or {argument('backend')} pinocchio with "
            f"{argument('method')} odepack, Radau or BDF"
        )
    verb = "stopped"
    if status == codes.STATUS_NONFINITE:
        problem = "the state or its derivative became non-finite"
        verb = "diverged"
    elif status == codes.STATUS_STEP_UNDERFLOW:
        problem = f"the step size fell below 10 ulp of t in {method}: {stiff}"
    elif status == codes.STATUS_SINGULAR_MASS:
        name = f"q{coordinate + 1}" + (f" (variant {variant})" if variant is not None else "")
        problem = (
            f"the state grew beyond any sensible range (the mass matrix lost its "
            f"significant digits in {name}): the motion blew up numerically; {stiff}"
        )
        verb = "diverged"
    elif status == codes.STATUS_MAX_STEPS:
        problem = f"{method} spent its budget of {max_steps:,} steps (this coordinate limits the step): {stiff}"
    elif status == codes.STATUS_NO_CONVERGENCE:
        problem = (
            "the implicit half kick of 'verlet' did not converge in 50 iterations; "
            f"use a step shorter than {step:.6g} s"
        )
    else:  # pragma: no cover - a status the loop does not produce
        problem = f"the compiled integrator returned status {status}"
    raise DivergenceError(float(t_fail), name, problem, verb=verb)


@functools.lru_cache(maxsize=16)
def _atol_vector(atol: float | None) -> np.ndarray:
    """The absolute tolerance per state component (read-only) [rad, m, rad/s, m/s]."""
    v = np.full(6, atol if atol is not None else 0.0)
    v.setflags(write=False)
    return v


def _threads_that_fit(threads: int, count: int) -> int:
    """An asked thread count, at most :func:`rrt_pin.core.cpus.max_threads`, cut to what fits.

    Each helper thread reserves a stack and (numba allocates in it) a malloc arena;
    the count is cut to the variants first (no thread without one).

    Raises:
        InputError: more than :func:`rrt_pin.core.cpus.max_threads`.
    """
    threads = cpus.check_threads("threads", threads)
    used = min(threads, max(1, count))
    if used == 1:
        return threads
    fit = memory.threads_that_fit(
        used,
        memory.thread_cost(),
        allocating=True,
        what=f"a batch of {count} variants",
        name="threads",
    )
    return threads if fit == used else fit


def _table(rows: Any, count: int, width: int) -> np.ndarray:
    """``count`` tuples of ``width`` numbers as a (count, width) float array, in one pass."""
    flat = itertools.chain.from_iterable(rows)
    return np.fromiter(flat, dtype=float, count=count * width).reshape(count, width)


#: Bytes a thread's lanes may hold in scratch runs (9 values an output time a lane,
#: unless only final states are kept): 32 lanes up to ~7,000 output times, fewer
#: beyond, one at 233,000 (one variant at a time kept 9 × T values).
LANE_SCRATCH_BYTES = 16 * 2**20


def lanes_for(times: int, keep: int, lanes: int) -> int:
    """The lanes of an adaptive batch with ``times`` output times: ``lanes`` or fewer.

    Fewer when their scratch runs would pass :data:`LANE_SCRATCH_BYTES` (``keep``, a
    ``KEEP_*`` code: final states need none).
    """
    if keep == codes.KEEP_FINAL:
        return lanes
    return max(1, min(lanes, LANE_SCRATCH_BYTES // (9 * 8 * times)))


def integrate_arrays(
    P: np.ndarray,
    kinds: np.ndarray,
    C: np.ndarray,
    Y0: np.ndarray,
    t: np.ndarray,
    method: str,
    rtol: float | None,
    atol: float | None,
    step: float | None,
    max_steps: int = MAX_STEPS,
    out: tuple[np.ndarray, np.ndarray] | None = None,
    *,
    keep: str = "trajectories",
    qf: np.ndarray | None = None,
    band: float = SETTLING_BAND,
    threads: int | None = 1,
    detail: bool = False,
    fill: Callable[[int, int], None] | None = None,
) -> Any:
    """Run B prepared variants in machine code; failures are reported per variant, not raised.

    Args:
        P: physical parameters (B, 15) in ``rrt_pin.dynamics.kernel.PARAM_ORDER`` [SI units].
        kinds: controller kinds (B,) of :mod:`rrt_pin.simulate.codes`.
        C: controller parameters (B, 24): kp, kd, qf and the law's 15 parameters.
        Y0: initial states (B, 6): q [rad, rad, m] then q̇.
        t: increasing output times [s] (validated by the caller).
        method: a method that runs compiled (as resolved by ``rrt_pin.simulate.options``).
        rtol: relative tolerance (adaptive methods).
        atol: absolute tolerance [rad, m, rad/s, m/s] (adaptive methods).
        step: longest step [s] (fixed-step methods).
        max_steps: step budget of each variant.
        out: buffers (≥ B, R, 6) and (≥ B, R, 3) to write the states and efforts into
            (reused across calls, they keep memory flat and warm); R = T, or 1 unless
            ``keep="trajectories"``.
        keep: ``"trajectories"``, ``"final"`` or ``"metrics"`` (see
            :func:`simulate_batch_compiled`; unchecked here).
        qf: targets (B, 3) of ``keep="metrics"`` [rad, rad, m]; default C[:, 6:9].
        band: settling band of ``keep="metrics"`` (share of |q0 − qf|).
        threads: threads sharing the batch (None: :func:`rrt_pin.core.cpus.threads_for`).
        detail: also return the metrics rows and the threads used.
        fill: ``fill(a, b)`` writes rows a..b of P, kinds and C before they are
            integrated (then these are C-contiguous arrays of float64, int64 and
            float64, and a ``qf`` given is ready at the call). Called on this thread:
            the first rows, then, while other threads integrate them, the rest — a
            batch's serial preparation overlaps its integration. None: all are ready.

    Returns:
        ``(y, tau, info, t_reached)``: states (B, R, 6), efforts (B, R, 3), per-variant
        (status, coordinate, n_evals, n_steps, n_rejected, n_out) and the time each
        variant reached (its failure time when status != OK) [s]. With ``detail``:
        ``(y, tau, metrics, info, t_reached, threads)``, ``metrics`` (B, METRIC_WIDTH)
        laid out as the ``METRIC_*`` offsets of :mod:`rrt_pin.simulate.codes` (or None).
        A failed variant's rows are left as they were.
    """
    ensure_compiled()
    from rrt_pin.compiled import _jit_batch as jit

    count = Y0.shape[0]
    code = _KEEP_CODES[keep]
    rows = t.size if code == codes.KEEP_TRAJECTORIES else 1
    if out is None:
        out_y, out_tau = np.empty((count, rows, 6)), np.empty((count, rows, 3))
    else:
        out_y, out_tau = out[0][:count, :rows], out[1][:count, :rows]
    metrics = np.empty((count if code == codes.KEEP_METRICS else 0, codes.METRIC_WIDTH))
    info = np.zeros((count, 6), dtype=np.int64)
    t_reached = np.zeros(count)
    f8 = np.float64
    Y0 = np.ascontiguousarray(Y0, dtype=f8)
    given = (P, kinds, C)
    P = np.ascontiguousarray(P, dtype=f8)
    kinds = np.ascontiguousarray(kinds, dtype=np.int64)
    C = np.ascontiguousarray(C, dtype=f8)
    if fill is not None and any(a is not b for a, b in zip(given, (P, kinds, C), strict=True)):
        raise ValueError("fill writes P, kinds, C in place: give C-contiguous float64/int64 arrays")
    if qf is None and code == codes.KEEP_METRICS:
        if fill is not None:  # the targets are C's columns 6:9, copied as they are laid out
            qf, lay_out = np.empty((count, 3)), fill

            def fill(a: int, b: int) -> None:
                lay_out(a, b)
                qf[a:b] = C[a:b, 6:9]

        else:
            qf = C[:, 6:9]
    qf = np.ascontiguousarray(qf if qf is not None else np.empty((0, 3)), dtype=f8)
    method_code = methods.get(method).code
    dt = step if step is not None else 0.0
    atol_v = _atol_vector(atol)
    rtol_v = rtol if rtol is not None else 0.0

    lanes = lanes_for(t.size, code, jit.LANES) if method_code < codes.FIXED_STEP_FROM else 1

    def run(counter: np.ndarray) -> None:
        if method_code < codes.FIXED_STEP_FROM:
            jit.integrate_lanes(
                method_code, Y0, t, atol_v, rtol_v, math.inf, max_steps, P, kinds, C, code, qf,
                float(band), out_y, out_tau, metrics, info, t_reached, lanes, counter,
            )  # fmt: skip
        else:
            jit.integrate_fixed(
                method_code, Y0, t, dt, max_steps, P, kinds, C, code, qf, float(band), out_y,
                out_tau, metrics, info, t_reached, counter,
            )  # fmt: skip

    if threads is None:  # the items are shared as threads finish (_together)
        threads = cpus.threads_for(count, MIN_PER_THREAD, shared=True)
    used = _together(run, count, threads, fill)
    if detail:
        return out_y, out_tau, (metrics if metrics.shape[0] else None), info, t_reached, used
    return out_y, out_tau, info, t_reached


#: Variants laid out before the other threads start, then at a time while they
#: integrate those before: a part's layout is short beside its integration (an order
#: of magnitude a variant), so they never wait after the first part, which is small
#: so that they start at once.
_FIRST_PART = 64


_PART = 256


def _together(
    run: Callable[[np.ndarray], None],
    count: int,
    threads: int,
    fill: Callable[[int, int], None] | None = None,
) -> int:
    """``run(counter)`` on up to ``threads`` threads that share the items 0..count.

    Every thread's ``run`` takes its items from one counter (an int64 array: [next
    item, items ready], see ``_take`` of :mod:`rrt_pin.compiled._jit_batch`), one at
    a time, until none is left: a thread slowed by other work on its core leaves
    more to the others. With ``fill``, this thread lays the items out part by part
    (``fill(a, b)``), raising the count of those ready as the others run them, then
    joins them. Returns the threads used.
    """
    threads = max(1, min(threads, count))
    counter = np.array([0, 0 if fill is not None else count], dtype=np.int64)
    if threads == 1:
        if fill is not None:
            fill(0, count)
            counter[1] = count
        run(counter)
        return 1
    started = threading.Event()

    def helper() -> None:
        started.set()
        run(counter)

    done = 0
    if fill is not None:
        done = min(count, _FIRST_PART)
        fill(0, done)
        counter[1] = done
    helpers = [_pool(threads - 1).submit(helper) for _ in range(threads - 1)]
    try:
        if fill is not None:
            # Let a helper take the GIL and enter the machine code (which releases it)
            # before laying out the rest: else it waits for the GIL's switch interval.
            started.wait()
            while done < count:
                end = min(count, done + _PART)
                fill(done, end)
                counter[1] = done = end
    except BaseException:
        counter[0] = count  # the helpers stop taking variants
        for h in helpers:
            h.result()
        raise
    run(counter)
    for h in helpers:
        h.result()
    return threads


_POOL: ThreadPoolExecutor | None = None
_POOL_SIZE = 0


def _pool(size: int) -> ThreadPoolExecutor:
    """The batches' helper threads (at least ``size``), kept across calls."""
    global _POOL, _POOL_SIZE
    if _POOL is None or _POOL_SIZE < size:
        if _POOL is not None:
            _POOL.shutdown(wait=False)
        _POOL = ThreadPoolExecutor(max_workers=size, thread_name_prefix="rrt-pin-batch")
        _POOL_SIZE = size
    return _POOL


#: Slices a thread takes at a time in :func:`_in_slices`: enough that a thread slowed
#: by another process's work on its core hands the rest to the others, few enough
#: that the calls (a few microseconds each) do not count.
_SLICES_PER_THREAD = 8


def _in_slices(run: Callable[[int, int], None], count: int, threads: int) -> int:
    """Call ``run(a, b)`` over slices covering range(count), on up to ``threads`` threads.

    Threads take the next slice when done with theirs (a shared counter), so the
    slices of a thread slowed by other work go to the others. Returns the threads used.
    """
    threads = max(1, min(threads, count))
    if threads == 1:
        run(0, count)
        return 1
    size = max(1, -(-count // (threads * _SLICES_PER_THREAD)))
    edges = list(range(0, count, size)) + [count]
    taken = itertools.count()  # next() is atomic under the GIL: each slice runs once

    def worker() -> None:
        while (i := next(taken)) < len(edges) - 1:
            run(edges[i], edges[i + 1])

    helpers = [_pool(threads - 1).submit(worker) for _ in range(threads - 1)]
    worker()
    for h in helpers:
        h.result()
    return threads


def failure(
    info: Sequence[int], t_fail: float, method: str, step: float | None, max_steps: int = MAX_STEPS
) -> DivergenceError | None:
    """The DivergenceError a variant's status stands for, or None when it succeeded."""
    try:
        _raise_status(info, t_fail, method, step, max_steps, None)
    except DivergenceError as e:
        return e
    return None
