"""CSV rows as data, and an atomic writer; every number at full precision.

Each number is written as the shortest decimal that reads back to the same
double (``0.003``, not ``0.0030000000000000001``). Columns are SI (s, m, rad,
kg, N, N·m); the header names them.

Two formatters give those digits: orjson's (Ryu's algorithm, about 17·10⁶
numbers/s, a dependency for that reason) and Python's ``%r`` (about 2·10⁶
numbers/s), used for blocks holding a non-finite value (orjson would write
``null``) or where orjson cannot be imported. Their notation differs in form only:
``1e-05``/``0.00001``, ``1e+16`` in both.
"""

from __future__ import annotations

import io
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.io._read import read_text_capped
from rrt_pin.io.files import atomic_write

__all__ = [
    "ENGINES",
    "MAX_CSV_BYTES",
    "CsvTable",
    "csv_block",
    "csv_bytes",
    "csv_engine",
    "csv_text",
    "read_csv",
    "read_csv_table",
    "write_csv",
]

#: The formatters, fastest first.
ENGINES = ("orjson", "repr")


def _check(header: Sequence[str], data: np.ndarray) -> np.ndarray:
    data = np.asarray(data, dtype=float)
    if data.ndim != 2 or data.shape[1] != len(header):
        raise InputError(f"{data.shape=} does not match {len(header)} header columns")
    return data


def csv_engine() -> str:
    """The fastest formatter installed: ``"orjson"``, else ``"repr"``."""
    try:
        import orjson  # noqa: F401
    except ImportError:
        return "repr"
    return "orjson"


def csv_bytes(data: np.ndarray, engine: str | None = None) -> bytes:
    """Rows of a CSV (no header) as ASCII bytes, each number the shortest that round-trips.

    Args:
        data: shape (rows, columns), finite or not.
        engine: one of :data:`ENGINES` (default :func:`csv_engine`); a block with
            a non-finite value is always formatted by ``repr`` (``nan``, ``inf``).
    """
    data = np.asarray(data, dtype=float)
    if data.size == 0:
        return b""
    engine = engine or csv_engine()
    if engine not in ENGINES:
        raise InputError(f"engine={engine!r} is not one of {', '.join(ENGINES)}")
    if engine == "orjson" and np.isfinite(data).all():
        import orjson

        text = orjson.dumps(np.ascontiguousarray(data), option=orjson.OPT_SERIALIZE_NUMPY)
        return text[2:-2].replace(b"],[", b"\n") + b"\n"
    row = ",".join(["%r"] * data.shape[1]) + "\n"
    # One formatting pass over all values: about twice as fast as np.savetxt.
    return ((row * data.shape[0]) % tuple(data.ravel().tolist())).encode("ascii")


def csv_block(data: np.ndarray, engine: str | None = None) -> str:
    """:func:`csv_bytes` as text."""
    return csv_bytes(data, engine).decode("ascii")


def csv_text(header: Sequence[str], data: np.ndarray, engine: str | None = None) -> str:
    """The CSV text: one header line, then one row per line (shortest round-trip numbers).

    Args:
        header: column names.
        data: shape (rows, len(header)).
        engine: the formatter (default: :func:`csv_engine`).
    """
    data = _check(header, data)
    return ",".join(header) + "\n" + csv_block(data, engine)


def write_csv(path: str | Path, header: Sequence[str], data: np.ndarray) -> Path:
    """Write ``data`` (rows × columns) under ``header`` to ``path`` atomically."""
    data = _check(header, data)
    text = (",".join(header) + "\n").encode() + csv_bytes(data)
    return atomic_write(path, lambda fh: fh.write(text))


#: The largest CSV :func:`read_csv` reads [bytes] (``/dev/zero`` fails at once).
MAX_CSV_BYTES = 1 << 30

# A number as we read it: a decimal (``1``, ``-2.5``, ``.5``, ``1e-3``), ``inf`` or ``nan``.
_NUMBER = re.compile(
    r"[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|inf|infinity|nan)", re.IGNORECASE
)


@dataclass(frozen=True)
class CsvTable:
    """A CSV read by :func:`read_csv_table`: its columns, its numbers and where each row was.

    Attributes:
        path: the file, as given.
        header: the column names (line 1).
        data: the numbers, shape (rows, columns).
        lines: the line of each row as a text editor numbers it (the header is
            line 1; blank and ``#`` lines are skipped, so rows and lines may differ),
            shape (rows,).
    """

    path: str
    header: list[str]
    data: np.ndarray
    lines: np.ndarray
    _text: str = field(default="", repr=False, compare=False)

    def where(self, row: int, column: int | str) -> str:
        """``CSV 'path' line L, column 'c'`` for row ``row`` (0-based) of ``column``."""
        name = column if isinstance(column, str) else self.header[column]
        return f"{_name(self.path)} line {int(self.lines[row])}, column {name!r}"

    def check_increasing(self, column: str = "t") -> None:
        """Refuse a ``column`` whose values do not increase strictly (naming both lines).

        Raises:
            InputError: the first value that does not exceed the one before it.
        """
        steps = np.diff(self.data[:, self.header.index(column)])
        if (steps <= 0.0).any():
            k = int(np.argmax(steps <= 0.0))
            raise InputError(
                f"{self.where(k + 1, column)}: times must increase strictly, but "
                f"{self.value_text(k + 1, column)} s follows {self.value_text(k, column)} s "
                f"(line {int(self.lines[k])})"
            )

    def value_text(self, row: int, column: int | str) -> str:
        """The text of a value as the file has it (stripped), for messages."""
        index = column if isinstance(column, int) else self.header.index(column)
        line = _line(self._text, int(self.lines[row]))
        fields = line.split(",")
        return fields[index].strip() if index < len(fields) else ""


