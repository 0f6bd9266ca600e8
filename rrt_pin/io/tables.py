"""Tables of samples written a block of rows at a time: CSV or Parquet, by suffix.

A run's table (``t``, ``q…``, ``qd…``, efforts…) can have 10⁷ rows; it is computed
and written in blocks of :data:`BLOCK_ROWS` rows, so memory stays flat whatever
the row count. The format follows the path: ``.parquet`` or ``.pq`` writes Parquet
(pyarrow, ``pip install rrt-pin[parquet]``) with each column's unit in its field
metadata (``unit``) and the run's metadata in the schema metadata
(``rrt_pin.units``, ``rrt_pin.run``: JSON); anything else (``.csv``, ``.txt``, no
suffix, ``-`` for stdout) writes CSV: one header line, then each number as the
shortest decimal that reads back to the same double.

The bytes go to the file handle :mod:`rrt_pin.io.files` gives a writer (a temporary
file renamed at the end, or a spooled buffer for stdout, FIFOs and devices).
"""

from __future__ import annotations

import json
import os
from collections.abc import Mapping, Sequence
from typing import IO, Any

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.core.extras import MissingExtra
from rrt_pin.io.csvio import csv_bytes, csv_engine

__all__ = [
    "BLOCK_ROWS",
    "PARQUET_SUFFIXES",
    "TableWriter",
    "estimate_bytes",
    "table_format",
]

#: Rows computed and written at a time (13 columns: ~7 MB of doubles, ~20 MB of text).
BLOCK_ROWS = 65_536

#: Suffixes that write Parquet; every other path writes CSV.
PARQUET_SUFFIXES = (".parquet", ".pq")

# Longest shortest-round-trip double and a comma ("-1.2345678901234567e-100,"): an
# upper bound of a CSV number; Parquet stores 8 bytes a number before compression.
_CSV_NUMBER_BYTES = 25
_PARQUET_NUMBER_BYTES = 8


def table_format(path: str | os.PathLike[str] | None) -> str:
    """``"parquet"`` for a ``.parquet`` or ``.pq`` path, else ``"csv"``."""
    if path is None:
        return "csv"
    suffix = os.path.splitext(os.fspath(path))[1].lower()
    return "parquet" if suffix in PARQUET_SUFFIXES else "csv"


def estimate_bytes(fmt: str, rows: int, columns: int) -> int:
    """An upper bound of a table's size [bytes]: rows × columns × bytes per number."""
    per = _PARQUET_NUMBER_BYTES if fmt == "parquet" else _CSV_NUMBER_BYTES
    return int(rows) * int(columns) * per + 64 * int(columns)


def _pyarrow(flag: str | None) -> Any:
    try:
        import pyarrow as pa
        import pyarrow.parquet  # noqa: F401
    except ImportError as e:
        raise MissingExtra("pyarrow", "parquet", f"{flag or 'a'} .parquet output") from e
    return pa


def check_format(path: str | os.PathLike[str] | None, flag: str | None = None) -> str:
    """The path's format, refusing Parquet up front when pyarrow is missing.

    Raises:
        InputError: a Parquet path without pyarrow installed (one line, with the hint).
    """
    fmt = table_format(path)
    if fmt == "parquet":
        _pyarrow(flag)
    return fmt


class TableWriter:
    """Writes one table to a binary file, a block of rows at a time.

    Example::

        with TableWriter(fh, "csv", ["t", "q1"], {"t": "s", "q1": "rad"}) as w:
            for block in blocks:
                w.write(block)

    Args:
        fh: the binary file (from :func:`rrt_pin.io.files.write_outputs`).
        fmt: ``"csv"`` or ``"parquet"`` (see :func:`table_format`).
        header: column names.
        units: unit of each column (SI), stored in Parquet's metadata.
        metadata: the run's description (JSON-serialisable), stored in Parquet's
            schema metadata as ``rrt_pin.run``.
    """

    def __init__(
        self,
        fh: IO[bytes],
        fmt: str,
        header: Sequence[str],
        units: Mapping[str, str] | None = None,
        metadata: Mapping[str, Any] | None = None,
    ) -> None:
        self.fh, self.fmt, self.header = fh, fmt, list(header)
        self.rows = 0
        self._parquet: Any = None
        units = dict(units or {})
        if fmt == "parquet":
            pa = _pyarrow(None)
            import pyarrow.parquet as pq

            fields = [
                pa.field(name, pa.float64(), metadata={"unit": units.get(name, "")})
                for name in self.header
            ]
            meta = {
                "rrt_pin.units": json.dumps({n: units.get(n, "") for n in self.header}),
                "rrt_pin.run": json.dumps(dict(metadata or {}), default=str),
            }
            self._schema = pa.schema(fields, metadata=meta)
            self._parquet = pq.ParquetWriter(fh, self._schema)
        else:
            self._engine = csv_engine()
            fh.write((",".join(self.header) + "\n").encode("utf-8"))

    def write(self, block: np.ndarray) -> None:
        """Append rows (shape (n, columns)) to the table."""
        block = np.asarray(block, dtype=float)
        if block.ndim != 2 or block.shape[1] != len(self.header):
            raise InputError(f"{block.shape=} does not match {len(self.header)} header columns")
        if self._parquet is not None:
            import pyarrow as pa

            columns = [pa.array(np.ascontiguousarray(block[:, k])) for k in range(block.shape[1])]
            self._parquet.write_table(pa.Table.from_arrays(columns, schema=self._schema))
        else:
            self.fh.write(csv_bytes(block, self._engine))
        self.rows += block.shape[0]

    def close(self) -> None:
        """Finish the table (Parquet writes its footer)."""
        if self._parquet is not None:
            self._parquet.close()
            self._parquet = None

    def __enter__(self) -> TableWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
