#!/usr/bin/env python
"""The generated RNEA of any robot, vectorised across samples: ns/sample, flops, the machine's rates.

Times, in ONE run and interleaved round by round (other processes load the machine
alike on every side; in a round each side runs --inner + 1 times, the first not
counted), the median ns a sample over --samples random states (joint coordinates
uniform in ±3 rad or m, velocities and accelerations normal) of:

* pin.rnea loop      a Python loop calling ``pin.rnea`` once a sample (the baseline);
* one-sample kernel  the generated RNEA as it was compiled before it was vectorised: a
                     loop over rows, one sample at a time, libm's sine and cosine
                     (compiled here in memory, for the comparison);
* vectorised kernel  the kernel ``rrt_pin.compiled.rnea.kernel_for`` gives (blocks of
                     samples as structure of arrays, polynomial sine and cosine), alone,
                     one thread, into a preallocated output;
* inverse_dynamics   ``rrt_pin.inverse_dynamics(robot, ..., backend="compiled",
                     num_threads=1)``: the whole public call (checks, a new output).

Next to each kernel: its floating-point operations a sample (the generator's count, plus
``SINCOS_FLOPS`` a polynomial sine-cosine pair for the vectorised kernel; libm's are not
counted for the one-sample kernel), the rate they run at and its fraction of two limits
measured here on one core by numba loops of independent chains over an L1-resident
array: mul+add (a multiply then an add, no contraction: the operations the kernels
compile to, without fast-math) and FMA (contracted, 2 flops each, the core's most).
Then each side's worst difference from ``pin.rnea`` (max |τ − τ_pin| / max |τ_pin|), and,
with --sizes, the time a call at small batch sizes (one-sample against vectorised).

    .venv/bin/python -m scripts.bench.rnea [--samples 15001] [--repeat 15] [--inner 3]
        [--robots ur5,panda,kinova] [--sizes] [--check]

Targets: 15,001 samples, vectorised kernel UR5 ≤ 60 ns/sample, Panda ≤ 90 ns/sample,
each ≥ 40× the ``pin.rnea`` loop; agreement ≤ 1e-13. ``--check`` exits 1 when one is missed.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from rrt_pin.cli.flops import fma_rate
from rrt_pin.robot import robots
from scripts.bench.common import interleaved, verdict

ROBOTS = ("ur5", "panda", "kinova")
TARGET_NS = {"ur5": 60.0, "panda": 90.0}
TARGET_SPEEDUP = 40.0
TARGET_AGREEMENT = 1e-13


def states(robot, n: int, seed: int = 7) -> tuple[np.ndarray, ...]:
    """n random states: coordinates, velocities, accelerations (N, nv)."""
    rng = np.random.default_rng(seed)
    nv = robot.nv
    return rng.uniform(-3, 3, (n, nv)), rng.normal(0, 2, (n, nv)), rng.normal(0, 5, (n, nv))


def rnea_loop(model: pin.Model, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> np.ndarray:
    """The baseline: one ``pin.rnea`` call a sample from Python."""
    data = model.createData()
    out = np.empty((q.shape[0], model.nv))
    for i in range(q.shape[0]):
        out[i] = pin.rnea(model, data, q[i], qd[i], qdd[i])
    return out


def one_sample_source(gen) -> str:
    """The module the generated RNEA had before it was vectorised: a loop over rows."""
    from rrt_pin.compiled.rnea import _pairwise_sum

    ind = " " * 8
    checked = [f"q[{k}]" for k in range(gen.nq)]
    checked += [f"{x}[{k}]" for x in ("v", "a") for k in range(gen.nv)]
    checked += [t for t in gen.tau if not t[:1].isdigit() and not t.startswith("-")]
    return "\n".join(
        [
            "from math import cos, sin",
            "def kernel(Q, V, A, out):",
            "    check = 0.0",
            "    for i in range(Q.shape[0]):",
            f"{ind}q = Q[i]",
            f"{ind}v = V[i]",
            f"{ind}a = A[i]",
            *(f"{ind}{line}" for line in gen.lines),
            *(f"{ind}out[i, {k}] = {t}" for k, t in enumerate(gen.tau)),
            f"{ind}s = {_pairwise_sum(checked)}",
            f"{ind}check += s - s",
            "    return check",
            "",
        ]
    )


def one_sample_kernel(model: pin.Model) -> Callable:
    """The one-sample kernel of ``model``, compiled in memory (as numba compiled it before)."""
    import numba

    from rrt_pin.compiled.rnea import _signature
    from rrt_pin.dynamics.rnea_source import rnea_source

    scope: dict = {}
    exec(compile(one_sample_source(rnea_source(model)), "<one-sample>", "exec"), scope)  # noqa: S102
    return numba.njit(_signature(numba), nogil=True, error_model="numpy")(scope["kernel"])


def worst(tau: np.ndarray, ref: np.ndarray) -> float:
    return float(np.abs(tau - ref).max() / np.abs(ref).max())


def bench(name: str, n: int, repeat: int, inner: int, rates: dict[str, float]) -> dict:
    import rrt_pin
    from rrt_pin.compiled import rnea

    robot = robots.get(name)
    model = robot.model
    kernel = rnea.kernel_for(model)
    start = time.perf_counter()
    before = one_sample_kernel(model)
    compile_before = time.perf_counter() - start
    x, qd, qdd = states(robot, n)
    q = np.ascontiguousarray(robot.configuration(x))
    out = {k: np.empty((n, robot.nv)) for k in ("one", "vec")}
    sides: dict[str, Callable[[], object]] = {
        "pin.rnea loop": lambda: rnea_loop(model, q, qd, qdd),
        "one-sample kernel": lambda: before(q, qd, qdd, out["one"]),
        "vectorised kernel": lambda: kernel.kernel(q, qd, qdd, out["vec"]),
        "inverse_dynamics": lambda: rrt_pin.inverse_dynamics(
            robot, x, qd, qdd, backend="compiled", num_threads=1
        ),
    }
    ref = rnea_loop(model, q, qd, qdd)
    results = {
        "pin.rnea loop": ref,
        "one-sample kernel": (before(q, qd, qdd, out["one"]), out["one"].copy())[1],
        "vectorised kernel": (kernel.kernel(q, qd, qdd, out["vec"]), out["vec"].copy())[1],
        "inverse_dynamics": sides["inverse_dynamics"](),
    }
    flops = {"one-sample kernel": kernel.flops, "vectorised kernel": kernel.all_flops}
    medians = interleaved(sides, repeat, inner)
    ns = {k: 1e9 * t / n for k, t in medians.items()}
    print(
        f"\n{name}: nq={model.nq}, nv={model.nv}, {n:,} samples, median of {repeat} rounds x "
        f"{inner} calls; vectorised kernel {kernel.origin} in {kernel.seconds:.2f} s, "
        f"one-sample kernel compiled in {compile_before:.2f} s"
    )
    print(
        f"{'side':<18} {'ns/sample':>9} {'x loop':>7} {'flops':>6} {'Gflop/s':>8} "
        f"{'of mul+add':>10} {'of FMA':>7} {'max rel':>9}"
    )
    for side, value in ns.items():
        f = flops.get(side)
        if f:
            gf = f / value
            rate = f"{f:>6} {gf:>8.2f} {gf / rates['mul+add']:>10.1%} {gf / rates['fma']:>7.1%}"
        else:
            rate = f"{'':>6} {'':>8} {'':>10} {'':>7}"
        print(
            f"{side:<18} {value:>9.1f} {ns['pin.rnea loop'] / value:>6.1f}x {rate} "
            f"{worst(results[side], ref):>9.1e}"
        )
    print(
        f"flops a sample: {kernel.flops} RNEA + {kernel.sincos} sine-cosine pairs "
        f"({kernel.all_flops - kernel.flops} as polynomials; the one-sample kernel calls libm "
        f"{kernel.transcendentals} times instead); vectorised / one-sample = "
        f"{ns['one-sample kernel'] / ns['vectorised kernel']:.2f}x"
    )
    return {
        "ns": ns["vectorised kernel"],
        "speedup": ns["pin.rnea loop"] / ns["vectorised kernel"],
        "agreement": worst(results["vectorised kernel"], ref),
    }


def sizes(name: str, repeat: int) -> None:
    """ns a call of the one-sample and the vectorised kernel at small batch sizes."""
    from rrt_pin.compiled import rnea

    robot = robots.get(name)
    kernel, before = rnea.kernel_for(robot.model), one_sample_kernel(robot.model)
    print(f"\n{name}: ns a call (kernel alone, one thread), median of {repeat} rounds x 20")
    print(f"{'samples':>8} {'one-sample':>11} {'vectorised':>11} {'ratio':>6}")
    for n in (1, 4, 16, 64, 128, 129, 1000):
        x, qd, qdd = states(robot, n, seed=n)
        q = np.ascontiguousarray(robot.configuration(x))
        out = np.empty((n, robot.nv))
        med = interleaved(
            {
                "one": lambda q=q, qd=qd, qdd=qdd, out=out: before(q, qd, qdd, out),
                "vec": lambda q=q, qd=qd, qdd=qdd, out=out: kernel.kernel(q, qd, qdd, out),
            },
            repeat,
            20,
        )
        one, vec = med["one"] * 1e9, med["vec"] * 1e9
        print(f"{n:>8} {one:>11.0f} {vec:>11.0f} {one / vec:>5.2f}x")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=15_001, help="samples a call")
    ap.add_argument("--repeat", type=int, default=15, help="timed rounds (median)")
    ap.add_argument("--inner", type=int, default=3, help="timed calls a side a round")
    ap.add_argument("--robots", default=",".join(ROBOTS), help="comma-separated robot names")
    ap.add_argument("--sizes", action="store_true", help="also time small batches")
    ap.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    args = ap.parse_args()
    rates = {"mul+add": 2 * fma_rate(fused=False) / 1e9, "fma": 2 * fma_rate() / 1e9}
    print(
        f"pinocchio {pin.__version__}, numpy {np.__version__}; one core: "
        f"mul+add {rates['mul+add']:.1f} Gflop/s (a multiply and an add), "
        f"FMA {rates['fma']:.1f} Gflop/s (2 flops an FMA)"
    )
    ok: dict[str, bool] = {}
    for name in args.robots.split(","):
        got = bench(name, args.samples, args.repeat, args.inner, rates)
        if name in TARGET_NS:
            ok[f"{name} ≤ {TARGET_NS[name]:g} ns/sample ({got['ns']:.1f})"] = (
                got["ns"] <= TARGET_NS[name]
            )
            ok[f"{name} ≥ {TARGET_SPEEDUP:g}x the pin.rnea loop ({got['speedup']:.0f}x)"] = (
                got["speedup"] >= TARGET_SPEEDUP
            )
        ok[f"{name} within {TARGET_AGREEMENT:g} of pin.rnea ({got['agreement']:.1e})"] = (
            got["agreement"] <= TARGET_AGREEMENT
        )
    if args.sizes:
        for name in args.robots.split(",")[:2]:
            sizes(name, args.repeat)
    print()
    for label, good in ok.items():
        print(f"target {label}: {verdict(good)}")
    return 1 if args.check and not all(ok.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
