"""CSV rows as data, and an atomic writer; every number at full precision.

Each number is written as the shortest decimal that reads back to the same
double (``0.003``, not ``0.0030000000000000001``), as Python's ``repr`` prints
it. Columns are SI (s, m, rad, kg, N, N·m); the header names them.

Two formatters give those digits: Python's ``%r`` (always there, about 2·10⁶
numbers/s) and pyarrow's CSV writer (about 4× as fast, but ~0.2 s to import),
used for tables of :data:`ARROW_MIN_ROWS` rows or more when pyarrow is
installed. Their notation differs in form only: ``0.0``/``0``, ``1e-05``/``0.00001``.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rrt_pin.errors import InputError
from rrt_pin.io import atomic_write

__all__ = ["ARROW_MIN_ROWS", "csv_block", "csv_engine", "csv_text", "read_csv", "write_csv"]

#: Tables this long are formatted by pyarrow when it is installed: its import (~0.2 s)
#: costs what it saves on ~40,000 rows of 13 numbers.
ARROW_MIN_ROWS = 50_000


def _check(header: Sequence[str], data: np.ndarray) -> np.ndarray:
    data = np.asarray(data, dtype=float)
    if data.ndim != 2 or data.shape[1] != len(header):
        raise InputError(f"{data.shape=} does not match {len(header)} header columns")
    return data


def csv_engine(rows: int) -> str:
    """The formatter for a table of ``rows`` rows: ``"arrow"`` or ``"repr"``."""
    if rows >= ARROW_MIN_ROWS:
        try:
            import pyarrow.csv  # noqa: F401
        except ImportError:
            return "repr"
        return "arrow"
    return "repr"


def csv_block(data: np.ndarray, engine: str = "repr") -> str:
    """Rows of a CSV (no header), each number the shortest decimal that round-trips.

    Args:
        data: shape (rows, columns), finite or not.
        engine: ``"repr"`` (Python's ``%r``) or ``"arrow"`` (pyarrow's CSV writer).
    """
    data = np.asarray(data, dtype=float)
    if data.size == 0:
        return ""
    if engine == "arrow":
        import pyarrow as pa
        import pyarrow.csv as pc

        table = pa.Table.from_arrays(
            [pa.array(np.ascontiguousarray(data[:, k])) for k in range(data.shape[1])],
            names=[f"c{k}" for k in range(data.shape[1])],
        )
        sink = pa.BufferOutputStream()
        pc.write_csv(table, sink, pc.WriteOptions(include_header=False, batch_size=1 << 16))
        return sink.getvalue().to_pybytes().decode("ascii")
    row = ",".join(["%r"] * data.shape[1]) + "\n"
    # One formatting pass over all values: about twice as fast as np.savetxt.
    return (row * data.shape[0]) % tuple(data.ravel().tolist())


def csv_text(header: Sequence[str], data: np.ndarray, engine: str | None = None) -> str:
    """The CSV text: one header line, then one row per line (shortest round-trip numbers).

    Args:
        header: column names.
        data: shape (rows, len(header)).
        engine: the formatter (default: :func:`csv_engine` of the row count).
    """
    data = _check(header, data)
    engine = engine or csv_engine(data.shape[0])
    return ",".join(header) + "\n" + csv_block(data, engine)


def write_csv(path: str | Path, header: Sequence[str], data: np.ndarray) -> Path:
    """Write ``data`` (rows × columns) under ``header`` to ``path`` atomically."""
    text = csv_text(header, data)
    return atomic_write(path, lambda fh: fh.write(text.encode()))


def read_csv(path: str | Path, required: Sequence[str] = ()) -> tuple[list[str], np.ndarray]:
    """Read a CSV written by :func:`write_csv` (or any numeric CSV with a header).

    Raises:
        InputError: the file cannot be read, a required column is missing, a
            value is not a number, or a value is not finite.
    """
    path = Path(path)
    try:
        with open(path, encoding="utf-8-sig") as fh:  # a UTF-8 BOM is not part of the name
            header = [h.strip() for h in fh.readline().strip().split(",")]
            rows = fh.read()
    except OSError as e:
        raise InputError(f"cannot read CSV {str(path)!r}: {e.strerror}") from e
    except UnicodeDecodeError as e:
        raise InputError(f"CSV {str(path)!r} is not UTF-8 text") from e
    seen: set[str] = set()
    for name in header:
        if name in seen:
            raise InputError(f"CSV {str(path)!r} names column {name!r} twice")
        seen.add(name)
    missing = [c for c in required if c not in header]
    if missing:
        raise InputError(
            f"CSV {str(path)!r} lacks column {missing[0]!r}; it has {','.join(header)}"
        )
    if not rows.strip():
        raise InputError(f"CSV {str(path)!r} has no data rows")
    try:
        data = np.loadtxt(io.StringIO(rows), delimiter=",", ndmin=2)
    except ValueError as e:
        raise InputError(f"CSV {str(path)!r}: {str(e).splitlines()[0]}") from e
    if data.size == 0:
        raise InputError(f"CSV {str(path)!r} has no data rows")
    if data.shape[1] != len(header):
        raise InputError(f"CSV {str(path)!r}: {data.shape[1]} columns but {len(header)} names")
    bad = ~np.isfinite(data)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise InputError(
            f"CSV {str(path)!r}: non-finite value {float(data[r, c])!r} in column "
            f"{header[c]!r}, row {r + 2}"
        )
    return header, data
