#!/usr/bin/env python
"""What a process pays to use the compiled backend: numba's import, the cache load, a compilation.

Every figure is measured in fresh subprocesses (medians over --repeat runs) with
a private, new cache directory, so the user's cache is neither used nor touched:

1. the interpreter alone, ``import numba`` alone, and ``import rrt_pin.compiled`` +
   ``is_compiled()`` (the CLI's check: no numba, reads and hashes the cache record);
2. ``python -X importtime -c "import numba"``: numba's cumulative import time and
   its heaviest dependencies;
3. ``ensure_compiled()`` cold (empty cache: every function compiled, once) and warm
   (all loaded from the cache): whole-process wall time, and the report's split
   into numba's import and the load, the first function's load apart (numba's own
   start-up: LLVM's target, the runtime).

    .venv/bin/python -m scripts.bench.cache [--repeat 7]
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]

ENSURE = """
import json, time
t0 = time.perf_counter()
import rrt_pin.compiled as c
before = c.is_compiled()
t1 = time.perf_counter()
r = c.ensure_compiled()
t2 = time.perf_counter()
first = next(iter(r.functions))
print(json.dumps({"is_compiled": before, "check": t1 - t0, "ensure": t2 - t1,
                  "numba_import": r.numba_import, "load": r.compile, "first": first,
                  "first_load": r.functions[first], "from_cache": r.from_cache}))
"""


def _env(cache: Path) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    env["RRT_PIN_CACHE_DIR"] = str(cache)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(ROOT), env.get("PYTHONPATH")]))
    return env


def wall(code: str, env: dict[str, str], *flags: str) -> tuple[float, str, str]:
    """Wall time [s] of ``python [flags] -c code`` in a fresh process, with its stdout and stderr."""
    start = time.perf_counter()
    out = subprocess.run(
        [sys.executable, *flags, "-c", code], env=env, capture_output=True, text=True, check=True
    )
    return time.perf_counter() - start, out.stdout, out.stderr


def importtime(env: dict[str, str]) -> list[tuple[str, float]]:
    """Cumulative import times [s] of numba and of its big dependencies (-X importtime)."""
    _, _, err = wall("import numba", env, "-X", "importtime")
    found = {}
    for line in err.splitlines():
        if not line.startswith("import time:") or "cumulative" in line:
            continue
        _, cumulative, name = (part.strip() for part in line[len("import time:") :].split("|"))
        found.setdefault(name, int(cumulative) * 1e-6)
    return [(name, found[name]) for name in ("numba", "numpy", "llvmlite.binding") if name in found]


def main() -> int:
    """Print the figures (seconds)."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="runs per warm figure")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="rrt_pin-bench-cache-") as tmp:
        env = _env(Path(tmp) / "cache")
        print(f"python {sys.version.split()[0]}, cache {tmp}, medians of {args.repeat} processes")
        for label, code in (
            ("interpreter only (python -c pass)", "pass"),
            ("import numba", "import numba"),
            (
                "import rrt_pin.compiled; is_compiled()",
                "import rrt_pin.compiled as c; c.is_compiled()",
            ),
        ):
            times = [wall(code, env)[0] for _ in range(args.repeat)]
            print(f"  {label:<48} {statistics.median(times):7.3f} s wall")
        print("  python -X importtime -c 'import numba' (cumulative, numba includes the others):")
        for name, seconds in importtime(env):
            print(f"    {name:<46} {seconds:7.3f} s")

        seconds, out, _ = wall(ENSURE, env)
        cold = json.loads(out)
        assert not cold["is_compiled"] and not cold["from_cache"], cold
        print(
            f"  ensure_compiled() cold (compiles everything)     {seconds:7.3f} s wall "
            f"(numba import {cold['numba_import']:.3f} s, compile {cold['load']:.3f} s)"
        )
        warm = []
        for _ in range(args.repeat):
            seconds, out, _ = wall(ENSURE, env)
            run = json.loads(out)
            assert run["is_compiled"] and run["from_cache"], run
            warm.append((seconds, run))
        med = {k: statistics.median(r[k] for _, r in warm) for k in ("check", "ensure")}
        med.update({k: statistics.median(r[k] for _, r in warm) for k in ("numba_import", "load")})
        first = statistics.median(r["first_load"] for _, r in warm)
        print(
            f"  ensure_compiled() warm (loads the cache)         "
            f"{statistics.median(s for s, _ in warm):7.3f} s wall"
        )
        print(f"    import rrt_pin.compiled + is_compiled()        {med['check']:7.3f} s")
        print(f"    ensure_compiled()                              {med['ensure']:7.3f} s")
        print(f"      numba import                                 {med['numba_import']:7.3f} s")
        print(f"      load of all functions                        {med['load']:7.3f} s")
        label = f"of which the first ({warm[0][1]['first']})"
        print(f"        {label:<42} {first:7.3f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
