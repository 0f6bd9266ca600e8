"""The ``rrt-pin`` command line: parsing, run files, one module a command.

* :mod:`~rrt_pin.cli.app`: :func:`main` and :func:`build_parser` (errors are one line,
  exit status 2);
* :mod:`~rrt_pin.cli.commands`: one module a command (parse, call the library, write);
* :mod:`~rrt_pin.cli.runfile`: TOML run files (``--config``);
* :mod:`~rrt_pin.cli.bench_report`, :mod:`~rrt_pin.cli.flops`: what ``rrt-pin bench``
  measures and prints.

May import: every layer (rrt_pin.core, rrt_pin.io, rrt_pin.robot, rrt_pin.dynamics,
rrt_pin.simulate, rrt_pin.compiled, rrt_pin.viewer, rrt_pin.sweeps).
"""

from __future__ import annotations

from rrt_pin.cli.app import build_parser, main

__all__ = ["build_parser", "main"]
