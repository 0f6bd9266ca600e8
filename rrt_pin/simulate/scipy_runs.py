"""Adaptive integrators through scipy: ODEPACK's LSODA (odeint), solve_ivp, and a batched LSODA.

A failed run is rerun with checks (:func:`diagnose`) so that the error says when
and in which coordinate it failed; no NaN is ever returned.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from rrt_pin import methods
from rrt_pin.errors import DivergenceError
from rrt_pin.integrators import blame

__all__ = ["Counted", "diagnose", "first_order", "lsoda_batch", "run_odeint", "run_solve_ivp"]

#: Internal steps odeint may take between two output times.
ODEINT_MXSTEP = 50_000
#: Right-hand-side evaluations a solve_ivp method may spend before it is stopped.
MAX_EVALS = 2_000_000


class _TooMuchWork(Exception):
    pass


class _NonFinite(Exception):
    def __init__(self, t: float, index: int) -> None:
        super().__init__(t, index)
        self.t, self.index = t, index


class _Watch:
    """A right-hand side f(t, y) that checks its input and output.

    Records the last (t, y, f) and raises _NonFinite at the first non-finite
    state or derivative.
    """

    def __init__(self, f: Callable[[float, np.ndarray], np.ndarray]) -> None:
        self.f = f
        self.calls = 0
        self.last: tuple[float, np.ndarray, np.ndarray] | None = None

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, y), counted."""
        self.calls += 1
        if self.calls > MAX_EVALS:
            raise _TooMuchWork(t)
        size = np.abs(np.nan_to_num(y))
        if not np.isfinite(y).all():
            raise _NonFinite(t, int(np.argmax(blame(y, size))))
        dy = self.f(t, y)
        if not np.isfinite(dy).all():
            raise _NonFinite(t, int(np.argmax(blame(dy, size))))
        self.last = (t, np.array(y), np.array(dy))
        return dy


def _fastest(watch: _Watch, rtol: float, atol: float) -> int:
    """Index of the coordinate changing fastest relative to its error weight."""
    if watch.last is None:
        return 0
    _, y, dy = watch.last
    return int(np.argmax(np.abs(dy) / (atol + rtol * np.abs(y))))


def first_order(acc: Callable[[float, np.ndarray, np.ndarray], np.ndarray], n: int):
    """f(t, y) = (v, a(t, q, v)) of the first-order system in y = (q, v); a fresh array each call."""

    def f(t: float, y: np.ndarray) -> np.ndarray:
        v = y[n:]
        return np.concatenate((v, acc(t, y[:n], v)))

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
    options: dict[str, Any] = {"jac": jac} if implicit and jac is not None else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            sol = solve_ivp(
                f, (t[0], t[-1]), y0, method=method, t_eval=t, rtol=rtol, atol=atol, **options
            )
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as e:
            # e.g. an implicit method's LU of a non-finite Jacobian
            return np.empty((0, y0.size)), f"{type(e).__name__}: {e}", False, 0
        except _TooMuchWork:
            return np.empty((0, y0.size)), f"more than {MAX_EVALS} evaluations", False, 0
    ok = sol.status == 0 and sol.y.shape[1] == t.size and bool(np.isfinite(sol.y).all())
    return sol.y.T, sol.message, ok, int(sol.njev)


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
) -> DivergenceError:
    """Rerun a failed integration with checks, to say when and where it failed."""
    watch = _Watch(f)

    def label(index: int) -> str:
        if width is None:
            return names[index]
        return f"{names[index % width]} (variant {index // width})"

    try:
        if method == "odepack":
            _, info, _ = run_odeint(watch, y0, t, rtol, atol, band)
            message = str(info["message"])
            imxer = int(info.get("imxer", -1))
            index = imxer - 1 if imxer > 0 else _fastest(watch, rtol, atol)
        else:
            _, message, _, _ = run_solve_ivp(watch, y0, t, method, rtol, atol, jac)
            index = _fastest(watch, rtol, atol)
    except _NonFinite as e:
        return DivergenceError(e.t, label(e.index), "the state or its derivative became non-finite")
    except _TooMuchWork:
        index, message = _fastest(watch, rtol, atol), f"more than {MAX_EVALS} evaluations"
    t_fail = watch.last[0] if watch.last is not None else float(t[0])
    return DivergenceError(t_fail, label(index), f"the integrator {method} stopped: {message}")


class Counted:
    """Counts the calls of f(t, y) and stops the run after MAX_EVALS of them."""

    def __init__(self, f: Callable[[float, np.ndarray], np.ndarray]) -> None:
        self.f, self.calls = f, 0

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        """f(t, y), counted."""
        self.calls += 1
        if self.calls > MAX_EVALS:
            raise _TooMuchWork(t)
        return self.f(t, y)


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
            raise DivergenceError(
                solver.t,
                label(int(np.argmax(np.abs(solver.y) / (atol + rtol * np.abs(solver.y))))),
                f"the integrator odepack stopped: {message}",
            )
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
