#!/usr/bin/env python
"""Sweeps at scale: throughput, scaling and peak memory of ``rrt_pin.sweep`` in one run.

The sweep: the chapter's direct run (0..15 s, metrics from 1,501 samples) with the six
gains ±25 %, q0 ± 0.1 (rad, rad, m), m3 ± 20 % and I3x −20 % … 0 % (I3x = I3y + I3z
already: more breaks the triangle inequality), drawn at random, metrics only.

1. per core: ``run_chunk`` in this process (the compiled batch and the one-pass metrics),
   the rate a Dask worker can reach at best;
2. Dask's local cluster (one single-threaded worker process per core) for 10^3 … --max
   variants: wall time, variants/s, efficiency = rate / (cores × per-core rate), and the
   peak of the summed RSS of this process and its children (sampled every 0.1 s);
3. accuracy: sampled variants' metrics against single ``simulate`` runs.

    .venv/bin/python -m scripts.bench.sweep [--max 1000000] [--workers 2]

Targets: 10^6 variants <= 5 min, peak memory <= 1 GiB, efficiency >= 90 %,
metrics equal to single runs to 1e-9.
"""

from __future__ import annotations

import argparse
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path

import numpy as np
import psutil

from rrt_pin.robot.params import Params
from rrt_pin.sweeps.compute import run_chunk
from rrt_pin.sweeps.run import sweep
from rrt_pin.sweeps.spec import spec_from_dict

# What is timed is a sweep as it runs by default: on the backend auto chooses for it (the
# package sets the engine of record for the benchmarks that name no backend).
os.environ.pop("RRT_PIN_BACKEND", None)


def bench_spec(count: int, chunk: int = 16384) -> dict:
    p = Params()
    vary = {}
    for name in ("gamma01", "gamma12", "gamma23", "beta01", "beta12", "beta23"):
        v = getattr(p, name)
        vary[name] = {"uniform": [0.75 * v, 1.25 * v]}
    for name in ("q10", "q20", "q30"):
        v = getattr(p, name)
        vary[name] = {"uniform": [v - 0.1, v + 0.1]}
    vary["m3"] = {"uniform": [0.8 * p.m3, 1.2 * p.m3]}
    # I3x = 5 = I3y + I3z already: above it the slider's inertia is impossible (the triangle
    # inequality), which the sweep refuses; so I3x varies over -20 % … 0 %
    vary["I3x"] = {"uniform": [0.8 * p.I3x, p.I3x]}
    return {
        "sweep": {"tf": 15.0, "dt": 0.01, "count": count, "seed": 2026, "chunk": chunk},
        "vary": vary,
    }


class PeakRSS:
    """The largest summed RSS of this process and its descendants, sampled in a thread."""

    def __init__(self, period: float = 0.1) -> None:
        self.period, self.peak, self._stop = period, 0, threading.Event()
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        me = psutil.Process()
        while not self._stop.is_set():
            total = 0
            for proc in [me, *me.children(recursive=True)]:
                try:
                    total += proc.memory_info().rss
                except psutil.Error:
                    pass
            self.peak = max(self.peak, total)
            self._stop.wait(self.period)

    def __enter__(self) -> PeakRSS:
        self.thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self.thread.join()


def per_core_rate(n: int = 16384, chunk: int = 4096) -> float:
    """The best of five passes over n variants in chunks, in this process [variants/s]."""
    spec = spec_from_dict(bench_spec(n, chunk))
    table = spec.random_table()
    run_chunk(spec.source, 0, 64, spec.random_rows(table, 0, 64))  # compile and warm up
    best = 0.0
    for _ in range(5):
        start = time.perf_counter()
        for a in range(0, n, chunk):
            run_chunk(spec.source, a, a + chunk, spec.random_rows(table, a, a + chunk))
        best = max(best, n / (time.perf_counter() - start))
    return best