def _name(path: str) -> str:
    return f"CSV {path!r}"


def _shown(text: str, limit: int = 40) -> str:
    """``text`` quoted for a message, cut to ``limit`` characters."""
    return repr(text if len(text) <= limit else text[: limit - 1] + "…")


def _line(text: str, number: int) -> str:
    """Line ``number`` (1-based) of ``text`` (whose lines end in a newline)."""
    start = 0
    for _ in range(number - 1):
        start = text.index("\n", start) + 1
    end = text.find("\n", start)
    return text[start:] if end < 0 else text[start:end]


def read_csv(path: str | Path, required: Sequence[str] = ()) -> tuple[list[str], np.ndarray]:
    """The header and numbers of a CSV (see :func:`read_csv_table`)."""
    table = read_csv_table(path, required)
    return table.header, table.data


def read_csv_table(path: str | Path, required: Sequence[str] = ()) -> CsvTable:
    """Read a CSV written by :func:`write_csv` (or any numeric CSV with a header line).

    The first line names the columns; every other line holds one number per
    column, separated by commas (``nan`` and ``inf`` are read, then refused).
    Blank lines and lines starting with ``#`` are skipped; Windows line ends and
    a UTF-8 byte-order mark are accepted. Every error names the file, the line
    as a text editor numbers it (the header is line 1), the column and the value.

    Args:
        path: the file, at most :data:`MAX_CSV_BYTES`.
        required: columns the file must have.

    Raises:
        InputError: the file cannot be read or is not UTF-8; the header is
            empty, names a column twice or lacks a required one; a line has too
            few or too many values; a value is missing, not a number, or not finite.
    """
    name = str(path)
    text = read_text_capped(path, cap=MAX_CSV_BYTES, what="CSV", error=InputError)
    if "\r" in text:
        text = text.replace("\r\n", "\n").replace("\r", "\n")
    first, _, rows = text.partition("\n")
    header = [h.strip() for h in first.split(",")]
    if header == [""]:
        raise InputError(f"{_name(name)} is empty: line 1 must name the columns")
    seen: set[str] = set()
    for k, column in enumerate(header):
        if not column:
            raise InputError(f"{_name(name)} line 1: column {k + 1} has no name")
        if column in seen:
            raise InputError(f"{_name(name)} line 1 names column {column!r} twice")
        seen.add(column)
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(
            f"{_name(name)} lacks column {missing[0]!r}; line 1 names {_shown(','.join(header), 80)}"
        )
    data = None
    if rows.strip():
        try:
            data = np.loadtxt(io.StringIO(rows), delimiter=",", ndmin=2, comments=None)
        except ValueError:
            pass  # the slow reader below says where and what
    if data is None or data.shape[1] != len(header):
        data, lines = _read_rows(name, header, rows)
    else:
        lines = _row_lines(rows, data.shape[0])
    if data.shape[0] == 0:
        raise InputError(f"{_name(name)} has no data rows (only the header, line 1)")
    table = CsvTable(path=name, header=header, data=data, lines=lines, _text=text)
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = (int(i) for i in np.argwhere(bad)[0])
        raise InputError(
            f"{table.where(r, c)}: {_shown(table.value_text(r, c))} is not a finite number"
        )
    return table


def _row_lines(rows: str, n: int) -> np.ndarray:
    """The line numbers of the ``n`` non-blank lines of ``rows`` (which start on line 2)."""
    count = rows.count("\n") + (0 if rows.endswith("\n") or not rows else 1)
    if count == n:  # no blank line
        return np.arange(2, n + 2)
    return np.array([k for k, line in enumerate(rows.split("\n"), start=2) if line.strip()][:n])


def _read_rows(name: str, header: list[str], rows: str) -> tuple[np.ndarray, np.ndarray]:
    """Parse ``rows`` value by value; raise at the first bad one, naming its line and column."""
    values: list[float] = []
    lines: list[int] = []
    width = len(header)
    for number, line in enumerate(rows.split("\n"), start=2):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        fields = line.split(",")
        where = f"{_name(name)} line {number}"
        if len(fields) > width:
            extra = fields[width].strip()
            what = f"an extra value {_shown(extra)}" if extra else "an extra comma"
            raise InputError(
                f"{where} has {len(fields)} fields but line 1 names {width} columns: "
                f"{what} follows the last column {header[-1]!r}"
            )
        for k, word in enumerate(fields):
            word = word.strip()
            if not word:
                raise InputError(f"{where}, column {header[k]!r}: the value is missing")
            if not _NUMBER.fullmatch(word):
                raise InputError(f"{where}, column {header[k]!r}: {_shown(word)} is not a number")
            values.append(float(word))
        if len(fields) < width:
            raise InputError(
                f"{where} has {len(fields)} fields but line 1 names {width} columns: "
                f"the value of column {header[len(fields)]!r} is missing"
            )
        lines.append(number)
    return np.array(values, dtype=float).reshape(len(lines), width), np.array(lines, dtype=int)
