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
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rrt_pin.errors import InputError
from rrt_pin.io import atomic_write

__all__ = ["ENGINES", "csv_block", "csv_bytes", "csv_engine", "csv_text", "read_csv", "write_csv"]

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
