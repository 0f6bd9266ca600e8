"""The per-variant metrics of :func:`rrt_pin.metrics.batch_metrics` in one pass, in machine code.

Imported only when numba is installed; :func:`rrt_pin.metrics.batch_metrics`
(numpy) is the reference the tests compare it with. :func:`variant_metrics`
is the one definition: :func:`metrics` applies it to stored runs (B, T, n), and
the compiled batch (``keep="metrics"`` of
:func:`rrt_pin.compiled.integrate.simulate_batch_compiled`) to each variant's
samples as soon as they are computed, so that no trajectory is kept.

A row of metrics is laid out as the ``METRIC_*`` offsets of
:mod:`rrt_pin.compiled.codes` say (:data:`~rrt_pin.compiled.codes.METRIC_WIDTH` values).
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import float64, types
from numba.extending import intrinsic

from rrt_pin.compiled._jit import jit, warn_problems
from rrt_pin.compiled.codes import (
    METRIC_ENERGY,
    METRIC_EXCURSION,
    METRIC_FINAL,
    METRIC_PEAK,
    METRIC_PEAK_TIME,
    METRIC_SETTLE,
    METRIC_WIDTH,
)

__all__ = ["as_rows", "metrics", "run", "variant_metrics"]

_r1 = types.Array(float64, 1, "A", readonly=True)
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
    """Joint k's columns of ``out`` from its pass: last sample outside the band, peak, excursion."""
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


@jit(types.void(_r1, _rows, _r1, float64, float64[::1]))
def variant_metrics(t, rows, qf, band, out):
    """One run's metrics into ``out`` (METRIC_WIDTH,) from its rows (9, T): q, q̇, τ at t (T,).

    ``qf`` (3,) is the target, ``band`` the settling band (share of |q0 − qf|).

    A pass per joint and quantity over contiguous rows, each a loop LLVM vectorizes:
    the last sample outside the band is the largest index that is (a max of integers),
    the largest |q − q(t0)| and |τ| are maxima of non-negative doubles taken on their
    bits (which order as the values do, and a nan as the largest, as numpy's max
    does), the time of the peak its first sample. The energy's trapezoids are summed
    in four interleaved partial sums (numpy's pairwise sum is another order; they
    agree to round-off). Compiled once for every caller, not inlined into each.
    """
    T = rows.shape[1]
    for k in range(3):
        x, e = rows[k], rows[6 + k]
        f, a = qf[k], rows[k, 0]
        s = abs(a - f)
        if s == 0.0:  # starts on target: scale by the largest distance
            for i in range(T):
                s = max(s, abs(x[i] - f))
        h = band * s
        last = -1
        far = 0
        for i in range(T):
            last = max(last, i if abs(x[i] - f) > h else -1)
            far = max(far, _bits(abs(x[i] - a)))
        top = 0
        for i in range(T):
            top = max(top, _bits(abs(e[i])))
        when = T - 1
        for i in range(T):
            when = min(when, i if _bits(abs(e[i])) == top else T - 1)
        _joint(out, k, t, abs(x[T - 1] - f), last, _double(top), when, _double(far))
    qd1, qd2, qd3, e1, e2, e3 = rows[3], rows[4], rows[5], rows[6], rows[7], rows[8]
    s0 = s1 = s2 = s3 = 0.0
    before = abs(e1[0] * qd1[0]) + abs(e2[0] * qd2[0]) + abs(e3[0] * qd3[0])
    i = 1
    while i + 4 <= T:
        p0 = abs(e1[i] * qd1[i]) + abs(e2[i] * qd2[i]) + abs(e3[i] * qd3[i])
        p1 = abs(e1[i + 1] * qd1[i + 1]) + abs(e2[i + 1] * qd2[i + 1]) + abs(e3[i + 1] * qd3[i + 1])
        p2 = abs(e1[i + 2] * qd1[i + 2]) + abs(e2[i + 2] * qd2[i + 2]) + abs(e3[i + 2] * qd3[i + 2])
        p3 = abs(e1[i + 3] * qd1[i + 3]) + abs(e2[i + 3] * qd2[i + 3]) + abs(e3[i + 3] * qd3[i + 3])
        s0 += 0.5 * (p0 + before) * (t[i] - t[i - 1])
        s1 += 0.5 * (p1 + p0) * (t[i + 1] - t[i])
        s2 += 0.5 * (p2 + p1) * (t[i + 2] - t[i + 1])
        s3 += 0.5 * (p3 + p2) * (t[i + 3] - t[i + 2])
        before = p3
        i += 4
    while i < T:
        power = abs(e1[i] * qd1[i]) + abs(e2[i] * qd2[i]) + abs(e3[i] * qd3[i])
        s0 += 0.5 * (power + before) * (t[i] - t[i - 1])
        before = power
        i += 1
    out[METRIC_ENERGY] = (s0 + s1) + (s2 + s3)


@jit(None, inline=True)
def as_rows(y, tau, rows, n):
    """rows[0:6, :n] = y[:n].T, rows[6:9, :n] = tau[:n].T: a run (T, 6), (T, 3) by rows (9, T)."""
    for m in range(n):
        for i in range(6):
            rows[i, m] = y[m, i]
        for k in range(3):
            rows[6 + k, m] = tau[m, k]


@jit(types.void(_r1, _r3, _r3, _r3, _r2, float64, _w2))
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
        np.asarray(t, f8), np.asarray(q, f8), np.asarray(qd, f8), np.asarray(tau, f8),
        np.ascontiguousarray(qf, f8), float(band), out,
    )  # fmt: skip
    return out