def compiled_batch_rate(n: int = 4096) -> float:
    """The in-process compiled batch (``simulate_batch(backend="compiled")``) on the same
    variants, dense outputs at the 1,501 times, best of 3 [variants/s]."""
    from rrt_pin.core.grid import time_grid
    from rrt_pin.simulate import simulate_batch
    from rrt_pin.simulate.control import chapter_controller

    spec = spec_from_dict(bench_spec(n))
    values = spec.values(0, n)
    plants = [Params(**{k: float(v[i]) for k, v in values.items()}) for i in range(n)]
    laws = [chapter_controller(p) for p in plants]
    q0s = np.array([p.q0 for p in plants])
    t = time_grid(15.0, 0.01)
    from rrt_pin.robot.robots import chapter_arm

    arm = chapter_arm(plants[0])
    simulate_batch(arm, laws[:8], q0s[:8], None, t, backend="compiled", params=plants[:8])
    best = 0.0
    for _ in range(3):
        start = time.perf_counter()
        simulate_batch(arm, laws, q0s, None, t, backend="compiled", params=plants)
        best = max(best, n / (time.perf_counter() - start))
    return best


def _pool_worker(args: tuple[int, int]) -> int:
    n, chunk = args
    return int(per_core_rate(n, chunk))


def side_by_side(workers: int) -> list[int]:
    """The per-core rate of ``workers`` processes running at once (no Dask) [variants/s each]."""
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(workers) as pool:
        return list(pool.map(_pool_worker, [(16384, 4096)] * workers))


def pool_sweep(n: int, workers: int) -> float:
    """The same chunks on a plain process pool (concurrent.futures), written nowhere [s]."""
    from concurrent.futures import ProcessPoolExecutor

    spec = spec_from_dict(bench_spec(n))
    table = spec.random_table()
    start = time.perf_counter()
    with ProcessPoolExecutor(workers) as pool:
        jobs = [pool.submit(run_chunk, spec.source, a, b, spec.random_rows(table, a, b))
                for a, b in spec.chunks]  # fmt: skip
        for job in jobs:
            job.result()
    return time.perf_counter() - start


def processes_sweep(n: int, workers: int, folder: Path) -> float:
    """The sweep on a LocalCluster of single-threaded worker processes (started first) [s]."""
    from distributed import LocalCluster

    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                      dashboard_address=None) as cluster:  # fmt: skip
        start = time.perf_counter()
        sweep(bench_spec(n), folder / "processes", scheduler=cluster.scheduler_address,
              progress=False)  # fmt: skip
        return time.perf_counter() - start


