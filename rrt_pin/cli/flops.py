"""How close the kernels come to the machine's arithmetic limit.

Each closed-form kernel has a known operation count a sample (counted in its
generated source by :func:`rrt_pin.dynamics.symbolic.codegen.flop_count`), so its
measured time a sample gives a rate in flop/s; :func:`fma_rate` measures the
limit that rate is compared with: independent fused multiply-adds on one core
(2 flops each), the most a core does. The fraction of that limit says how much
speed is left on the table by the arithmetic (the rest is memory, sine and
cosine, branches and call overhead). Counts and the rate need numba for the
compiled kernels; without it the compiled rows are absent.
"""

from __future__ import annotations

import time
from dataclasses import astuple, dataclass, fields

import numpy as np

from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics import kernel
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import get
from rrt_pin.simulate.codes import SINCOS_FLOPS
from rrt_pin.simulate.control import chapter_controller

__all__ = [
    "KernelRow",
    "closed_loop_kernel",
    "closed_loop_ns",
    "fma_rate",
    "generated_kernels",
    "kernel_flops",
    "kernel_rows",
]

#: Robots whose generated RNEA ``rrt-pin bench`` times (example-robot-data names).
GENERATED_ROBOTS = ("ur5", "panda")

#: The closed loop's evaluation beyond ``forward_terms`` and the sine/cosine: eq. (31)'s
#: PD part (15), gravity (3), the residuals (5) and 3 divisions (the diagonal M).
_CLOSED_LOOP_EXTRA = 26


@dataclass(frozen=True)
class KernelRow:
    """One kernel's speed against the machine's limit.

    Attributes:
        kernel: what was timed.
        ns_per_sample: median time a sample (or a state) [ns].
        flops: floating-point operations a sample (0: not counted).
        gflops: flops / ns_per_sample [Gflop/s] (nan when not counted).
        fma_gflops: the machine's limit on one core, 2 × FMA/s [Gflop/s].
        fraction: gflops / fma_gflops (nan when not counted).
    """

    kernel: str
    ns_per_sample: float
    flops: int
    gflops: float
    fma_gflops: float
    fraction: float

    @staticmethod
    def header() -> list[str]:
        """Column names, in order."""
        return [f.name for f in fields(KernelRow)]

    def values(self) -> tuple:
        """The row's values, in header order."""
        return astuple(self)


def kernel_flops() -> dict[str, int]:
    """Operations a sample of each counted kernel, by the name :func:`kernel_rows` uses.

    ``symbolic inverse`` excludes its sine and cosine (numpy calls libm);
    the compiled kernels include theirs (one vectorizable reduction for both).
    Needs no numba (the counts are constants).
    """
    return {
        "symbolic inverse": kernel.INVERSE_FLOPS,
        "compiled inverse": kernel.INVERSE_FLOPS + SINCOS_FLOPS,
        "compiled closed loop (per state)": (
            kernel.FORWARD_FLOPS + SINCOS_FLOPS + _CLOSED_LOOP_EXTRA
        ),
    }


def fma_rate(seconds: float = 0.3, fused: bool = True) -> float | None:
    """Fused multiply-adds a second on one core, best of runs for ``seconds`` [FMA/s].

    Eight independent chains ``v = v·a + b`` over an array that stays in L1, compiled
    by numba with contraction to FMA allowed: the throughput limit, not a latency.
    ``fused=False``: a multiply and an add each, as kernels compiled without fast-math
    run them [pairs/s]. None without numba.
    """
    try:
        import numba
    except ImportError:
        return None

    def chains(y, a, b, reps):  # noqa: ANN001, ANN202
        for _ in range(reps):
            for i in range(y.shape[0]):
                v = y[i]
                v = v * a + b
                v = v * a + b
                v = v * a + b
                v = v * a + b
                v = v * a + b
                v = v * a + b
                v = v * a + b
                v = v * a + b
                y[i] = v
        return y[0]

    chains = numba.njit(fastmath={"contract"} if fused else False)(chains)
    y = np.full(1024, 0.5)
    a, b = 0.999999, 1e-7
    chains(y, a, b, 1)
    best = 0.0
    end = time.perf_counter() + seconds
    while time.perf_counter() < end:
        start = time.perf_counter()
        chains(y, a, b, 2000)
        best = max(best, 8 * 1024 * 2000 / (time.perf_counter() - start))
    return best


