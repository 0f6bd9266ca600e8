"""The extremes over output samples equal NumPy's own reductions, block by block."""

import numpy as np
import pytest

from rrt_pin.simulate import extremes


@pytest.mark.parametrize("shape", [(1, 1501, 6), (3, 7, 2), (130, 301, 3), (1, 1, 4)])
def test_extremes_equal_numpys_reductions_over_the_samples(shape):
    rng = np.random.default_rng(sum(shape))
    a = rng.normal(size=shape)
    b = a + rng.normal(scale=1e-9, size=shape)
    if shape[0] > 2:  # NaN samples in some runs, and zeros of both signs
        a[1, rng.random(shape[1]) < 0.2, 0] = np.nan
        a[2] = -0.0
    lo, hi = extremes.extremes(a)
    np.testing.assert_array_equal(lo, a.min(axis=1))
    np.testing.assert_array_equal(hi, a.max(axis=1))
    got = extremes.peak(a)
    np.testing.assert_array_equal(got, np.abs(a).max(axis=1))
    assert not np.signbit(got[~np.isnan(got)]).any()  # never -0.0
    np.testing.assert_array_equal(extremes.deviation(a, b), np.abs(a - b).max(axis=1))


def test_runs_span_several_blocks():
    """Runs large enough to need many blocks are each reduced exactly once."""
    B, T, n = 200, 997, 3
    assert extremes.BLOCK_BYTES // (8 * T * n) < B  # several blocks
    x = np.arange(B * T * n, dtype=float).reshape(B, T, n)
    lo, hi = extremes.extremes(x)
    np.testing.assert_array_equal(lo, x[:, 0, :])
    np.testing.assert_array_equal(hi, x[:, -1, :])
