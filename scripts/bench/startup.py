#!/usr/bin/env python3
"""Whole-process time of the CLI's two jobs against the floor of importing Pinocchio.

Each round runs, interleaved, every process once in each of two environments:
``python -c "import pinocchio"`` (the floor: any run of the engine of record pays it),
``rrt-pin inverse --csv`` and ``rrt-pin simulate --csv`` (the chapter's jobs, default
backend: compiled where its code is built, as the benchmark's machine has it), and the
two jobs on each backend named (where nothing is built yet, the default is the arm's
numpy kernel for ``inverse`` and Pinocchio for ``simulate``).

* ``.pyc written``: Python's bytecode cache as a user's shell has it. The processes
  write and read their ``.pyc`` under a private ``PYTHONPYCACHEPREFIX`` (the first,
  untimed round writes them), so they leave the checkout's ``__pycache__`` alone.
* ``PYTHONDONTWRITEBYTECODE=1`` (containers, CI images, this VM's shell): no process
  writes a ``.pyc``; rrt-pin's modules load from what the install step compiled
  (``scripts/_venv.sh``), and any module without a current ``.pyc`` is compiled again
  in every process.

Prints medians of --repeat rounds [s], each job's ratio to the floor in the same
environment (target: at most 1.3 for the default jobs), and how many modules each
process compiles from source (counted once, after the timed rounds, through
importlib's ``SourceLoader.source_to_code``).

    .venv/bin/python -m scripts.bench.startup [--repeat 15] [--markdown] [--skip-compiled]

The CLI loads numpy's and scipy's OpenBLAS with one thread (unless
``OPENBLAS_NUM_THREADS`` is set): the floor, a plain ``import pinocchio``, starts
numpy's pool of threads, which spin beside it for a while.
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

from scripts.bench.common import verdict

#: Default jobs: at most this many times ``import pinocchio`` in the same environment.
TARGET_RATIO = 1.3

#: Runs a command as ``python -m`` would and prints how many modules it compiled from
#: source (all, then rrt_pin's), hooking the one method that compiles them.
_COUNTER = """\
import importlib._bootstrap_external as be, runpy, sys
compiled = []
source_to_code = be.SourceLoader.source_to_code
def counting(self, data, path, *args, **kwargs):
    compiled.append(str(path))
    return source_to_code(self, data, path, *args, **kwargs)
be.SourceLoader.source_to_code = counting
sys.argv = [sys.argv[0], *sys.argv[2:]]
try:
    if {module!r}:
        runpy.run_module({module!r}, run_name="__main__", alter_sys=True)
    else:
        exec(compile({code!r}, "<string>", "exec"), {{"__name__": "__main__"}})
except SystemExit:
    pass
