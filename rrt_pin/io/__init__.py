"""Files in and out: safe writes, CSV and Parquet tables, readers of input files.

* :mod:`~rrt_pin.io.files`: the one output layer (checked targets, atomic writes that
  never replace a device, pipe or link, space checked first);
* :mod:`~rrt_pin.io.csvio`: CSV numbers written shortest-exact and read back with
  editor lines in errors; :mod:`~rrt_pin.io.tables`: a result's table as CSV or
  Parquet with units and metadata; :mod:`~rrt_pin.io._read`: bounded reads of
  TOML and text inputs.

May import: rrt_pin.core.

The names of the 0.3 module ``rrt_pin.io`` (``atomic_write``, ``check_output``, …)
are still offered here for one release, with a DeprecationWarning naming
:mod:`rrt_pin.io.files`.
"""

from __future__ import annotations

import importlib
import warnings
from typing import Any

__all__: list[str] = []

_FILES = (
    "STDOUT", "OutputError", "Writer", "atomic_write", "atomic_write_bytes",
    "atomic_write_text", "check_output", "check_outputs", "check_space", "write_outputs",
)  # fmt: skip


def __getattr__(name: str) -> Any:
    if name in _FILES:
        warnings.warn(
            f"rrt_pin.io.{name} is deprecated: import it from rrt_pin.io.files",
            DeprecationWarning,
            stacklevel=2,
        )
        return getattr(importlib.import_module("rrt_pin.io.files"), name)
    raise AttributeError(f"module 'rrt_pin.io' has no attribute {name!r}")
