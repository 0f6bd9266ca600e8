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
    assert text == "t,q1\n0.0,0.1\n1.0,0.3333333333333333\n"


ENGINES = ["repr", "orjson"]


@pytest.mark.parametrize("engine", ENGINES)
def test_shortest_numbers_that_read_back_bit_for_bit(tmp_path, rng, engine):
    t = time_grid(15.0, 0.001)
    wild = rng.normal(size=t.size) * 10.0 ** rng.integers(-300, 300, size=t.size)
    data = np.column_stack([t, np.sin(t) / 3, wild, -t * 1e-7])
    text = csv_text(["t", "a", "b", "c"], data, engine=engine)
    path = tmp_path / "x.csv"
    path.write_text(text)
    _, back = read_csv(path)
    assert back.view(np.int64).tolist() == data.view(np.int64).tolist()  # bit for bit
    rows = text.splitlines()[1:]
    assert rows[3].split(",")[0] == "0.003"
    # No number is longer than the shortest decimal that round-trips (Python's repr).
    for line, row in zip(rows[::97], data[::97], strict=True):
        for word, value in zip(line.split(","), row, strict=True):
            assert float(word) == value
            digits = word.lstrip("-").split("e")[0].replace(".", "").strip("0")
            shortest = repr(float(value)).lstrip("-").split("e")[0].replace(".", "").strip("0")
            assert digits == shortest, (word, repr(value))


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
