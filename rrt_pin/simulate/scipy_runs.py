"""Adaptive integrators through scipy: ODEPACK's LSODA (odeint), solve_ivp, and a batched LSODA.

A failed run is rerun with checks (:func:`diagnose`) so that the error says when
and in which coordinate it failed; no NaN is ever returned.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from rrt_pin.core.errors import DivergenceError
from rrt_pin.core.text import argument
from rrt_pin.simulate import methods

__all__ = [
    "Counted",
    "diagnose",
    "eval_budget",
    "first_order",
    "lsoda_batch",
    "run_odeint",
    "run_solve_ivp",
    "too_much_work",
]

#: Internal steps odeint may take between two output times.
ODEINT_MXSTEP = 50_000
#: Right-hand-side evaluations a solve_ivp method may spend: EVALS_BASE plus
#: EVALS_PER_SECOND per simulated second, at most MAX_EVALS. A non-stiff run of the
#: catalogue needs under 1,000 a simulated second; an explicit method on a stiff
#: scene would need millions (minutes), so it is stopped early and told to use an
#: implicit method.
EVALS_BASE = 100_000
EVALS_PER_SECOND = 10_000
MAX_EVALS = 2_000_000


def eval_budget(span: float) -> int:
    """The evaluations a run over ``span`` [s] of simulated time may spend."""
    return int(min(MAX_EVALS, EVALS_BASE + EVALS_PER_SECOND * abs(span)))


class _TooMuchWork(Exception):
    pass


class _RaisedByRhs(Exception):
    """An error raised by the right-hand side or the Jacobian (a law's, or a check's).

    Carried through the solver so that it is raised as it is, never reported as the
    integrator's failure (scipy turns some errors of its callbacks into a status).
    """

    def __init__(self, error: Exception) -> None:
        super().__init__(error)
        self.error = error


def _guarded(g: Callable[..., Any] | None) -> Callable[..., Any] | None:
    if g is None:
        return None

    def h(*args: Any) -> Any:
        try:
            return g(*args)
        except (_TooMuchWork, _NonFinite):
            raise
        except Exception as e:
            raise _RaisedByRhs(e) from e

    return h


class _NonFinite(Exception):
    def __init__(self, t: float, index: int) -> None:
        super().__init__(t, index)
        self.t, self.index = t, index


class _Watch:
    """A right-hand side f(t, y) that checks its input and output.

    Records the last (t, y, f) and raises _NonFinite at the first non-finite
    state or derivative.
    """

    def __init__(
        self, f: Callable[[float, np.ndarray], np.ndarray], budget: int = MAX_EVALS
    ) -> None:
        self.f = f
        self.calls = 0
        self.budget = budget
        self.last: tuple[float, np.ndarray, np.ndarray] | None = None

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, y), counted."""
        self.calls += 1
        if self.calls > self.budget:
            raise _TooMuchWork(t)
        if not np.isfinite(y).all():
            raise _NonFinite(t, _blamed(y, y))
        dy = self.f(t, y)
        if not np.isfinite(dy).all():
            raise _NonFinite(t, _blamed(dy, y))
        self.last = (t, np.array(y), np.array(dy))
        return dy


def _blamed(values: np.ndarray, y: np.ndarray) -> int:
    """The entry of ``values`` to name for a blow-up at state ``y`` (only on failure)."""
    from rrt_pin.simulate.integrators import blame  # the fixed-step module, loaded when needed

    return int(np.argmax(blame(values, np.abs(np.nan_to_num(y)))))


def _fastest(watch: _Watch, rtol: float, atol: float) -> int:
    """Index of the coordinate changing fastest relative to its error weight."""
    if watch.last is None:
        return 0
    _, y, dy = watch.last
    with np.errstate(all="ignore"):  # overflowing ratios still rank
        return int(np.nanargmax(np.nan_to_num(np.abs(dy) / (atol + rtol * np.abs(y)), nan=0.0)))


def first_order(acc: Callable[[float, np.ndarray, np.ndarray], np.ndarray], n: int):
    """f(t, y) = (v, a(t, q, v)) of the first-order system in y = (q, v); a fresh array each call."""

    def f(t: float, y: np.ndarray) -> np.ndarray:
        q, v = y[:n], y[n:]
        q.flags.writeable = v.flags.writeable = False  # a law reads them, never writes
        return np.concatenate((v, acc(t, q, v)))

    return f


def run_odeint(
    f: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    rtol: float,
    atol: float,
    band: int | None = None,
    lean: Callable[[np.ndarray, float], np.ndarray] | None = None,
) -> tuple[np.ndarray, dict[str, Any], bool]:
    """ODEPACK's LSODA through ``odeint``: (states, odeint's info, whether it succeeded)."""
    from rrt_pin.simulate._odepack import odeint

    func = lean if lean is not None else (lambda y, s: f(s, y))
    Y, info = odeint(func, y0, t, rtol=rtol, atol=atol, mxstep=ODEINT_MXSTEP, ml=band, mu=band)
    ok = info["message"] == "Integration successful." and bool(np.isfinite(Y).all())
    return Y, info, ok


