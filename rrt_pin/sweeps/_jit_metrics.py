"""The per-variant metrics of :func:`rrt_pin.metrics.batch_metrics` in one pass, in machine code.

Imported only when numba is installed; :func:`rrt_pin.metrics.batch_metrics`
(numpy) is the reference the tests compare it with.
"""

from __future__ import annotations

import math

import numpy as np
from numba import float64, types

from rrt_pin.compiled._jit import jit, warn_problems

__all__ = ["metrics"]


_r1 = types.Array(float64, 1, "A", readonly=True)
_r2 = types.Array(float64, 2, "C", readonly=True)
_r3 = types.Array(float64, 3, "A", readonly=True)
_w1 = float64[::1]
_w2 = float64[:, ::1]


@jit(types.void(_r1, _r3, _r3, _r3, _r2, float64, _w2, _w2, _w2, _w2, _w2, _w1))
def metrics(t, q, qd, tau, qf, band, final, settle, peak, peak_t, excursion, energy):  # noqa: ANN001, ANN201
    """Fill the metric arrays (B, n) and energy (B,) from runs (B, T, n) sampled at t (T,)."""
    B, T, n = q.shape
    for b in range(B):
        for k in range(n):
            q0 = q[b, 0, k]
            f = qf[b, k]
            scale = abs(q0 - f)
            if scale == 0.0:
                for i in range(T):
                    scale = max(scale, abs(q[b, i, k] - f))
            threshold = band * scale
            last = -1
            far = 0.0
            top = -1.0
            when = 0
            for i in range(T):
                x = q[b, i, k]
                if abs(x - f) > threshold:
                    last = i
                far = max(far, abs(x - q0))
                m = abs(tau[b, i, k])
                if m > top:
                    top = m
                    when = i
            final[b, k] = abs(q[b, T - 1, k] - f)
            if last == -1:
                settle[b, k] = t[0]
            elif last == T - 1:
                settle[b, k] = math.nan
            else:
                settle[b, k] = t[last + 1]
            peak[b, k] = top
            peak_t[b, k] = t[when]
            excursion[b, k] = far
        total = 0.0
        before = 0.0
        for i in range(T):
            power = 0.0
            for k in range(n):
                power += abs(tau[b, i, k] * qd[b, i, k])
            if i > 0:
                total += 0.5 * (power + before) * (t[i] - t[i - 1])
            before = power
        energy[b] = total


def run(t: np.ndarray, q: np.ndarray, qd: np.ndarray, tau: np.ndarray, qf: np.ndarray, band: float):
    """All metric arrays at once: final, settle, peak, peak time, excursion (B, n); energy (B,)."""
    warn_problems()
    B, _, n = q.shape
    outs = [np.empty((B, n)) for _ in range(5)] + [np.empty(B)]
    f8 = np.float64
    metrics(
        np.asarray(t, f8), np.asarray(q, f8), np.asarray(qd, f8), np.asarray(tau, f8),
        np.ascontiguousarray(qf, f8), float(band), *outs,
    )  # fmt: skip
    return outs
