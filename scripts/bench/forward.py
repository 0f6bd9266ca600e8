#!/usr/bin/env python
"""Generated forward dynamics of UR5 and Panda: ABA against CRBA + LDLᵀ against ``pin.aba``.

Times, in ONE run and interleaved round by round (other processes load the machine
alike on every side; in a round each side runs --inner + 1 times, the first not
counted), the median ns a state of, over --samples random states (joint angles
uniform in ±3 rad, velocities and efforts normal):

* aba kernel       the generated articulated-body algorithm (``forward_aba``) alone,
                   one thread, into a preallocated output;
* crba kernel      the generated CRBA + bias + unrolled sparse LDLᵀ (``forward_crba``),
                   the same way;
* forward_dynamics ``ForwardKernels.forward_dynamics`` on one thread: the whole call
                   (conversions, shape checks, a new output) of the default variant;
* pin.aba loop     a Python loop calling ``pin.aba`` once a state (the baseline).

Next to each kernel: its floating-point operations a state (the generator's count,
sines and cosines apart) and ns a flop; then each side's worst difference from
``pin.aba`` (per joint, relative to that joint's peak |q̈|) and the ratios.

With ``--accuracy N``, instead: for every robot ``rrt_pin.robot.robots`` names, each
kernel's worst difference from Pinocchio over N random states (``pin.crba`` symmetrised,
``pin.rnea`` with q̈ = 0, ``pin.computeGeneralizedGravity``, ``pin.aba``), per state
relative to that state's largest |value|.

    .venv/bin/python -m scripts.bench.forward [--samples 10000] [--repeat 15] [--inner 3]
    .venv/bin/python -m scripts.bench.forward --accuracy 10000
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from rrt_pin.compiled.forward import DEFAULT_VARIANT, forward_kernel_for
from rrt_pin.robot import robots
from scripts.bench.common import interleaved

ROBOTS = ("ur5", "panda")


def states(robot, n: int, seed: int = 7) -> tuple[np.ndarray, ...]:
    """n random states: coordinates, velocities, efforts (N, nv)."""
    rng = np.random.default_rng(seed)
    nv = robot.nv
    return rng.uniform(-3, 3, (n, nv)), rng.normal(0, 2, (n, nv)), rng.normal(0, 20, (n, nv))


def aba_loop(model: pin.Model, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> np.ndarray:
    """The baseline: one ``pin.aba`` call a state from Python."""
    data = model.createData()
    out = np.empty((q.shape[0], model.nv))
    for i in range(q.shape[0]):
        out[i] = pin.aba(model, data, q[i], qd[i], tau[i])
    return out


def rel_diff(a: np.ndarray, ref: np.ndarray) -> float:
    """max over joints of max|a − ref| / max|ref|."""
    return float((np.abs(a - ref).max(axis=0) / np.abs(ref).max(axis=0)).max())


def bench(name: str, n: int, repeat: int, inner: int) -> dict[str, float]:
    robot = robots.get(name)
    model = robot.model
    fk = forward_kernel_for(model, name)
    fk.compile("forward_aba", "forward_crba")
    x, qd, tau = states(robot, n)
    q = robot.configuration(x)
    out = {v: np.empty((n, robot.nv)) for v in ("aba", "crba")}
    kernels = {v: fk.kernel(f"forward_{v}").kernel for v in ("aba", "crba")}
    sides: dict[str, Callable[[], object]] = {
        "aba kernel": lambda: kernels["aba"](x, qd, tau, out["aba"]),
        "crba kernel": lambda: kernels["crba"](x, qd, tau, out["crba"]),
        "forward_dynamics": lambda: fk.forward_dynamics(x, qd, tau, num_threads=1),
        "pin.aba loop": lambda: aba_loop(model, q, qd, tau),
    }
    ref = aba_loop(model, q, qd, tau)
    results = {
        "aba kernel": fk.forward_dynamics(x, qd, tau, variant="aba", num_threads=1),
        "crba kernel": fk.forward_dynamics(x, qd, tau, variant="crba", num_threads=1),
        "forward_dynamics": fk.forward_dynamics(x, qd, tau, num_threads=1),
        "pin.aba loop": ref,
    }
    flops = fk.flops
    sines = {k: fk.source(k).transcendentals for k in flops}
    medians = interleaved(sides, repeat, inner)
    ns = {k: 1e9 * t / n for k, t in medians.items()}
    print(
        f"\n{name}: nv={robot.nv}, {n} states, median of {repeat} rounds x {inner} calls "
        f"(forward_dynamics runs {DEFAULT_VARIANT})"
    )
    print(
        f"{'side':<17} {'ns/state':>9} {'vs pin.aba':>10} {'flops':>6} {'ns/flop':>8} {'max rel':>9}"
    )
    for side, value in ns.items():
        kind = {"aba kernel": "forward_aba", "crba kernel": "forward_crba"}.get(side)
        fl = f"{flops[kind]:>6}" if kind else f"{'':>6}"
        per = f"{value / flops[kind]:>8.3f}" if kind else f"{'':>8}"
        print(
            f"{side:<17} {value:>9.1f} {ns['pin.aba loop'] / value:>9.1f}x {fl} {per} "
            f"{rel_diff(results[side], ref):>9.1e}"
        )
    ratio = ns["aba kernel"] / ns["crba kernel"]
    faster = "crba" if ratio > 1 else "aba"
    print(
        f"aba / crba = {ratio:.2f}: {faster} is faster by {max(ratio, 1 / ratio):.2f}x; "
        "flops a state: " + ", ".join(f"{k} {v} (+{sines[k]} sin/cos)" for k, v in flops.items())
    )
    return ns


def per_state(a: np.ndarray, ref: np.ndarray) -> float:
    """max over states of max|a − ref| / max|ref| (each state's own scale)."""
    n = ref.shape[0]
    err = np.abs(a - ref).reshape(n, -1).max(axis=1)
    return float((err / np.abs(ref).reshape(n, -1).max(axis=1)).max())


def accuracy(n: int) -> None:
    """Each robot's kernels against Pinocchio on n random states."""
    print(f"worst per-state relative difference from Pinocchio, {n} random states")
    print(f"{'robot':<28} {'M':>8} {'b':>8} {'G':>8} {'aba':>8} {'crba':>8}")
    for name in robots.names():
        robot = robots.get(name)
        model, data = robot.model, robot.model.createData()
        fk = forward_kernel_for(model, name)
        x, qd, tau = states(robot, n, seed=42)
        zero = np.zeros(robot.nv)
        ref: dict[str, list] = {"M": [], "b": [], "G": [], "a": []}
        for q, v, u in zip(robot.configuration(x), qd, tau, strict=True):
            m = np.triu(pin.crba(model, data, q))
            ref["M"].append(m + np.triu(m, 1).T)
            ref["b"].append(pin.rnea(model, data, q, v, zero).copy())
            ref["G"].append(pin.computeGeneralizedGravity(model, data, q).copy())
            ref["a"].append(pin.aba(model, data, q, v, u).copy())
        want = {k: np.array(v) for k, v in ref.items()}
        errs = [
            per_state(fk.mass_matrix(x), want["M"]),
            per_state(fk.bias(x, qd), want["b"]),
            per_state(fk.gravity(x), want["G"]),
            per_state(fk.forward_dynamics(x, qd, tau, variant="aba"), want["a"]),
            per_state(fk.forward_dynamics(x, qd, tau, variant="crba"), want["a"]),
        ]
        print(f"{name:<28} " + " ".join(f"{e:>8.1e}" for e in errs))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=10_000, help="states a call")
    ap.add_argument("--repeat", type=int, default=15, help="timed rounds (median)")
    ap.add_argument("--inner", type=int, default=3, help="timed calls a side a round")
    ap.add_argument("--robots", default=",".join(ROBOTS), help="comma-separated robot names")
    ap.add_argument("--accuracy", type=int, default=0, help="check N states of every robot")
    args = ap.parse_args()
    print(f"pinocchio {pin.__version__}, numpy {np.__version__}")
    if args.accuracy:
        accuracy(args.accuracy)
        return 0
    for name in args.robots.split(","):
        bench(name, args.samples, args.repeat, args.inner)
    return 0


if __name__ == "__main__":
    sys.exit(main())
