#!/usr/bin/env python3
"""Whole-process time of the CLI's two jobs against the floor of importing Pinocchio.

Each round runs, interleaved: ``python -c "import pinocchio"`` (the floor: any run
of the engine of record pays it), ``rrt-pin inverse --csv`` and ``rrt-pin simulate
--csv`` (the chapter's jobs, default backend). Medians of --repeat rounds [s], and
each job's excess over the floor. The processes run as a user's do: with Python's
bytecode cache (``PYTHONDONTWRITEBYTECODE`` is dropped from their environment; an
installed package has its ``.pyc`` files, and the first, untimed round writes them
for a source checkout), otherwise every run would recompile rrt-pin's modules (~40 ms).

    .venv/bin/python -m scripts.bench.startup [--repeat 15]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

TARGETS = {"inverse": 0.30, "simulate": 0.45}  # [s] on the reference 2-core machine


ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def _seconds(argv: list[str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=ENV)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    repeat = parser.parse_args().repeat
    py = sys.executable
    with tempfile.TemporaryDirectory() as d:
        jobs = {
            "import pinocchio": [py, "-c", "import pinocchio"],
            "inverse": [py, "-m", "rrt_pin", "inverse", "--csv", str(Path(d) / "i.csv")],
            "simulate": [py, "-m", "rrt_pin", "simulate", "--csv", str(Path(d) / "s.csv")],
            # The compiled backend: its dynamics built ahead of time load without numba.
            "inverse compiled": [
                py, "-m", "rrt_pin", "inverse", "--backend", "compiled",
                "--csv", str(Path(d) / "c.csv"),
            ],
            "simulate compiled": [
                py, "-m", "rrt_pin", "simulate", "--backend", "compiled",
                "--csv", str(Path(d) / "d.csv"),
            ],
        }  # fmt: skip
        for argv in jobs.values():  # warm the page cache and the bytecode
            _seconds(argv)
        times: dict[str, list[float]] = {name: [] for name in jobs}
        for _ in range(repeat):
            for name, argv in jobs.items():
                times[name].append(_seconds(argv))
    floor = statistics.median(times["import pinocchio"])
    print(f"{'process':<18} {'median [s]':>10} {'over floor [s]':>15} {'target [s]':>11}")
    # The compiled processes are there for comparison: no target.
    for name, ts in times.items():
        median = statistics.median(ts)
        target = f"{TARGETS[name]:.2f}" if name in TARGETS else ""
        print(f"{name:<18} {median:>10.3f} {median - floor:>15.3f} {target:>11}")


if __name__ == "__main__":
    main()
