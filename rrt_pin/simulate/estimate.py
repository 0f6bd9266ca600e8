"""The estimate of a run's global error in q: a cheap companion run and the error's rate.

Error-controlled integrators bound the error each step makes, not the error at
the end: in a lightly damped oscillation the phase error of every step adds up,
so the global error of a run depends on the scene. :func:`attempt` measures it
with a companion run of the same method on the same backend:

* adaptive methods: at k times the run's rtol and atol (looser, so cheaper). If the
  error grows as a power of the tolerance, e(tol) ≈ C·tolᵖ, then
  |q(tol) − q(k·tol)| ≈ (kᵖ − 1)·e(tol), so e(tol) ≈ |q(tol) − q(k·tol)| / (kᵖ − 1).
  The rate p and the factor k of each method and backend are measured on the
  accuracy catalogue by ``scripts/bench/calibrate.py``
  (:data:`rrt_pin.simulate.calibration.COMPANIONS`): k is the loosest companion
  that keeps the estimate within 0.3–3× of the true error there. A run too loose
  for a looser companion (k·rtol above 1e-3) is compared with one ten times tighter
  instead (the same formula with k = 1/10);
* fixed-step methods of order p: at twice the step when each output interval
  holds an even number of steps, else at half the step; Richardson's formula
  e(h) ≈ |q(h) − q(2h)| / (2ᵖ − 1), or |q(h) − q(h/2)| / (1 − 2⁻ᵖ).

The estimate is the max over the output times, per coordinate [rad or m].
Its cost is the companion run's (its share for each method on the accuracy
catalogue: docs/benchmarks.md; ``estimate_error=False`` skips it).
"""

from __future__ import annotations

import logging
import time
import warnings
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core.errors import DivergenceError, InputError
from rrt_pin.simulate import calibration
from rrt_pin.simulate.extremes import deviation
from rrt_pin.simulate.methods import ACCURACY, calibration_key
from rrt_pin.simulate.results import ErrorEstimate

if TYPE_CHECKING:
    from rrt_pin.simulate.options import Options
    from rrt_pin.simulate.results import BatchResult, SimulationResult

__all__ = [
    "LOOSEST",
    "TIGHTER",
    "AccuracyWarning",
    "EstimateWarning",
    "attempt",
    "companion",
    "estimate",
    "requested_accuracy",
    "warn_if_exceeded",
]

#: How much tighter the companion's tolerances are when it cannot be looser.
TIGHTER = 10.0
#: The loosest rtol a companion runs at (the calibration's loosest rung).
LOOSEST = 1e-3
#: The tightest relative tolerance a companion uses (100 machine epsilons, as SciPy).
RTOL_FLOOR = 100 * float(np.finfo(float).eps)

_logger = logging.getLogger("rrt_pin")


class AccuracyWarning(UserWarning):
    """A run's estimated global error exceeds the accuracy it asked for."""


class EstimateWarning(AccuracyWarning):
    """A run's error estimate could not be made: its comparison run failed.

    The run itself is returned, with ``estimate=None`` and the reason in
    ``estimate_failure``; a subclass of :class:`AccuracyWarning` (the accuracy of
    the run is unknown), so filtering that filters both.
    """


def requested_accuracy(rtol: float | None, atol: float | None) -> float:
    """The accuracy a run at explicit tolerances asks for: max(ACCURACY, rtol, atol) [rad or m].

    (Runs resolved by :func:`rrt_pin.simulate.options.resolve` carry theirs in
    ``options.accuracy``.)
    """
    return max(ACCURACY, rtol or 0.0, atol or 0.0)


def companion(options: Options, t: np.ndarray | None = None) -> tuple[Options, float] | None:
    """The companion run's options and its ratio k to the run (tolerance or step), or None.

    Args:
        options: the run's.
        t: its output times [s] (fixed-step methods: whether twice the step fits).

    None when no companion is possible (an rtol at its floor that cannot be looser).
    """
    m = options.method
    if m.adaptive:
        rtol, atol = float(options.rtol), float(options.atol)  # type: ignore[arg-type]
        key = calibration_key(options.backend, m.name)
        k, _ = calibration.COMPANIONS.get(key, (1.0 / TIGHTER, 1.0))
        if k > 1.0 and rtol * k > LOOSEST:
            k = 1.0 / TIGHTER
        if k < 1.0:
            tight = max(rtol * k, RTOL_FLOOR)
            if tight >= rtol:
                return None
            k = tight / rtol
        return replace(options, rtol=rtol * k, atol=atol * k), k
    step = float(options.step)  # type: ignore[arg-type]
    if t is not None and t.size >= 2:
        with np.errstate(over="ignore"):
            per = np.ceil(np.diff(t) / step * (1.0 - 1e-12))
        if np.all(per % 2 == 0):
            return replace(options, step=2.0 * step), 2.0
    return replace(options, step=step / 2.0), 0.5


