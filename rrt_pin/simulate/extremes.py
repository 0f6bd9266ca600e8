"""Extremes over the output samples of runs: per run and coordinate, without a slow axis.

Arrays of runs are (B, T, n): B runs, T samples, n coordinates, C-ordered. NumPy reduces
their middle axis (``x.max(axis=1)``) one short row of n at a time, 5–20× slower than a
reduction along contiguous memory. These functions transpose a block of runs at a time
(about 256 KiB, so it stays in cache) and reduce along the samples. The values are
NumPy's own: NaN propagates as in ``np.min``/``np.max``, and ``max |x|`` is exact.
"""

from __future__ import annotations

import numpy as np

__all__ = ["deviation", "extremes", "peak"]

#: The bytes of one block of runs, transposed at a time.
BLOCK_BYTES = 1 << 18


def _blocks(B: int, T: int, n: int) -> range:
    step = max(1, BLOCK_BYTES // max(1, 8 * T * n))
    return range(0, B, step)


def extremes(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(min, max) over the samples of ``x`` (B, T, n): two (B, n) arrays."""
    B, T, n = x.shape
    if T == 0:  # NumPy's answer (an error: no samples)
        return x.min(axis=1), x.max(axis=1)
    lo, hi = np.empty((B, n)), np.empty((B, n))
    starts = _blocks(B, T, n)
    for s in starts:
        e = min(B, s + starts.step)
        rows = np.ascontiguousarray(x[s:e].transpose(0, 2, 1))
        rows.min(axis=2, out=lo[s:e])
        rows.max(axis=2, out=hi[s:e])
    return lo, hi


def peak(x: np.ndarray) -> np.ndarray:
    """The largest |x| over the samples of ``x`` (B, T, n), as ``np.abs(x).max(axis=1)``."""
    lo, hi = extremes(x)
    return np.maximum(-lo, hi) + 0.0  # + 0.0: 0.0, never -0.0


def deviation(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """The largest |a − b| over the samples, per run and coordinate (B, n).

    As ``np.abs(a - b).max(axis=1)``, but a block at a time (no array as large as ``a``).
    """
    B, T, n = a.shape
    out = np.empty((B, n))
    starts = _blocks(B, T, n)
    for s in starts:
        e = min(B, s + starts.step)
        d = np.subtract(a[s:e], b[s:e])
        out[s:e] = peak(d)
    return out