def accuracy(out: Path, spec: dict) -> float:
    import pyarrow.parquet as pq

    from rrt_pin.core.grid import time_grid
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.simulate import simulate
    from rrt_pin.simulate.control import regulator

    table = pq.read_table(out / "chunks" / "chunk-000000.parquet")
    names = list(spec["vary"])
    worst = 0.0
    for i in (0, 17, 500):
        p = Params(**{n: float(table.column(n)[i].as_py()) for n in names})
        arm = chapter_arm(p)
        run = simulate(arm, regulator(arm), p.q0, p.qd0, time_grid(15.0, 0.01), backend="compiled")
        for k, q in enumerate(("q1", "q2", "q3")):
            got = table.column(f"final_error_{q}")[i].as_py()
            worst = max(worst, abs(got - abs(run.q[-1, k] - p.qf[k])))
    return worst


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--max", type=int, default=1_000_000, help="largest sweep (default 10^6)")
    ap.add_argument("--workers", type=int, default=2, help="local workers (default 2)")
    args = ap.parse_args()
    core = per_core_rate()
    print(f"1. per core (in process, chunks of 4,096, best of 5): {core:,.0f} variants/s")
    batch = compiled_batch_rate()
    print(f"   the in-process compiled batch (simulate_batch, backend compiled, dense outputs): "
          f"{batch:,.0f} variants/s")  # fmt: skip
    both = side_by_side(args.workers)
    print(f"   {args.workers} such processes at once (no Dask): "
          f"{', '.join(f'{r:,}' for r in both)} variants/s each, {sum(both):,} in all "
          f"({sum(both) / (args.workers * core):.0%} of {args.workers} × one alone)")  # fmt: skip
    print(f"\n2. rrt_pin.sweep on Dask's LocalCluster (one worker, {args.workers} threads; the "
          "default), metrics only, cluster start included")  # fmt: skip
    print(
        f"{'variants':>10} {'wall [s]':>9} {'variants/s':>11} {'efficiency':>10} {'peak RSS':>10}"
    )
    rows, last_out = [], None
    sizes = [n for n in (1_000, 10_000, 100_000, 1_000_000, 10_000_000) if n <= args.max]
    folder = Path(tempfile.mkdtemp(prefix="bench-sweep-"))
    try:
        for n in sizes:
            spec = bench_spec(n)
            out = folder / f"n{n}"
            marks: list[tuple[float, int]] = []
            with PeakRSS() as mem:
                result = sweep(
                    spec,
                    out,
                    workers=args.workers,
                    progress=False,
                    on_chunk=lambda k, c, marks=marks: marks.append(
                        (time.perf_counter(), len(c["index"]), c["seconds"])
                    ),
                )
            rate = n / result.wall_time
            eff = rate / (args.workers * core)
            # steady state: after the first chunk is back (cluster start and warm-up excluded)
            steady = (sum(m[1] for m in marks[1:]) / (marks[-1][0] - marks[0][0])
                      if len(marks) > 2 else float("nan"))  # fmt: skip
            busy = sum(m[2] for m in marks) / (args.workers * result.wall_time)
            rows.append((n, result.wall_time, rate, eff, mem.peak, steady / (args.workers * core)))
            print(f"{n:>10,} {result.wall_time:>9.1f} {rate:>11,.0f} {eff:>9.0%} "
                  f"{rows[-1][5]:>8.0%} {mem.peak / 2**20:>7.0f} MiB  workers busy {busy:.0%}",
                  flush=True)  # fmt: skip
            last_out = (out, spec)
        pool_n = min(args.max, 300_000)
        pool_wall = pool_sweep(pool_n, args.workers)
        print(f"\n   the alternatives on {pool_n:,} variants: a plain process pool "
              f"(concurrent.futures, nothing written) {pool_n / pool_wall:,.0f} variants/s; "
              f"Dask with {args.workers} worker processes "
              f"{pool_n / processes_sweep(pool_n, args.workers, folder):,.0f} variants/s")  # fmt: skip
        err = accuracy(*last_out)
        print(
            f"\n3. metrics of sampled variants vs single simulate() runs: max difference {err:.1e}"
        )
    finally:
        shutil.rmtree(folder, ignore_errors=True)
    n, wall, rate, eff, peak, steady_eff = rows[-1]
    print()
    checks = [
        (f"{n:,} variants <= 5 min ({wall / 60:.2f} min)", n < 1_000_000 or wall <= 300),
        (
            f"peak memory <= 1 GiB ({max(r[4] for r in rows) / 2**20:.0f} MiB)",
            max(r[4] for r in rows) <= 2**30,
        ),  # fmt: skip
        (
            f"Dask's per-core rate >= 90 % of the in-process compiled batch's at {n:,} "
            f"({rate / args.workers:,.0f} vs {batch:,.0f} variants/s: "
            f"{rate / (args.workers * batch):.0%})",
            rate / (args.workers * batch) >= 0.9,
        ),
        (
            f"... and >= 90 % of run_chunk's own rate, metrics included, in one process "
            f"(whole run {eff:.0%}, steady state {steady_eff:.0%}; {rate / sum(both):.0%} of "
            f"{args.workers} such processes at once)",
            eff >= 0.9,
        ),
        (f"metrics equal single runs to 1e-9 ({err:.1e})", err <= 1e-9),
    ]
    for text, ok in checks:
        print(f"target {text}: {'met' if ok else 'MISSED'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