def second_options(options: Options) -> Options | None:
    """The companion's options (see :func:`companion`), or None."""
    found = companion(options)
    return None if found is None else found[0]


def rate(options: Options) -> float:
    """The rate p of error ∝ tolᵖ (adaptive methods, measured) or stepᵖ (fixed-step: the order)."""
    m = options.method
    if m.adaptive:
        return calibration.COMPANIONS.get(calibration_key(options.backend, m.name), (0.1, 1.0))[1]
    return float(m.order or 1)


def _how(options: Options) -> str:
    m = options.method
    if m.adaptive:
        return f"{m.name} at rtol {options.rtol:.3g}, atol {options.atol:.3g}"
    return f"{m.name} at step {options.step:.6g} s, Richardson (order {m.order})"


def estimate(
    result: SimulationResult | BatchResult,
    options: Options,
    rerun: Callable[[Options], SimulationResult | BatchResult],
) -> ErrorEstimate | None:
    """The estimated global error of ``result``, or None (see :func:`attempt` for why)."""
    return attempt(result, options, rerun)[0]


def attempt(
    result: SimulationResult | BatchResult,
    options: Options,
    rerun: Callable[[Options], SimulationResult | BatchResult],
    stacklevel: int = 3,
) -> tuple[ErrorEstimate | None, str | None]:
    """The estimated global error of ``result`` from ``rerun`` of its companion (:func:`companion`).

    Args:
        result: the run (q of shape (N, nv), or (B, N, nv) for a batch).
        options: the options it ran with.
        rerun: runs the same problem with other options.
        stacklevel: of the warning, as :func:`warnings.warn`'s.

    Returns:
        (the estimate, None), or (None, why there is none). No estimate when the
        tolerance is at its floor already (said on the ``rrt_pin`` logger, at INFO),
        or when the comparison run failed: the first run is returned as it is (it
        passed every check of its own), with an :class:`EstimateWarning` and the
        reason in ``result.estimate_failure``, e.g. ``"the comparison run (rk4 at
        step 0.005 s, Richardson (order 4)) failed: simulation diverged at …"``.
    """
    found = companion(options, np.asarray(result.t))
    if found is None:
        why = f"rtol={options.rtol:.3g} cannot be tightened (it is at the method's floor)"
        _logger.info("no error estimate: %s", why)
        return None, why
    tight, k = found
    start = time.perf_counter()
    try:
        other = rerun(tight)
    except (InputError, DivergenceError) as e:
        why = f"the comparison run ({_how(tight)}) failed: {e}"
        _logger.warning("no error estimate: %s", why)  # the CLI's line on stderr
        warnings.warn(f"no error estimate: {why}", EstimateWarning, stacklevel=stacklevel)
        return None, why
    wall_time = time.perf_counter() - start
    factor = 1.0 / abs(k ** rate(options) - 1.0)
    q, q2 = np.asarray(result.q), np.asarray(other.q)  # (N, nv) or (B, N, nv)
    batch = q.ndim == 3
    if q.shape[-2]:
        per = deviation(q, q2) if batch else deviation(q[None], q2[None])[0]
        per *= factor
    else:
        per = np.zeros(q.shape[:-2] + q.shape[-1:])
    return ErrorEstimate(
        q=per.max(axis=0) if batch else per,
        accuracy=float(
            getattr(options, "accuracy", requested_accuracy(options.rtol, options.atol))
        ),
        how=_how(tight),
        n_evals=int(other.n_evals),
        wall_time=wall_time,
        variants=per if batch else None,
    ), None


def describe(estimate: ErrorEstimate, names: tuple[str, ...]) -> str:
    """One line: the estimate, the worst coordinate, the accuracy asked for."""
    k = int(np.argmax(estimate.q)) if estimate.q.size else 0
    worst = f" ({names[k]})" if names else ""
    return (
        f"estimated global error of q {estimate.max:.2g}{worst} exceeds the accuracy "
        f"asked for, {estimate.accuracy:.2g} [rad or m]"
    )


def warn_if_exceeded(result: SimulationResult | BatchResult, stacklevel: int = 3) -> None:
    """Warn (:class:`AccuracyWarning`) when the result's estimate exceeds its accuracy."""
    est = result.estimate
    if est is None or not est.exceeded:
        return
    tol = (
        f"rtol {result.rtol:g}, atol {result.atol:g}: tighten them"
        if result.rtol is not None
        else f"step {result.step:g} s: shorten it"
    )
    warnings.warn(
        f"{describe(est, result.q_names)}; method {result.method}, {tol}",
        AccuracyWarning,
        stacklevel=stacklevel,
    )
