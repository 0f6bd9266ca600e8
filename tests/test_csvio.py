import numpy as np
import pytest

from rrt_pin.csvio import csv_text, read_csv, write_csv
from rrt_pin.errors import InputError
from rrt_pin.grid import time_grid


def test_round_trip_at_full_precision(tmp_path, rng):
    data = rng.normal(size=(50, 3)) * 10.0 ** rng.integers(-300, 300, size=(50, 3))
    path = write_csv(tmp_path / "x.csv", ["a", "b", "c"], data)
    header, back = read_csv(path, required=["a", "c"])
    assert header == ["a", "b", "c"]
    np.testing.assert_array_equal(back, data)


def test_text_has_one_header_line():
    text = csv_text(["t", "q1"], np.array([[0.0, 0.1], [1.0, 1 / 3]]))
    assert text == "t,q1\n0,0.10000000000000001\n1,0.33333333333333331\n"


@pytest.mark.parametrize(
    "text, words",
    [
        ("t,q1\n", "no data rows"),
        ("", "lacks column 't'"),
        ("t,q2\n0,1\n", "lacks column 'q1'"),
        ("t,q1\n0,nan\n", "non-finite value nan in column 'q1', row 2"),
        ("t,q1\n0,1\n1,-inf\n", "non-finite value -inf in column 'q1', row 3"),
        ("t,q1\n0,x\n", "could not convert"),
        ("t,q1\n0,1,2\n", "columns"),
    ],
)
def test_bad_csv(tmp_path, text, words):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(InputError, match=words):
        read_csv(path, required=["t", "q1"])


def test_failed_write_leaves_nothing(tmp_path):
    with pytest.raises(InputError):
        write_csv(tmp_path / "x.csv", ["a", "b"], np.zeros((2, 3)))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "tf, dt, n, last",
    [(15.0, 0.001, 15001, 15.0), (15.0, 0.01, 1501, 15.0), (1.0, 0.3, 5, 1.0), (1.0, 1.0, 2, 1.0)],
)
def test_time_grid_includes_both_ends(tf, dt, n, last):
    t = time_grid(tf, dt)
    assert t.size == n and t[0] == 0.0 and t[-1] == last
    assert np.all(np.diff(t) > 0) and np.diff(t).max() <= dt * (1 + 1e-9)


@pytest.mark.parametrize(
    "tf, dt, words",
    [
        (0.0, 0.1, "tf=0.0 must be > t0"),
        (1.0, 0.0, "dt=0.0 must be > 0"),
        (1.0, 2.0, "larger than"),
        (float("nan"), 0.1, "finite"),
    ],
)
def test_time_grid_refuses(tf, dt, words):
    with pytest.raises(InputError, match=words):
        time_grid(tf, dt)
