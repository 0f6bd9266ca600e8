"""The per-variant metrics of :func:`rrt_pin.simulate.metrics.batch_metrics` in one pass, in machine code.

Imported only when numba is installed; :func:`rrt_pin.simulate.metrics.batch_metrics`
(numpy) is the reference the tests compare it with. :func:`variant_metrics`
is the one definition: :func:`metrics` applies it to stored runs (B, T, n), and
the compiled batch (``keep="metrics"`` of
:func:`rrt_pin.compiled.integrate.simulate_batch_compiled`) to each variant's
samples as soon as they are computed, so that no trajectory is kept.

A row of metrics is laid out as the ``METRIC_*`` offsets of
:mod:`rrt_pin.simulate.codes` say (:data:`~rrt_pin.simulate.codes.METRIC_WIDTH` values).
The ``limits`` group is 0 (its peak demand the peak effort): the chapter's arm states no binding limit
(:func:`rrt_pin.robot.limits.physical_model`).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import float64, types
from numba.extending import intrinsic

from rrt_pin.compiled._jit import jit, warn_problems, wide_vectors
from rrt_pin.simulate.codes import (
    METRIC_DEMAND,
    METRIC_ENERGY,
    METRIC_EXCURSION,
    METRIC_FINAL,
    METRIC_LIMIT,
    METRIC_PEAK,
    METRIC_PEAK_TIME,
    METRIC_SATURATION,
    METRIC_SETTLE,
    METRIC_WIDTH,
)

__all__ = ["as_rows", "metrics", "run", "variant_metrics"]

_c1 = types.Array(float64, 1, "C", readonly=True)
_r2 = types.Array(float64, 2, "C", readonly=True)
_r3 = types.Array(float64, 3, "A", readonly=True)
_w2 = float64[:, ::1]
_rows = types.Array(float64, 2, "C", readonly=True)


@intrinsic
def _bits(typingctx, x):
    """The bits of the double ``x`` as an int64: for x >= 0 (and +nan) they order as x does."""
    sig = types.int64(x)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.IntType(64))

    return sig, codegen


@intrinsic
def _double(typingctx, n):
    """The double whose bits are the int64 ``n`` (the inverse of :func:`_bits`)."""
    sig = types.float64(n)

    def codegen(context, builder, signature, args):
        return builder.bitcast(args[0], ir.DoubleType())

    return sig, codegen


@jit(None, inline=True)
def _joint(out, k, t, final, last, top, when, far):
    """Joint k's columns of ``out`` from its pass: last sample outside the band, peak, excursion.

    Its ``limits`` columns are 0 (the arm states no binding limit), its peak demanded
    effort the peak effort (nothing saturates).
    """
    T = t.shape[0]
    out[METRIC_FINAL + k] = final
    if last == -1:
        out[METRIC_SETTLE + k] = t[0]
    elif last == T - 1:
        out[METRIC_SETTLE + k] = math.nan
    else:
        out[METRIC_SETTLE + k] = t[last + 1]
    out[METRIC_PEAK + k] = top
    out[METRIC_PEAK_TIME + k] = t[when]
    out[METRIC_EXCURSION + k] = far
    out[METRIC_LIMIT + k] = 0.0
    out[METRIC_SATURATION + k] = 0.0
    out[METRIC_DEMAND + k] = top


#: Partial sums of the energy's trapezoids (independent chains of additions).
_SUMS = 16


@jit(types.void(_c1, _rows, _c1, float64, float64[::1]))
def variant_metrics(t, rows, qf, band, out):
    """One run's metrics into ``out`` (METRIC_WIDTH,) from its rows (9, ≥ T): q, q̇, τ at t (T,).

    ``qf`` (3,) is the target, ``band`` the settling band (share of |q0 − qf|).

    One pass over the nine rows (each read from the caches once, not once per
    quantity) in a loop LLVM vectorizes: the last sample outside the band is
    the largest index that is (a max of integers), the largest |q − q(t0)| and |τ|
    are maxima of non-negative doubles taken on their bits (which order as the
    values do, and a nan as the largest, as numpy's max does), and the power
    |τ·q̇| of each sample goes to a scratch row; then the time of each peak (its
    first sample) and the energy's trapezoids, summed in 16 interleaved partial
    sums (numpy's pairwise sum is another order; they agree to round-off).
    Compiled once for every caller, not inlined into each.
    """
    wide_vectors()
    T = t.shape[0]
    x1, x2, x3, v1, v2, v3 = rows[0], rows[1], rows[2], rows[3], rows[4], rows[5]
    e1, e2, e3 = rows[6], rows[7], rows[8]
    f1, f2, f3 = qf[0], qf[1], qf[2]
    a1, a2, a3 = x1[0], x2[0], x3[0]
    s1, s2, s3 = abs(a1 - f1), abs(a2 - f2), abs(a3 - f3)
    if s1 == 0.0 or s2 == 0.0 or s3 == 0.0:  # starts on target: scale by the largest distance
        z1 = z2 = z3 = 0.0
        for i in range(T):
            z1 = max(z1, abs(x1[i] - f1))
            z2 = max(z2, abs(x2[i] - f2))
            z3 = max(z3, abs(x3[i] - f3))
        s1 = z1 if s1 == 0.0 else s1
        s2 = z2 if s2 == 0.0 else s2
        s3 = z3 if s3 == 0.0 else s3
    h1, h2, h3 = band * s1, band * s2, band * s3
    power = np.empty(T)
    last1 = last2 = last3 = -1
    far1 = far2 = far3 = 0
    top1 = top2 = top3 = 0
    for i in range(T):
        last1 = max(last1, i if abs(x1[i] - f1) > h1 else -1)
        last2 = max(last2, i if abs(x2[i] - f2) > h2 else -1)
        last3 = max(last3, i if abs(x3[i] - f3) > h3 else -1)
        far1 = max(far1, _bits(abs(x1[i] - a1)))
        far2 = max(far2, _bits(abs(x2[i] - a2)))
        far3 = max(far3, _bits(abs(x3[i] - a3)))
        top1 = max(top1, _bits(abs(e1[i])))
        top2 = max(top2, _bits(abs(e2[i])))
        top3 = max(top3, _bits(abs(e3[i])))
        power[i] = abs(e1[i] * v1[i]) + abs(e2[i] * v2[i]) + abs(e3[i] * v3[i])
    when1 = when2 = when3 = T - 1
    for i in range(T):
        when1 = min(when1, i if _bits(abs(e1[i])) == top1 else T - 1)
        when2 = min(when2, i if _bits(abs(e2[i])) == top2 else T - 1)
        when3 = min(when3, i if _bits(abs(e3[i])) == top3 else T - 1)
    _joint(out, 0, t, abs(x1[T - 1] - f1), last1, _double(top1), when1, _double(far1))
    _joint(out, 1, t, abs(x2[T - 1] - f2), last2, _double(top2), when2, _double(far2))
    _joint(out, 2, t, abs(x3[T - 1] - f3), last3, _double(top3), when3, _double(far3))
    n = T - 1  # trapezoids, in place: power[i] becomes the one of [t_i, t_i+1]
    for i in range(n):
        power[i] = 0.5 * (power[i + 1] + power[i]) * (t[i + 1] - t[i])
    sums = np.zeros(_SUMS)
    i = 0
    while i + _SUMS <= n:
        for j in range(_SUMS):
            sums[j] += power[i + j]
        i += _SUMS
    while i < n:
        sums[0] += power[i]
        i += 1
    width = _SUMS // 2
    while width >= 1:
        for j in range(width):
            sums[j] += sums[j + width]
        width //= 2
    out[METRIC_ENERGY] = sums[0]


@jit(None, inline=True)
def as_rows(y, tau, rows, n):
    """rows[0:6, :n] = y[:n].T, rows[6:9, :n] = tau[:n].T: a run (T, 6), (T, 3) by rows (9, T)."""
    for m in range(n):
        for i in range(6):
            rows[i, m] = y[m, i]
        for k in range(3):
            rows[6 + k, m] = tau[m, k]


@jit(types.void(_c1, _r3, _r3, _r3, _r2, float64, _w2))
def metrics(t, q, qd, tau, qf, band, out):  # noqa: ANN001, ANN201
    """Fill ``out`` (B, METRIC_WIDTH) from runs (B, T, 3) sampled at t (T,), targets qf (B, 3)."""
    T = t.shape[0]
    rows = np.empty((9, T))
    for b in range(q.shape[0]):
        for m in range(T):
            for k in range(3):
                rows[k, m] = q[b, m, k]
                rows[3 + k, m] = qd[b, m, k]
                rows[6 + k, m] = tau[b, m, k]
        variant_metrics(t, rows, qf[b], band, out[b])


def run(t: np.ndarray, q: np.ndarray, qd: np.ndarray, tau: np.ndarray, qf: np.ndarray, band: float):
    """The metrics (B, METRIC_WIDTH) of runs (B, T, 3) sampled at t (T,), targets qf (B, 3)."""
    warn_problems()
    f8 = np.float64
    out = np.empty((q.shape[0], METRIC_WIDTH))
    metrics(
        np.ascontiguousarray(t, f8), np.asarray(q, f8), np.asarray(qd, f8), np.asarray(tau, f8),
        np.ascontiguousarray(qf, f8), float(band), out,
    )  # fmt: skip
    return out
