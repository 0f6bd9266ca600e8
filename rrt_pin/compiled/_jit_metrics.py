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
from numba import float64, types

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

__all__ = ["metrics", "run", "variant_metrics"]

_r1 = types.Array(float64, 1, "A", readonly=True)
_r2 = types.Array(float64, 2, "C", readonly=True)
_r3 = types.Array(float64, 3, "A", readonly=True)
_w2 = float64[:, ::1]
_a2 = types.Array(float64, 2, "A", readonly=True)


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


@jit(types.void(_r1, _a2, _a2, _a2, _r1, float64, float64[::1]))
def variant_metrics(t, q, qd, tau, qf, band, out):
    """One run's metrics into ``out`` (METRIC_WIDTH,): q, qd, tau (T, 3) sampled at t (T,), target qf (3,).

    One pass over the samples, the three joints side by side (a row of q, qd and
    tau is read once); the same operations in the same order as a pass per joint.
    Compiled once for every caller (any layout of q, qd, tau: columns of stored runs,
    transposed rows of a scratch run), not inlined into each.
    """
    T = q.shape[0]
    f0, f1, f2 = qf[0], qf[1], qf[2]
    a0, a1, a2 = q[0, 0], q[0, 1], q[0, 2]
    s0, s1, s2 = abs(a0 - f0), abs(a1 - f1), abs(a2 - f2)
    if s0 == 0.0 or s1 == 0.0 or s2 == 0.0:  # starts on target: scale by the largest distance
        z0, z1, z2 = s0 == 0.0, s1 == 0.0, s2 == 0.0
        for i in range(T):
            if z0:
                s0 = max(s0, abs(q[i, 0] - f0))
            if z1:
                s1 = max(s1, abs(q[i, 1] - f1))
            if z2:
                s2 = max(s2, abs(q[i, 2] - f2))
    h0, h1, h2 = band * s0, band * s1, band * s2
    last0 = last1 = last2 = -1
    far0 = far1 = far2 = 0.0
    top0 = top1 = top2 = -1.0
    when0 = when1 = when2 = 0
    total = 0.0
    before = 0.0
    for i in range(T):
        x0, x1, x2 = q[i, 0], q[i, 1], q[i, 2]
        if abs(x0 - f0) > h0:
            last0 = i
        if abs(x1 - f1) > h1:
            last1 = i
        if abs(x2 - f2) > h2:
            last2 = i
        far0 = max(far0, abs(x0 - a0))
        far1 = max(far1, abs(x1 - a1))
        far2 = max(far2, abs(x2 - a2))
        e0, e1, e2 = tau[i, 0], tau[i, 1], tau[i, 2]
        m0, m1, m2 = abs(e0), abs(e1), abs(e2)
        if m0 > top0:
            top0 = m0
            when0 = i
        if m1 > top1:
            top1 = m1
            when1 = i
        if m2 > top2:
            top2 = m2
            when2 = i
        power = abs(e0 * qd[i, 0]) + abs(e1 * qd[i, 1]) + abs(e2 * qd[i, 2])
        if i > 0:
            total += 0.5 * (power + before) * (t[i] - t[i - 1])
        before = power
    _joint(out, 0, t, abs(q[T - 1, 0] - f0), last0, top0, when0, far0)
    _joint(out, 1, t, abs(q[T - 1, 1] - f1), last1, top1, when1, far1)
    _joint(out, 2, t, abs(q[T - 1, 2] - f2), last2, top2, when2, far2)
    out[METRIC_ENERGY] = total


@jit(types.void(_r1, _r3, _r3, _r3, _r2, float64, _w2))
def metrics(t, q, qd, tau, qf, band, out):  # noqa: ANN001, ANN201
    """Fill ``out`` (B, METRIC_WIDTH) from runs (B, T, 3) sampled at t (T,), targets qf (B, 3)."""
    for b in range(q.shape[0]):
        variant_metrics(t, q[b], qd[b], tau[b], qf[b], band, out[b])


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