def run_solve_ivp(
    f: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    method: str,
    rtol: float,
    atol: float,
    jac: Callable[[float, np.ndarray], np.ndarray] | None,
) -> tuple[np.ndarray, str, bool, int]:
    """``solve_ivp`` at the output times: (states, message, success, Jacobian evaluations)."""
    from scipy.integrate import solve_ivp

    implicit = methods.get(method).implicit
    options: dict[str, Any] = {"jac": _guarded(jac)} if implicit and jac is not None else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            sol = solve_ivp(
                _guarded(f), (t[0], t[-1]), y0, method=method, t_eval=t, rtol=rtol, atol=atol,
                **options,
            )  # fmt: skip
        except _RaisedByRhs as e:  # the law's (or a check's) own error, as it is
            raise e.error from None
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as e:
            # e.g. an implicit method's LU of a non-finite Jacobian
            return np.empty((0, y0.size)), f"{type(e).__name__}: {e}", False, 0
        except _TooMuchWork:
            return np.empty((0, y0.size)), "evaluation budget spent", False, 0
    # a run that fails before the first output time leaves y an empty list
    y = np.asarray(sol.y, dtype=float).reshape(y0.size, -1)
    ok = sol.status == 0 and y.shape[1] == t.size and bool(np.isfinite(y).all())
    return y.T, sol.message, ok, int(sol.njev)


def _ARGUMENTS() -> dict[str, str]:  # noqa: N802 - the templates' fields
    """The tolerances' names as the caller spells them (``rtol`` or ``--rtol``)."""
    return {"rtol": argument("rtol"), "atol": argument("atol")}


#: What LSODA's failures mean for a user, by the words of its status message. LSODA
#: switches to BDF by itself when the motion is stiff: stiffness is not what exhausts it.
_LSODA_CAUSES = {
    "Excess work done": "more than {mxstep:,} internal steps between two output times (LSODA "
    "switches to BDF on stiff motion by itself): the tolerances are too tight for this "
    "motion, or it is not smooth there (a discontinuous law?); loosen rtol/atol",
    "Excess accuracy requested": "the tolerances are tighter than float64 can meet there "
    "(loosen {rtol}/{atol})",
    "Illegal input": "the first step would be shorter than float64 can resolve: the "
    "derivatives at the start are too large (|d{where}/dt| = {size:.2g}) or the tolerances "
    "too tight",
    "Repeated error test failures": "the step size collapsed: the motion is not smooth there "
    "(a discontinuous controller?) or the tolerances are too tight",
    "Repeated convergence failures": "the step size collapsed: the corrector does not "
    "converge (a discontinuous or very stiff right-hand side)",
    "Error weight became zero": "a coordinate reached exactly zero with {atol} 0: give {atol} > 0",
}


def _cause(
    method: str, message: str, watch: _Watch, rtol: float, atol: float, names: Sequence[str]
) -> str:
    """A user's reading of an integrator's failure message (the message itself last)."""
    index = _fastest(watch, rtol, atol)
    size = float(np.abs(watch.last[2][index])) if watch.last is not None else float("nan")
    for words, cause in _LSODA_CAUSES.items():
        if words in message:
            where = names[index % len(names)]
            what = cause.format(mxstep=ODEINT_MXSTEP, size=size, where=where, **_ARGUMENTS())
            return f"{what} [{method}: {message.rstrip('.')}]"
    return f"the integrator {method} stopped: {message}"


def too_much_work(
    method: str,
    counted: Counted,
    span: float,
    names: Sequence[str],
    rtol: float,
    atol: float,
    label: Callable[[int], str] | None = None,
) -> DivergenceError:
    """The error of a run stopped after its evaluation budget (without running it again)."""
    t_stop = float(counted.last[0]) if counted.last is not None else float("nan")
    watch = _Watch(counted.f)
    watch.last = counted.last
    index = _fastest(watch, rtol, atol)
    where = label(index) if label is not None else names[index]
    spent = (
        f"{method} gave up after {counted.budget:,} evaluations ({EVALS_PER_SECOND:,} per "
        f"simulated second of {span:g} s, plus {EVALS_BASE:,}), fastest-changing "
        f"coordinate {where}"
    )
    return DivergenceError(t_stop, where, f"{spent}: {_work_hint(method, counted)}", verb="stopped")


