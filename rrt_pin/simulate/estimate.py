"""The estimate of a run's global error in q: the same method again, ten times tighter.

Error-controlled integrators bound the error each step makes, not the error at
the end: in a lightly damped oscillation the phase error of every step adds up,
so the global error of a run depends on the scene. :func:`estimate` measures
it with a second run of the same method on the same backend:

* adaptive methods: at rtol/10 and atol/10. If the error is proportional to the
  tolerance, e(tol) ≈ C·tol, then |q(tol) − q(tol/10)| ≈ 0.9·e(tol), so
  e(tol) ≈ |q(tol) − q(tol/10)| / 0.9 (DOP853 follows this model closely;
  ODEPACK's LSODA less so, which the test on the catalogue bounds);
* fixed-step methods of order p: at half the step, and Richardson's formula
  e(h) ≈ |q(h) − q(h/2)| / (1 − 2⁻ᵖ).

The estimate is the max over the output times, per coordinate [rad or m].
It costs the second run (its share for each method on the accuracy catalogue:
docs/benchmarks.md; ``estimate_error=False`` skips it).
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
from rrt_pin.simulate.methods import ACCURACY
from rrt_pin.simulate.results import ErrorEstimate

if TYPE_CHECKING:
    from rrt_pin.simulate.options import Options
    from rrt_pin.simulate.results import BatchResult, SimulationResult

__all__ = [
    "TIGHTER",
    "AccuracyWarning",
    "EstimateWarning",
    "attempt",
    "estimate",
    "requested_accuracy",
    "warn_if_exceeded",
]

#: How much tighter the second run's tolerances are.
TIGHTER = 10.0
#: The tightest relative tolerance a second run uses (100 machine epsilons, as SciPy).
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
    """The global accuracy a run asks for: max(ACCURACY, rtol, atol) [rad or m].

    The defaults are chosen to keep :data:`rrt_pin.simulate.methods.ACCURACY` (1e-8) on the
    accuracy catalogue; a run at looser tolerances asks for no better than them.
    """
    return max(ACCURACY, rtol or 0.0, atol or 0.0)


def second_options(options: Options) -> Options | None:
    """The options of the comparison run, or None when no tighter run is possible."""
    if options.method.adaptive:
        rtol = max(float(options.rtol) / TIGHTER, RTOL_FLOOR)  # type: ignore[arg-type]
        if rtol >= float(options.rtol):  # type: ignore[arg-type]
            return None
        return replace(options, rtol=rtol, atol=float(options.atol) / TIGHTER)  # type: ignore[arg-type]
    return replace(options, step=float(options.step) / 2.0)  # type: ignore[arg-type]


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
    """The estimated global error of ``result`` from ``rerun(second_options(options))``.

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
    tight = second_options(options)
    if tight is None:
        why = f"rtol={options.rtol:.3g} cannot be tightened (it is at the method's floor)"
        _logger.info("no error estimate: %s", why)
        return None, why
    start = time.perf_counter()
    try:
        other = rerun(tight)
    except (InputError, DivergenceError) as e:
        why = f"the comparison run ({_how(tight)}) failed: {e}"
        _logger.warning("no error estimate: %s", why)  # the CLI's line on stderr
        warnings.warn(f"no error estimate: {why}", EstimateWarning, stacklevel=stacklevel)
        return None, why
    wall_time = time.perf_counter() - start
    method = options.method
    if method.adaptive:
        factor = 1.0 / (1.0 - 1.0 / TIGHTER)
    else:
        factor = 1.0 / (1.0 - 2.0 ** -(method.order or 1))
    diff = np.abs(np.asarray(result.q) - np.asarray(other.q))  # (N, nv) or (B, N, nv)
    per = (
        factor * diff.max(axis=-2)
        if diff.shape[-2]
        else np.zeros(diff.shape[:-2] + diff.shape[-1:])
    )
    batch = per.ndim == 2
    return ErrorEstimate(
        q=per.max(axis=0) if batch else per,
        accuracy=requested_accuracy(options.rtol, options.atol),
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
