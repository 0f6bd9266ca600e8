"""CSV rows as data, and an atomic writer; full float precision (``%.17g``).

Columns are SI (s, m, rad, kg, N, N·m); the header names them.
"""

from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from rrt_pin.errors import InputError
from rrt_pin.io import atomic_write

__all__ = ["csv_text", "read_csv", "write_csv"]


def _check(header: Sequence[str], data: np.ndarray) -> np.ndarray:
    data = np.asarray(data, dtype=float)
    if data.ndim != 2 or data.shape[1] != len(header):
        raise InputError(f"{data.shape=} does not match {len(header)} header columns")
    return data


def csv_text(header: Sequence[str], data: np.ndarray) -> str:
    """The CSV text: one header line, then one row per line at ``%.17g``."""
    data = _check(header, data)
    row = ",".join(["%.17g"] * data.shape[1]) + "\n"
    # One formatting pass over all values: about twice as fast as np.savetxt.
    return ",".join(header) + "\n" + (row * data.shape[0]) % tuple(data.ravel().tolist())


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
