#!/usr/bin/env python3
"""Ahead-of-time compilation (numba.pycc) against the JIT cache: what a process pays.

The compiled backend's machine code lives in numba's disk cache; a process that
uses it first imports numba and loads the cache (~0.75 s). An ahead-of-time module
(``numba.pycc``) is a plain extension module: importing it needs numpy only. This
script builds one holding the inverse-dynamics kernel ``inverse_batch`` (the same
Python source as the JIT's, with its inlined callees), then times in fresh
processes, interleaved (medians of --repeat rounds):

* ``floor``: ``import numpy``;
* ``jit``: import the compiled backend, load ``inverse_batch`` from the cache, call it once;
* ``aot``: import the ahead-of-time module, call it once;

and in one process the kernel's ns/sample on the chapter's 15,001 samples both ways
(the efforts must agree bit for bit). It also reports the one-time build cost.

    .venv/bin/python -m scripts.bench.aot [--repeat 9]
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

import numpy as np

ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
SIG = "f8(f8[:,::1], f8[:,::1], f8[:,::1], f8[::1], f8[:,::1])"

CALL = """
import numpy as np
q = np.zeros((15001, 3)); q[:, 2] = 0.2
p = np.linspace(1.0, 2.0, 15)
out = np.empty((15001, 3))
"""


def build(out_dir: Path) -> float:
    """Build the ahead-of-time module ``rrt_aot`` into ``out_dir``; seconds taken."""
    start = time.perf_counter()
    code = (
        "from numba.pycc import CC\n"
        "from rrt_pin.compiled import _jit_dynamics as jd\n"
        f"cc = CC('rrt_aot'); cc.output_dir = {str(out_dir)!r}; cc.verbose = False; cc.target_cpu = 'host'\n"
        f"cc.export('inverse_batch', {SIG!r})(jd.inverse_batch.py_func)\n"
        "cc.compile()\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, env=ENV)
    return time.perf_counter() - start


def _seconds(argv: list[str], env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run(argv, check=True, env=env, stdout=subprocess.DEVNULL)
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=9)
    args = parser.parse_args()
    from rrt_pin import compiled
    from rrt_pin.dynamics import kernel
    from rrt_pin.dynamics.trajectory import rest_to_rest
    from rrt_pin.robot.params import Params
    from rrt_pin.robot.robots import chapter_arm

    compiled.ensure_compiled()  # the JIT cache exists before timing its loads
    with tempfile.TemporaryDirectory() as d:
        seconds = build(Path(d))
        print(f"ahead-of-time build of inverse_batch: {seconds:.1f} s (once per install)")
        env = dict(ENV, PYTHONPATH=os.pathsep.join([d, *sys.path]))
        py = sys.executable
        jobs = {
            "floor (import numpy)": [py, "-c", "import numpy"],
            "jit (cache load + call)": [
                py, "-c", CALL + "from rrt_pin.compiled import _jit_dynamics as jd\n"
                "jd.inverse_batch(q, q, q, p, out)\n",
            ],
            "aot (import + call)": [
                py, "-c", CALL + "import rrt_aot\nrrt_aot.inverse_batch(q, q, q, p, out)\n"
            ],
        }  # fmt: skip
        for argv in jobs.values():
            _seconds(argv, env)
        times: dict[str, list[float]] = {k: [] for k in jobs}
        for _ in range(args.repeat):
            for name, argv in jobs.items():
                times[name].append(_seconds(argv, env))
        print(f"\n{'process':<26} {'median [s]':>10}")
        for name, ts in times.items():
            print(f"{name:<26} {statistics.median(ts):>10.3f}")

        sys.path.insert(0, d)
        import rrt_aot

        from rrt_pin.compiled import _jit_dynamics as jd

        arm = chapter_arm()
        m = rest_to_rest(arm.defaults.q0, arm.defaults.qf, 15.0, np.linspace(0, 15, 15_001))
        p = np.array([getattr(Params(), k) for k in kernel.PARAM_ORDER])
        q, qd, qdd = (np.ascontiguousarray(a) for a in (m.q, m.qd, m.qdd))
        a, b = np.empty_like(q), np.empty_like(q)
        sides = {"jit": lambda: jd.inverse_batch(q, qd, qdd, p, a),
                 "aot": lambda: rrt_aot.inverse_batch(q, qd, qdd, p, b)}  # fmt: skip
        ns: dict[str, list[float]] = {k: [] for k in sides}
        for _ in range(max(15, args.repeat)):
            for name, f in sides.items():
                f()
                start = time.perf_counter()
                for _ in range(20):
                    f()
                ns[name].append((time.perf_counter() - start) / 20 / q.shape[0] * 1e9)
        same = np.array_equal(a, b)
        print(f"\n{'kernel (15,001 samples)':<26} {'ns/sample':>10}")
        for name, v in ns.items():
            print(f"{name:<26} {statistics.median(v):>10.2f}")
        print(f"same efforts bit for bit: {same}")


if __name__ == "__main__":
    main()