mine = [p for p in compiled if {package!r} in p]
print(len(compiled), len(mine), file=sys.__stderr__)
"""


def _environments(prefix: str) -> dict[str, dict[str, str]]:
    base = {k: v for k, v in os.environ.items()  # the default backend is what is timed
            if k not in ("PYTHONDONTWRITEBYTECODE", "PYTHONPYCACHEPREFIX", "RRT_PIN_BACKEND")}  # fmt: skip
    return {
        ".pyc written": {**base, "PYTHONPYCACHEPREFIX": prefix},
        "PYTHONDONTWRITEBYTECODE=1": {**base, "PYTHONDONTWRITEBYTECODE": "1"},
    }


def _seconds(argv: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    return time.perf_counter() - start


def _compiled(argv: list[str], env: dict[str, str]) -> tuple[int, int]:
    """How many modules (all, rrt_pin's) the process ``argv`` compiles from source."""
    py, flag, rest = argv[0], argv[1], argv[2:]
    if flag == "-m":
        code = _COUNTER.format(module=rest[0], code="", package=f"{os.sep}rrt_pin{os.sep}")
        args = rest[1:]
    else:  # -c CODE
        code = _COUNTER.format(module="", code=rest[0], package=f"{os.sep}rrt_pin{os.sep}")
        args = rest[1:]
    proc = subprocess.run([py, "-c", code, "-", *args], env=env, stdout=subprocess.DEVNULL,
                          stderr=subprocess.PIPE, text=True, check=True)  # fmt: skip
    total, mine = proc.stderr.split()[-2:]
    return int(total), int(mine)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    parser.add_argument("--markdown", action="store_true", help="print a Markdown table")
    parser.add_argument("--skip-compiled", action="store_true",
                        help="leave out the two --backend compiled jobs (in a checkout where "
                        "nothing is built they would compile first)")  # fmt: skip
    opts = parser.parse_args()
    py = sys.executable
    with tempfile.TemporaryDirectory() as d:
        jobs = {
            "import pinocchio": [py, "-c", "import pinocchio"],
            "rrt-pin inverse --csv": [py, "-m", "rrt_pin", "inverse", "--csv", f"{d}/i.csv"],
            "rrt-pin simulate --csv": [py, "-m", "rrt_pin", "simulate", "--csv", f"{d}/s.csv"],
            # The defaults where no compiled code is built yet: the arm's numpy kernel
            # for inverse dynamics, Pinocchio for simulations.
            "inverse --backend symbolic": [
                py, "-m", "rrt_pin", "inverse", "--backend", "symbolic", "--csv", f"{d}/n.csv",
            ],
            "inverse --backend pinocchio": [
                py, "-m", "rrt_pin", "inverse", "--backend", "pinocchio", "--csv", f"{d}/p.csv",
            ],
            "simulate --backend pinocchio": [
                py, "-m", "rrt_pin", "simulate", "--backend", "pinocchio", "--csv", f"{d}/q.csv",
            ],
            # The compiled backend: its dynamics built ahead of time load without numba.
            "inverse --backend compiled": [
                py, "-m", "rrt_pin", "inverse", "--backend", "compiled", "--csv", f"{d}/c.csv",
            ],
            "simulate --backend compiled": [
                py, "-m", "rrt_pin", "simulate", "--backend", "compiled", "--csv", f"{d}/d.csv",
            ],
        }  # fmt: skip
        if opts.skip_compiled:
            jobs = {name: argv for name, argv in jobs.items() if "compiled" not in name}
        envs = _environments(str(Path(d) / "pycache"))
        sides = [(job, env) for env in envs for job in jobs]
        for job, env in sides:  # warm the page cache; the first environment writes its .pyc
            _seconds(jobs[job], envs[env])
        times: dict[tuple[str, str], list[float]] = {side: [] for side in sides}
        for _ in range(opts.repeat):
            for job, env in sides:
                times[(job, env)].append(_seconds(jobs[job], envs[env]))
        compiled = {(job, env): _compiled(jobs[job], envs[env]) for job, env in sides}
    medians = {side: statistics.median(ts) for side, ts in times.items()}
    rows = []
    for job, env in sides:
        ratio = medians[(job, env)] / medians[("import pinocchio", env)]
        judged = job.endswith("--csv") or job.split()[-1] in ("pinocchio", "symbolic")
        target = f"≤ {TARGET_RATIO} ({verdict(ratio <= TARGET_RATIO)})" if judged else ""
        total, mine = compiled[(job, env)]
        rows.append((job, env, f"{medians[(job, env)]:.3f}", f"{ratio:.2f}", target,
                     f"{total} ({mine} rrt_pin)"))  # fmt: skip
    head = ("process", "environment", "median [s]", "× import pinocchio", "target",
            "modules compiled")  # fmt: skip
    print(f"{opts.repeat} interleaved rounds, medians; Python {sys.version.split()[0]}")
    if opts.markdown:
        print("| " + " | ".join(head) + " |")
        print("| --- | --- | ---: | ---: | --- | ---: |")
        for row in rows:
            print("| " + " | ".join(row) + " |")
        return
    widths = [max(len(r[i]) for r in [head, *rows]) for i in range(len(head))]
    for row in [head, *rows]:
        print("  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in
                        enumerate(zip(row, widths, strict=True))))  # fmt: skip


if __name__ == "__main__":
    main()
