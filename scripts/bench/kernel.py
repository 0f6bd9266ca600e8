#!/usr/bin/env python
"""The inverse-dynamics kernels: ns/sample, flops, the machine's FMA rate, and 30-digit accuracy.

Times, in ONE run and interleaved round by round (other processes load the
machine alike on every side; in a round each side runs 4 times, the first not
counted), the median ns/sample of:

* rnea loop        a Python loop calling ``pin.rnea`` once per sample (the baseline);
* rnea batched     ``rrt_pin.inverse_dynamics`` (``pin.rneaInParallel``, all CPUs);
* symbolic         ``inverse_dynamics(backend="symbolic")``: the generated numpy kernel;
* compiled         ``inverse_dynamics(backend="compiled")``: the whole call, checks included;
* compiled kernel  ``_jit_dynamics.inverse_batch`` alone, into a preallocated output;
* forward kernel   the direct run's right-hand side, ``_jit_dynamics.closed_loop_inline``
                   under eq. (31) (``forward_terms``, one division per joint), one state
                   at a time as the adaptive integrators' stage loop calls it;

on the chapter's run (eq. 30, 15,001 samples) and on 10⁶ samples (the chapter's
run repeated; the loop is timed on the first 15,001 and scaled). Next to each
kernel: its floating-point operations a sample (the generator's count of
``inverse_terms`` plus sine and cosine), the rate they run at, and the fraction
of the machine's fused-multiply-add limit, measured here by a numba loop of
independent FMAs over an L1-resident array (2 flops an FMA, one core). Last,
each backend's worst relative error against the 30-digit reference
(``rrt_pin.cli.bench_measure.mpmath_inverse_reference``) at every --stride-th sample.

    .venv/bin/python -m scripts.bench.kernel [--repeat 15] [--big 1000000] [--stride 50] [--check]

Targets: compiled ≤ 12 ns/sample on the chapter's run and at 10⁶, ≥ 120×
the loop; every backend within 1e-15 of the reference. ``--check`` exits 1 when one
is missed.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

import numpy as np

from rrt_pin.robot.robots import chapter_arm
from scripts.bench.common import interleaved

TARGET_NS = 12.0
TARGET_SPEEDUP = 120.0
TARGET_AGREEMENT = 1e-15


def rnea_loop(model, q, qd, qdd) -> np.ndarray:
    import pinocchio as pin

    data = model.createData()
    out = np.empty((q.shape[0], model.nv))
    for i in range(q.shape[0]):
        out[i] = pin.rnea(model, data, q[i], qd[i], qdd[i])
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=15, help="timed rounds (median)")
    ap.add_argument("--big", type=int, default=1_000_000, help="samples of the large case")
    ap.add_argument("--stride", type=int, default=50, help="reference at every n-th sample")
    ap.add_argument("--check", action="store_true", help="exit 1 when a target is missed")
    args = ap.parse_args()

    from rrt_pin import compiled
    from rrt_pin.cli.bench_measure import mpmath_inverse_reference
    from rrt_pin.compiled import _jit_dynamics as jd
    from rrt_pin.compiled.dynamics import param_array
    from rrt_pin.core.grid import time_grid
    from rrt_pin.dynamics import kernel
    from rrt_pin.dynamics.inverse import default_num_threads, inverse_dynamics
    from rrt_pin.dynamics.trajectory import rest_to_rest
    from rrt_pin.robot.model import rrt_model
    from rrt_pin.robot.params import Params

    compiled.ensure_compiled()
    p = Params()
    model = rrt_model(p)
    arm = chapter_arm(p)
    arm.model  # noqa: B018  (its Pinocchio model built before any timing)
    traj = rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, 1e-3))
    pa = param_array(p)
    from rrt_pin.cli.flops import kernel_flops

    counts = kernel_flops()  # the closed loop: forward_terms, vsincos, eq. (31), solve
    forward_flops = counts["compiled closed loop (per state)"]
    flops = {
        "symbolic": f"{kernel.INVERSE_FLOPS} + libm sin, cos",
        "compiled": counts["compiled inverse"],
        "compiled kernel": counts["compiled inverse"],
        "forward kernel": forward_flops,
    }
    from rrt_pin.compiled.integrate import _controller_arrays
    from rrt_pin.simulate.control import chapter_controller

    kind, cvec = _controller_arrays(chapter_controller(p), p, pa)
    from rrt_pin.cli.flops import closed_loop_kernel

    forward = closed_loop_kernel()
    from rrt_pin.cli.flops import fma_rate

    rate = fma_rate()
    peak = 2.0 * rate  # flops/s, every operation an FMA
    print(
        f"FMA rate, one core: {rate / 1e9:.2f} GFMA/s = {peak / 1e9:.2f} Gflop/s; "
        f"{default_num_threads()} CPUs; compiled kernel = {kernel.INVERSE_FLOPS} flops "
        f"(generated inverse_terms) + {jd.SINCOS_FLOPS} (vsincos) a sample; forward kernel "
        f"= {kernel.FORWARD_FLOPS} (forward_terms) + {jd.SINCOS_FLOPS} + "
        f"{forward_flops - kernel.FORWARD_FLOPS - jd.SINCOS_FLOPS} (eq. 31, solve)"
    )

    def cases():
        yield "chapter's run", traj.q, traj.qd, traj.qdd
        reps = -(-args.big // len(traj))
        big = [
            np.ascontiguousarray(np.tile(a, (reps, 1))[: args.big])
            for a in (traj.q, traj.qd, traj.qdd)
        ]
        yield f"{args.big:,} samples", *big

    ok: dict[str, bool] = {}
    for label, q, qd, qdd in cases():
        n = q.shape[0]
        small = min(n, len(traj))
        out = np.empty((n, 3))
        funcs: dict[str, Callable[[], object]] = {
            "rnea loop": lambda q=q, qd=qd, qdd=qdd, small=small: rnea_loop(
                model, q[:small], qd[:small], qdd[:small]
            ),
            "rnea batched": lambda q=q, qd=qd, qdd=qdd: inverse_dynamics(arm, q, qd, qdd),
            "symbolic": lambda q=q, qd=qd, qdd=qdd: inverse_dynamics(
                arm, q, qd, qdd, backend="symbolic"
            ),
            "compiled": lambda q=q, qd=qd, qdd=qdd: inverse_dynamics(
                arm, q, qd, qdd, backend="compiled"
            ),
            "compiled kernel": lambda q=q, qd=qd, qdd=qdd, out=out: jd.inverse_batch(
                q, qd, qdd, pa, out
            ),
            "forward kernel": lambda q=q, qd=qd, out=out: forward(kind, pa, cvec, q, qd, out),
        }
        big = n > 100_000
        repeat = max(3, args.repeat // 3) if big else args.repeat
        medians = interleaved(funcs, repeat, inner=1 if big else 3)
        ns = {k: 1e9 * t / (small if k == "rnea loop" else n) for k, t in medians.items()}
        print(f"\n{label}: {n:,} samples, median of {repeat} interleaved rounds")
        print(
            f"{'side':<16} {'ns/sample':>10} {'× loop':>8} {'flops':>22} {'Gflop/s':>8} "
            f"{'of FMA limit':>12}"
        )
        for k, v in ns.items():
            f = flops.get(k)
            gf = f"{f / v:8.2f}" if isinstance(f, int) else f"{'':>8}"
            frac = f"{f / v / (peak / 1e9):12.1%}" if isinstance(f, int) else f"{'':>12}"
            print(f"{k:<16} {v:>10.2f} {ns['rnea loop'] / v:>7.1f}x {f or '':>22} {gf} {frac}")
        ok[f"compiled ≤ {TARGET_NS:g} ns/sample, {label} ({ns['compiled']:.1f})"] = (
            ns["compiled"] <= TARGET_NS
        )
        speedup = ns["rnea loop"] / ns["compiled"]
        ok[f"compiled ≥ {TARGET_SPEEDUP:g}x the loop, {label} ({speedup:.0f}x)"] = (
            speedup >= TARGET_SPEEDUP
        )

    sel = slice(None, None, args.stride)
    q, qd, qdd = traj.q[sel], traj.qd[sel], traj.qdd[sel]
    ref = mpmath_inverse_reference(q, qd, qdd, p)
    print(f"\nagreement with the 30-digit reference at {len(q)} samples of the chapter's run")
    print(f"{'side':<16} {'T01x':>9} {'T12y':>9} {'F23z':>9}  (max |τ − ref| / max |ref|)")
    results = {
        "pinocchio": inverse_dynamics(arm, q, qd, qdd),
        "symbolic": inverse_dynamics(arm, q, qd, qdd, backend="symbolic"),
        "compiled": inverse_dynamics(arm, q, qd, qdd, backend="compiled"),
    }
    for k, tau in results.items():
        rel = np.abs(tau - ref).max(axis=0) / np.abs(ref).max(axis=0)
        print(f"{k:<16} " + " ".join(f"{x:9.1e}" for x in rel))
        ok[f"{k} within {TARGET_AGREEMENT:g} of the reference ({rel.max():.1e})"] = (
            rel.max() <= TARGET_AGREEMENT
        )
    print()
    for label, good in ok.items():
        print(f"target {label}: {'met' if good else 'MISSED'}")
    return 1 if args.check and not all(ok.values()) else 0


if __name__ == "__main__":
    sys.exit(main())
