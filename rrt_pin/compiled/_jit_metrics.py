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


@jit(None, inline=True)
def variant_metrics(t, q, qd, tau, qf, band, out):
    """One run's metrics into ``out`` (METRIC_WIDTH,): q, qd, tau (T, 3) sampled at t (T,), target qf (3,)."""
    T = q.shape[0]
    for k in range(3):
        q0 = q[0, k]
        f = qf[k]
        scale = abs(q0 - f)
        if scale == 0.0:
            for i in range(T):
                scale = max(scale, abs(q[i, k] - f))
        threshold = band * scale
        last = -1
        far = 0.0
        top = -1.0
        when = 0
        for i in range(T):
            x = q[i, k]
            if abs(x - f) > threshold:
                last = i
            far = max(far, abs(x - q0))
            m = abs(tau[i, k])
            if m > top:
                top = m
                when = i
        out[METRIC_FINAL + k] = abs(q[T - 1, k] - f)
        if last == -1:
            out[METRIC_SETTLE + k] = t[0]
        elif last == T - 1:
            out[METRIC_SETTLE + k] = math.nan
        else:
            out[METRIC_SETTLE + k] = t[last + 1]
        out[METRIC_PEAK + k] = top
        out[METRIC_PEAK_TIME + k] = t[when]
        out[METRIC_EXCURSION + k] = far
    total = 0.0
    before = 0.0
    for i in range(T):
        power = abs(tau[i, 0] * qd[i, 0]) + abs(tau[i, 1] * qd[i, 1]) + abs(tau[i, 2] * qd[i, 2])
        if i > 0:
            total += 0.5 * (power + before) * (t[i] - t[i - 1])
        before = power
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
