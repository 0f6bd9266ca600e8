import re

import numpy as np
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.io.csvio import csv_text, read_csv, read_csv_table, write_csv


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


# Every error names the file, the line as an editor numbers it (header = line 1),
# the column and the value, in our words (never numpy's "could not convert", "row 1").
@pytest.mark.parametrize(
    "text, words",
    [
        ("t,q1\n0,1\n1,x\n", "line 3, column 'q1': 'x' is not a number"),
        ("t,q1\n0,1e\n", "line 2, column 'q1': '1e' is not a number"),
        ("t,q1\n0,1_0\n", "line 2, column 'q1': '1_0' is not a number"),
        ("t,q1\n0,nan\n", "line 2, column 'q1': 'nan' is not a finite number"),
        ("t,q1\n0,1\n1,-inf\n", "line 3, column 'q1': '-inf' is not a finite number"),
        ("t,q1\n0,1\n1e999,1\n", "line 3, column 't': '1e999' is not a finite number"),
        ("t,q1,q2\n0,1,2\n1,,2\n", "line 3, column 'q1': the value is missing"),
        (
            "t,q1,q2\n0,1,2\n1,2\n",
            "line 3 has 2 fields but line 1 names 3 columns: the value of column 'q2' is missing",
        ),
        (
            "t,q1\n0,1\n1,2,3\n",
            "line 3 has 3 fields but line 1 names 2 columns: an extra value '3' follows the "
            "last column 'q1'",
        ),
        ("t,q1\n0,1,\n", "line 2 has 3 fields but line 1 names 2 columns: an extra comma"),
        ("t,q1\n", "has no data rows (only the header, line 1)"),
        ("t,q1\n\n  \n", "has no data rows"),
        ("", "is empty: line 1 must name the columns"),
        ("t,,q1\n0,1,2\n", "line 1: column 2 has no name"),
        ("t,q1,q1\n0,1,2\n", "line 1 names column 'q1' twice"),
        ("t,q2\n0,1\n", "lacks column 'q1'; line 1 names 't,q2'"),
        # blank lines count as lines, as in an editor; so do Windows line ends
        ("t,q1\n\n0,1\n\n1,nan\n", "line 5, column 'q1': 'nan' is not a finite number"),
        ("t,q1\r\n0,1\r\n1,y\r\n", "line 3, column 'q1': 'y' is not a number"),
        ("t,q1\n0,1\n1," + "9" * 100 + "x\n", "'" + "9" * 39 + "…' is not a number"),
    ],
)
def test_bad_csv(tmp_path, text, words):
    path = tmp_path / "bad.csv"
    path.write_text(text, newline="")
    with pytest.raises(InputError) as e:
        read_csv(path, required=["t", "q1"])
    message = str(e.value)
    assert message.startswith(f"CSV {str(path)!r}")
    assert words in message
    assert "\n" not in message and "convert" not in message
    assert not re.search(r"\brow \d", message)  # numpy's 0-based rows


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda p: None, "cannot read CSV '{p}': No such file or directory"),
        (lambda p: p.mkdir(), "cannot read CSV '{p}': it is a folder"),
        (lambda p: p.write_bytes(b"t,q1\n0,caf\xe9\n"), "CSV '{p}' is not UTF-8 text"),
    ],
)
def test_unreadable_csv(tmp_path, make, words):
    path = tmp_path / "x.csv"
    make(path)
    with pytest.raises(InputError, match=words.format(p=path)):
        read_csv(path)


def test_lines_as_an_editor_numbers_them(tmp_path):
    path = tmp_path / "x.csv"
    path.write_bytes(b"\xef\xbb\xbft , q1\r\n0,1\r\n\r\n 2 , 3 \r\n\r\n")
    table = read_csv_table(path, required=["t"])
    assert table.header == ["t", "q1"]
    assert table.data.tolist() == [[0.0, 1.0], [2.0, 3.0]]
    assert table.lines.tolist() == [2, 4]
    assert table.where(1, "q1") == f"CSV {str(path)!r} line 4, column 'q1'"
    assert table.value_text(1, 0) == "2"


@pytest.mark.parametrize("skipped", ["   ", "# a comment", "  #,1,2"])
def test_blank_and_comment_lines_are_skipped(tmp_path, skipped):
    path = tmp_path / "x.csv"
    path.write_text(f"t,q1\n0,1\n{skipped}\n2,3\n4,x\n")
    with pytest.raises(InputError, match="line 5, column 'q1': 'x' is not a number"):
        read_csv_table(path)
    path.write_text(f"t,q1\n0,1\n{skipped}\n2,3\n")
    table = read_csv_table(path)
    assert table.data.tolist() == [[0.0, 1.0], [2.0, 3.0]] and table.lines.tolist() == [2, 4]


def test_a_csv_beyond_the_cap_is_refused_unread(tmp_path, monkeypatch):
    import rrt_pin.io.csvio as csvio

    path = tmp_path / "x.csv"
    path.write_text("t,q1\n0,1\n")
    monkeypatch.setattr(csvio, "MAX_CSV_BYTES", 8)
    with pytest.raises(InputError, match="is 9 bytes, larger than the 8 bytes allowed"):
        read_csv(path)


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
