#!/usr/bin/env python
"""Streaming outputs: peak memory and rows/s of ``rrt-pin inverse`` for 10⁵ … 10⁷ rows.

Runs, as separate processes (interpreter start included), for each row count:

* csv        ``rrt-pin inverse --tf … --dt 0.001 --csv out.csv`` (this tree);
* parquet    the same with ``--csv out.parquet`` (pyarrow);
* baseline   the CSV run of another checkout (``--baseline /work/main``: the
             version before streaming), only up to ``--baseline-max`` rows, since
             it holds the whole table and its text in memory (9 GB at 10⁷ rows).

The sides run interleaved, round by round, so machine noise hits them alike. For
each it prints the wall time, rows/s, peak resident memory of the child process
(``os.wait4``'s ``ru_maxrss``) and the file size, then the baseline's ratios.

    .venv/bin/python -m scripts.bench.stream [--rows 1e5,1e6,1e7] [--repeat 1]
        [--baseline /work/main] [--baseline-max 1e6] [--check]

Target: 10⁷ rows under 500 MB peak RSS; ``--check`` exits 1 when it is missed.
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

ROOT = Path(__file__).resolve().parents[2]
TARGET_MB = 500.0
DT = 0.001


def run_once(tree: Path, rows: int, out: Path) -> tuple[float, float, int]:
    """Wall time [s], peak RSS [MB] and output size [bytes] of one ``rrt-pin inverse`` run."""
    tf = (rows - 1) * DT
    argv = [sys.executable, "-m", "rrt_pin", "inverse", "--tf", repr(tf), "--dt", repr(DT)]
    argv += ["--csv", str(out)]
    env = dict(os.environ, PYTHONPATH=str(tree))
    start = time.perf_counter()
    proc = subprocess.Popen(
        argv, cwd=tree, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - start
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode() if proc.stderr else ""
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}): {err.strip()}")
    size = out.stat().st_size
    out.unlink()
    return wall, usage.ru_maxrss / 1024.0, size  # ru_maxrss is in kB on Linux


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rows", default="1e5,1e6,1e7", help="row counts, comma-separated")
    parser.add_argument("--repeat", type=int, default=1, help="rounds per row count")
    parser.add_argument("--baseline", type=Path, help="another checkout to compare with")
    parser.add_argument("--baseline-max", type=float, default=1e6, help="largest baseline run")
    parser.add_argument("--no-parquet", action="store_true", help="skip the Parquet side")
    parser.add_argument("--check", action="store_true", help="exit 1 when the target is missed")
    args = parser.parse_args()
    counts = [int(float(x)) for x in args.rows.split(",")]
    ok = True
    print(
        f"{'rows':>12} {'side':<9} {'wall [s]':>9} {'rows/s':>12} {'peak RSS [MB]':>14} "
        f"{'file [MB]':>10}"
    )
    with tempfile.TemporaryDirectory(dir=ROOT) as tmp:
        folder = Path(tmp)
        for rows in counts:
            sides = [("csv", ROOT, "out.csv")]
            if not args.no_parquet:
                sides.append(("parquet", ROOT, "out.parquet"))
            if args.baseline and rows <= args.baseline_max:
                sides.append(("baseline", args.baseline.resolve(), "old.csv"))
            results: dict[str, list[tuple[float, float, int]]] = {s[0]: [] for s in sides}
            for _ in range(args.repeat):
                for name, tree, file in sides:
                    results[name].append(run_once(tree, rows, folder / file))
            figures = {}
            for name, runs in results.items():
                wall = statistics.median(r[0] for r in runs)
                rss = max(r[1] for r in runs)
                size = runs[-1][2]
                figures[name] = (wall, rss)
                print(
                    f"{rows:>12,} {name:<9} {wall:>9.2f} {rows / wall:>12,.0f} {rss:>14.0f} "
                    f"{size / 1e6:>10.1f}"
                )
            if "baseline" in figures:
                (w, r), (bw, br) = figures["csv"], figures["baseline"]
                print(f"{'':>12} baseline/csv: time ×{bw / w:.2f}, peak RSS ×{br / r:.2f}")
            if rows >= 10**7 and figures["csv"][1] > TARGET_MB:
                ok = False
                print(f"  MISSED: {figures['csv'][1]:.0f} MB > {TARGET_MB:.0f} MB")
    return 0 if ok or not args.check else 1


if __name__ == "__main__":
    sys.exit(main())
