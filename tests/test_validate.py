"""One validation module, one wording: what the library accepts at its boundary."""

from __future__ import annotations

import numpy as np
import pytest

from rrt_pin.core import validate
from rrt_pin.core.errors import InputError


@pytest.mark.parametrize("value", [1, 2.5, np.float32(0.5), np.int64(3), np.array(0.25)])
def test_real_numbers_of_any_numeric_type(value):
    assert validate.real("x", value) == float(value)


@pytest.mark.parametrize(
    "value, words",
    [
        (True, "x=True must be a real number"),
        (1j, "x=1j must be a real number"),
        ("1", "x='1' must be a real number"),
        (None, "x=None must be a real number"),
        (float("nan"), "x=nan must be finite"),
        (10**400, "is too large"),
    ],
)
def test_real_refuses(value, words):
    with pytest.raises(InputError) as info:
        validate.real("x", value)
    assert words in str(info.value)


@pytest.mark.parametrize("value, words", [(0, "> 0"), (1.0, "< 1"), (1e300, "< 1"), (-1e-3, "> 0")])
def test_tolerances_lie_in_0_1(value, words):
    with pytest.raises(InputError, match=words):
        validate.tolerance("rtol", value)
    assert validate.tolerance("rtol", 1e-9) == 1e-9


def test_vectors_states_samples_and_times():
    np.testing.assert_array_equal(validate.vector("q0", [1, 2, 3], 3), [1.0, 2.0, 3.0])
    with pytest.raises(InputError, match=r"q0\[1\]=inf must be finite \[rad\]"):
        validate.vector("q0", [0, np.inf, 0], 3, "rad")
    with pytest.raises(InputError, match="holds complex numbers"):
        validate.vector("q0", [1j, 0, 0], 3)
    with pytest.raises(InputError, match=r"q0s has shape \(3,\) but needs \(B, 3\)"):
        validate.states("q0s", [1, 2, 3], 3)
    arr, single = validate.samples("q", [1, 2], 2)
    assert single and arr.shape == (1, 2)
    with pytest.raises(InputError, match=r"t_eval must increase: t_eval\[2\]=1.0 <= 1.0 \[s\]"):
        validate.times([0.0, 1.0, 1.0])
    with pytest.raises(InputError, match="at least 2 times"):
        validate.times([0.0])
    assert validate.positive_int("threads", np.int32(2)) == 2
    with pytest.raises(InputError, match="threads=True must be an integer >= 1"):
        validate.positive_int("threads", True)


@pytest.mark.parametrize(
    "value", [np.float64(-0.5), np.int32(-3), np.array(-2.0), np.float32(-1.25)]
)
def test_messages_show_numpy_scalars_as_python_numbers(value):
    with pytest.raises(InputError) as info:
        validate.real("dt", value, "s", positive=True)
    assert "np." not in str(info.value) and "array(" not in str(info.value)
    assert str(info.value) == f"dt={np.asarray(value).item()!r} must be > 0 [s]"