def kernel_rows(
    ns_per_sample: dict[str, float], rate: float | None, counts: dict[str, int] | None = None
) -> list[KernelRow]:
    """Rows for measured kernels: ``ns_per_sample`` by kernel name, ``rate`` from :func:`fma_rate`.

    ``counts``: operation counts of kernels beyond :func:`kernel_flops`'s (by name).
    """
    counts = {**kernel_flops(), **(counts or {})}
    peak = 2.0 * rate / 1e9 if rate else float("nan")
    rows = []
    for name, ns in ns_per_sample.items():
        flops = counts.get(name, 0)
        gflops = flops / ns if flops else float("nan")
        rows.append(KernelRow(name, ns, flops, gflops, peak, gflops / peak))
    return rows


def generated_kernels(
    robots: tuple[str, ...] = GENERATED_ROBOTS, repeats: int = 7, samples: int = 15_001
) -> tuple[dict[str, float], dict[str, int]]:
    """ns/sample and flops a sample of the RNEA generated for each robot; ({}, {}) without numba.

    One thread, the kernel alone (no checks around it), over ``samples`` states of a
    rest-to-rest motion (0.2..0.8 rad or m per joint in 15 s), median of ``repeats``;
    compiling (or loading) each kernel is paid before. The flops count the kernel's
    polynomial sines and cosines (it runs them vectorised across samples).
    """
    try:
        import numba  # noqa: F401
    except ImportError:
        return {}, {}
    from rrt_pin.compiled import rnea

    ns: dict[str, float] = {}
    counts: dict[str, int] = {}
    for name in robots:
        robot = get(name)
        kernel = rnea.kernel_for(robot.model)
        n = robot.nv
        m = rest_to_rest(np.zeros(n), np.linspace(0.2, 0.8, n), 15.0, np.linspace(0, 15, samples))
        q = np.ascontiguousarray(robot.configuration(m.q))
        qd, qdd = np.ascontiguousarray(m.qd), np.ascontiguousarray(m.qdd)
        out = np.empty((samples, n))
        kernel.kernel(q, qd, qdd, out)
        times = []
        for _ in range(repeats):
            start = time.perf_counter()
            kernel.kernel(q, qd, qdd, out)
            times.append(time.perf_counter() - start)
        label = f"compiled inverse generated for {robot.name}"
        ns[label] = 1e9 * float(np.median(times)) / samples
        counts[label] = kernel.all_flops
    return ns, counts


def closed_loop_kernel():  # noqa: ANN201
    """A compiled loop evaluating the closed loop's dynamics (inlined) once per state.

    ``run(kind, p, c, q, qd, out)`` writes q̈ (N, 3) [rad/s², m/s²] of the states
    (q, qd) (N, 3) under the controller ``(kind, c)`` on the arm ``p``: what the
    direct run's right-hand side computes. Needs numba (ImportError without it).
    """
    import numba

    from rrt_pin.compiled import _jit_dynamics as jd

    closed_loop, as_p, as_c = jd.closed_loop_inline, jd.as_tuple_p, jd.as_tuple_c

    @numba.njit
    def run(kind, p, c, q, qd, out):  # noqa: ANN001, ANN202
        pt, ct = as_p(p), as_c(c)
        for i in range(q.shape[0]):
            a1, a2, a3, _, _, _, _ = closed_loop(
                kind, ct, pt, q[i, 0], q[i, 1], q[i, 2], qd[i, 0], qd[i, 1], qd[i, 2]
            )
            out[i, 0] = a1
            out[i, 1] = a2
            out[i, 2] = a3

    return run


def closed_loop_ns(repeats: int = 7) -> float | None:
    """Median time of the compiled closed loop's evaluation, per state [ns].

    Eq. (31) on the chapter's arm (the direct run's right-hand side), over the
    15,001 states of the chapter's motion; None without numba.
    """
    try:
        run = closed_loop_kernel()
    except ImportError:
        return None
    from rrt_pin.compiled.dynamics import param_array
    from rrt_pin.compiled.integrate import _controller_arrays

    p = Params()
    pa = param_array(p)
    kind, c = _controller_arrays(chapter_controller(p), p, pa)
    traj = rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, 1e-3))
    q, qd = np.ascontiguousarray(traj.q), np.ascontiguousarray(traj.qd)
    out = np.empty_like(q)
    run(kind, pa, c, q, qd, out)
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        for _ in range(10):
            run(kind, pa, c, q, qd, out)
        times.append((time.perf_counter() - start) / 10)
    return float(np.median(times)) / q.shape[0] * 1e9