#: Right-hand-side evaluations per step of the explicit methods, and the reach of their
#: stability region along the negative real axis (h·|λ| beyond it is unstable).
_EXPLICIT = {"RK45": (6, 3.3), "DOP853": (12, 6.0)}
#: An explicit run whose mean step times the fastest rate exceeds this fraction of its
#: stability reach is limited by stability, i.e. stiff.
STIFF_FRACTION = 0.3


def _work_hint(method: str, counted: Counted) -> str:
    """Why a run spent its budget, by the kind of method (stiffness only when measured)."""
    if method not in _EXPLICIT:  # implicit methods and odepack cope with stiffness
        return (
            f"{method} handles stiff motion, so the tolerances are too tight for this motion, "
            "or it is not smooth (a discontinuous law?), or its Jacobian is poor "
            "(jacobian='finite-difference', or a law's inexact jacobian()); loosen rtol/atol"
        )
    stages, reach = _EXPLICIT[method]
    rate = _fastest_rate(counted)
    steps = max(1, counted.calls // stages)
    mean_step = abs(_elapsed(counted)) / steps
    if rate is not None and mean_step * rate > STIFF_FRACTION * reach:
        return (
            f"the motion is stiff (fastest rate {rate:.3g} 1/s measured, so {method}'s "
            f"steps of about {mean_step:.3g} s are at its stability limit); use an implicit "
            "method: Radau, BDF or odepack (looser tolerances do not lift a stability limit)"
        )
    measured = (
        f" (fastest rate {rate:.3g} 1/s: steps of {mean_step:.3g} s are stable)"
        if (rate is not None)
        else ""
    )
    return (
        f"{method}'s steps are limited by accuracy, not stability{measured}: the tolerances "
        "are too tight for this motion or it is not smooth (a discontinuous law?); loosen "
        "rtol/atol"
    )


def _elapsed(counted: Counted) -> float:
    """Simulated time covered before the budget ran out [s]."""
    if counted.last is None or counted.first is None:
        return 0.0
    return float(counted.last[0]) - float(counted.first)


def _fastest_rate(counted: Counted) -> float | None:
    """The spectral radius [1/s] of ∂f/∂y at the last state, by finite differences.

    A batch's Jacobian is block diagonal (each variant its own block of ``counted.width``):
    all blocks are perturbed at once, one column each, and the largest radius returned.
    """
    if counted.last is None:
        return None
    t, y, dy = counted.last
    y = np.array(y, dtype=float)
    dy = np.array(dy, dtype=float)
    width = counted.width or y.size
    blocks = y.size // width
    J = np.empty((blocks, width, width))
    with np.errstate(all="ignore"):
        for j in range(width):
            h = 1e-7 * max(1.0, float(np.abs(y[j::width]).max()))
            yp = y.copy()
            yp[j::width] += h
            col = (np.asarray(counted.f(t, yp), dtype=float) - dy) / h
            J[:, :, j] = col.reshape(blocks, width)
        if not np.isfinite(J).all():
            return None
        try:
            return float(np.abs(np.linalg.eigvals(J)).max())
        except np.linalg.LinAlgError:  # pragma: no cover
            return None


def diagnose(
    method: str,
    f: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    rtol: float,
    atol: float,
    names: Sequence[str],
    message: str,
    band: int | None = None,
    jac: Callable[[float, np.ndarray], np.ndarray] | None = None,
    width: int | None = None,
    states: np.ndarray | None = None,
) -> DivergenceError:
    """Rerun a failed integration with checks, to say when, where and why it failed.

    ``states`` (the failed run's output, if any) names the first non-finite
    output when the checked rerun itself goes through.
    """
    watch = _Watch(f, eval_budget(float(t[-1] - t[0])))

    def label(index: int) -> str:
        if width is None:
            return names[index]
        return f"{names[index % width]} (variant {index // width})"

    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            if method == "odepack":
                _, info, ok = run_odeint(watch, y0, t, rtol, atol, band)
                message = str(info["message"])
                imxer = int(info.get("imxer", -1))
                index = imxer - 1 if imxer > 0 and not ok else _fastest(watch, rtol, atol)
            else:
                _, message, ok, _ = run_solve_ivp(watch, y0, t, method, rtol, atol, jac)
                index = _fastest(watch, rtol, atol)
        except _NonFinite as e:
            return DivergenceError(
                e.t, label(e.index), "the state or its derivative became non-finite"
            )
        except _TooMuchWork:
            counted = Counted(f, watch.budget, width)
            counted.calls, counted.last, counted.first = watch.calls, watch.last, float(t[0])
            return too_much_work(method, counted, float(t[-1] - t[0]), names, rtol, atol, label)
    if ok and states is not None:  # the checked rerun went through: the first run's output
        bad = np.argwhere(~np.isfinite(states))
        if bad.size:
            row, col = (int(x) for x in bad[0])
            return DivergenceError(
                float(t[row]), label(col), "the interpolated output became non-finite"
            )
    t_fail = watch.last[0] if watch.last is not None else float(t[0])
    if ok:  # pragma: no cover - a failure that does not repeat
        return DivergenceError(
            t_fail, label(index), f"{method} failed once and not when rerun", verb="stopped"
        )
    if "successful" in message:  # it said so, yet its output is not finite: its own arithmetic
        gap = float(np.diff(t).min())
        return DivergenceError(
            t_fail, label(index),
            f"{method} returned non-finite states although it reported success, while every "
            f"derivative it asked for was finite: its step arithmetic breaks down on an output "
            f"interval of {gap:.3g} s; use longer output intervals, or another method",
            verb="stopped",
        )  # fmt: skip
    cause = _cause(method, message, watch, rtol, atol, names)
    return DivergenceError(t_fail, label(index), cause, verb="stopped")


class Counted:
    """Counts the calls of f(t, y) and stops the run after ``budget`` of them.

    Keeps the last (t, y, f) (references, no copies), so that a run stopped for
    too much work is reported without running it again.
    """

    def __init__(
        self,
        f: Callable[[float, np.ndarray], np.ndarray],
        budget: int = MAX_EVALS,
        width: int | None = None,
    ) -> None:
        self.f, self.calls, self.budget, self.width = f, 0, budget, width
        self.first: float | None = None
        self.last: tuple[float, np.ndarray, np.ndarray] | None = None

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, y), counted."""
        self.calls += 1
        if self.calls > self.budget:
            raise _TooMuchWork(t)
        dy = self.f(t, y)
        if self.first is None:
            self.first = t
        self.last = (t, y, dy)
        return dy

    def too_much_work(self) -> bool:
        """Whether the run was stopped for spending its whole budget."""
        return self.calls > self.budget


#: Columns per matrix product of the batch interpolation: small products stay on one
#: thread in OpenBLAS, whose worker threads only slow things down on a busy machine.
_PRODUCT_SIZE = 200_000


def _product(powers: np.ndarray, yh: np.ndarray, out: np.ndarray) -> None:
    """Set ``out = powers @ yh.T`` in column blocks of at most _PRODUCT_SIZE multiply-adds."""
    k, order = powers.shape
    width = max(1, _PRODUCT_SIZE // (k * order))
    for s in range(0, yh.shape[0], width):
        np.matmul(powers, yh[s : s + width].T, out=out[:, s : s + width])


#: Output rows handed to the batch's efforts at a time (a few MB: still cached).
_ROW_BLOCK = 32


def lsoda_batch(
    f: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    rtol: float,
    atol: float,
    band: int,
    label: Callable[[int], str],
    on_rows: Callable[[np.ndarray, slice], None] | None = None,
) -> tuple[np.ndarray, int]:
    """LSODA step by step, interpolating from its Nordsieck history; states (T, len(y0)).

    ``on_rows(Y, rows)`` is called on each new block of about ``_ROW_BLOCK`` output
    rows while it is still in the cache.
    """
    from scipy.integrate import LSODA

    solver = LSODA(f, t[0], y0, t[-1], rtol=rtol, atol=atol, lband=band, uband=band)
    Y = np.empty((t.size, y0.size))
    Y[0] = y0
    k, done = 1, 0
    while k < t.size:
        message = solver.step()
        bad = np.flatnonzero(~np.isfinite(solver.y))
        if bad.size:
            raise DivergenceError(solver.t, label(int(bad[0])), "the state became non-finite")
        if solver.status == "failed":
            explained = next((c for w, c in _LSODA_CAUSES.items() if w in str(message)), None)
            with np.errstate(all="ignore"):
                index = int(np.argmax(np.abs(solver.y) / (atol + rtol * np.abs(solver.y))))
            if explained:
                size = float(np.abs(solver.y[index]))
                what = explained.format(
                    mxstep=ODEINT_MXSTEP, size=size, where=label(index), **_ARGUMENTS()
                )
                problem = f"{what} [odepack: {str(message).rstrip('.')}]"
            else:
                problem = f"odepack stopped: {message}"
            raise DivergenceError(solver.t, label(index), problem, verb="stopped")
        j = int(np.searchsorted(t, solver.t, side="right"))
        if j > k:
            dense = solver.dense_output()
            yh = getattr(dense, "yh", None)
            if yh is not None:  # y(t) = Σ_i yh[:, i]·((t − t_n)/h)^i, all outputs at once
                powers = ((t[k:j] - dense.t) / dense.h)[:, None] ** dense.p
                _product(powers, yh, Y[k:j])
            else:  # pragma: no cover - another scipy's dense output
                Y[k:j] = dense(t[k:j]).T
            if on_rows is not None and (j - done >= _ROW_BLOCK or j == t.size):
                on_rows(Y, slice(done, j))
                done = j
            k = j
    return Y, int(solver.nfev)
