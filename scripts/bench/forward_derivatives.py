#!/usr/bin/env python
"""Generated Jacobian of the forward dynamics of UR5 and Panda against ``pin.computeABADerivatives``.

Times, in ONE run and interleaved round by round (in a round each side runs --inner + 1
times, the first not counted), the median ns a state of, over --samples random states
(joint angles uniform in ±3 rad, velocities and efforts normal):

* <variant> kernel  the generated q̈, ∂q̈/∂q, ∂q̈/∂q̇ (``rrt_pin.compiled.jacobian``) of
                    each variant alone, one thread, into a preallocated output: ``aba``
                    and ``crba`` the tangents of that generated forward dynamics,
                    ``rnea`` ABA then −M⁻¹ times the generated inverse dynamics' tangents;
* vector kernel     the default variant vectorised across samples (blocks of
                    ``VECTOR_BLOCK``, polynomial sines and cosines), one thread;
* derivatives()     ``DerivativeKernels.derivatives`` on one thread: the whole call
                    (conversions, shape checks, new outputs split in three) of the
                    default variant;
* closed-loop kernel q̈ and ∂q̈/∂(q, q̇) under PD plus gravity (the law's derivatives in);
* pin loop          a Python loop calling ``pin.computeABADerivatives`` once a state and
                    copying ∂q̈/∂q, ∂q̈/∂q̇ out (the baseline; it computes M⁻¹ too);
* inverse kernel    τ, ∂τ/∂q, ∂τ/∂q̇ of the generated RNEA's tangents (a computed-torque
                    law's Jacobian), against
* pin rnea loop     ``pin.computeRNEADerivatives`` once a state, ∂τ/∂q and ∂τ/∂q̇ copied.

Next to each kernel: its floating-point operations a state (the generator's count, sines
and cosines apart) and ns a flop; then the worst difference of ∂q̈/∂q and ∂q̈/∂q̇ from
Pinocchio's (per state, relative to that state's largest entry) and the ratios.

With ``--radau``, instead: 5 s of each robot under PD plus gravity from an offset
(``scripts.bench.robot_sim.scene``) by ``scipy.integrate.solve_ivp`` (``--method``: Radau,
BDF or LSODA) on
the Pinocchio backend's right-hand side (``ClosedLoop.acceleration``: ``pin.aba`` with
gravity folded), its ``jac`` either the backend's (``ClosedLoop.jacobian``:
``computeABADerivatives`` and the law's derivative, in Python) or the generated
closed-loop kernel (``DerivativeKernels.closed_loop_jac``); interleaved medians, the
Jacobian calls and the difference of the final states.

With ``--accuracy N``, instead: for every robot ``rrt_pin.robot.robots`` names, the
compiled default variant's worst difference from ``computeABADerivatives`` (q̈, ∂q̈/∂q,
∂q̈/∂q̇) over N random states, per state relative to that state's largest |value|.

    .venv/bin/python -m scripts.bench.forward_derivatives [--samples 2000] [--repeat 9]
    .venv/bin/python -m scripts.bench.forward_derivatives --accuracy 10000
    .venv/bin/python -m scripts.bench.forward_derivatives --radau [--rtol 1e-8] [--method BDF]
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from rrt_pin.compiled.jacobian import derivative_kernel_for
from rrt_pin.dynamics.forward_derivatives_source import DEFAULT_VARIANT, VARIANTS
from rrt_pin.robot import robots
from scripts.bench.common import interleaved

ROBOTS = ("ur5", "panda")


def states(nv: int, n: int, seed: int = 7) -> tuple[np.ndarray, ...]:
    """n random states: coordinates, velocities, efforts (N, nv)."""
    rng = np.random.default_rng(seed)
    return rng.uniform(-3, 3, (n, nv)), rng.normal(0, 2, (n, nv)), rng.normal(0, 20, (n, nv))


def pin_loop(model: pin.Model, q: np.ndarray, qd: np.ndarray, tau: np.ndarray) -> tuple:
    """The baseline: one ``computeABADerivatives`` a state from Python, ∂q̈/∂q and ∂q̈/∂q̇ kept."""
    data = model.createData()
    n, nv = q.shape[0], model.nv
    dq, dv = np.empty((n, nv, nv)), np.empty((n, nv, nv))
    for i in range(n):
        dq[i], dv[i], _ = pin.computeABADerivatives(model, data, q[i], qd[i], tau[i])
    return dq, dv


def rnea_loop(model: pin.Model, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray) -> tuple:
    """One ``computeRNEADerivatives`` a state from Python, ∂τ/∂q and ∂τ/∂q̇ kept."""
    data = model.createData()
    n, nv = q.shape[0], model.nv
    dq, dv = np.empty((n, nv, nv)), np.empty((n, nv, nv))
    for i in range(n):
        dq[i], dv[i], _ = pin.computeRNEADerivatives(model, data, q[i], qd[i], qdd[i])
    return dq, dv


def per_state(a: np.ndarray, ref: np.ndarray) -> float:
    """max over states of max|a − ref| / max|ref| (each state's own scale)."""
    n = ref.shape[0]
    err = np.abs(a - ref).reshape(n, -1).max(axis=1)
    return float((err / np.abs(ref).reshape(n, -1).max(axis=1)).max())


def bench(name: str, n: int, repeat: int, inner: int) -> dict[str, float]:
    robot = robots.get(name)
    model, nv = robot.model, robot.nv
    dk = derivative_kernel_for(model, name)
    variants = [f"forward_derivatives_{v}" for v in VARIANTS]
    dk.compile(*variants, "forward_derivatives_vector", "closed_loop_derivatives")
    dk.compile("inverse_derivatives")
    x, qd, tau = states(nv, n)
    q = robot.configuration(x)
    gains = np.full((n, nv), 100.0), np.full((n, nv), 20.0), np.zeros((n, nv))
    out = np.empty((n, nv, 1 + 2 * nv))
    out_loop = np.empty((n, nv, 1 + 2 * nv))
    loop = dk.kernel("closed_loop_derivatives").kernel
    inverse = dk.kernel("inverse_derivatives").kernel

    def kernel_side(variant: str) -> Callable[[], object]:
        fn = dk.kernel(f"forward_derivatives_{variant}").kernel
        return lambda: fn(x, qd, tau, out)

    sides: dict[str, Callable[[], object]] = {f"{v} kernel": kernel_side(v) for v in VARIANTS}
    vector = dk.kernel("forward_derivatives_vector").kernel
    sides["vector kernel"] = lambda: vector(x, qd, tau, out)
    sides.update(
        {
            "derivatives()": lambda: dk.derivatives(x, qd, tau, num_threads=1),
            "closed-loop kernel": lambda: loop(x, qd, *gains, out_loop),
            "pin loop": lambda: pin_loop(model, q, qd, tau),
            "inverse kernel": lambda: inverse(x, qd, tau, out),
            "pin rnea loop": lambda: rnea_loop(model, q, qd, tau),
        }
    )
    ref = pin_loop(model, q, qd, tau)
    _, dq, dv = dk.derivatives(x, qd, tau, num_threads=1)
    medians = interleaved(sides, repeat, inner)
    ns = {k: 1e9 * t / n for k, t in medians.items()}
    flops = {f"{v} kernel": dk.source(f"forward_derivatives_{v}").flops for v in VARIANTS}
    flops["vector kernel"] = dk.source("forward_derivatives_vector").flops
    flops["closed-loop kernel"] = dk.source("closed_loop_derivatives").flops
    flops["inverse kernel"] = dk.source("inverse_derivatives").flops
    print(
        f"\n{name}: nv={nv}, {n} states, median of {repeat} rounds x {inner} calls "
        f"(derivatives() and the closed loop run {DEFAULT_VARIANT})"
    )
    print(f"{'side':<19} {'ns/state':>9} {'vs pin':>7} {'flops':>6} {'ns/flop':>8}")
    for side, value in ns.items():
        base = ns["pin rnea loop" if "inverse" in side or "rnea loop" in side else "pin loop"]
        fl = f"{flops[side]:>6}" if side in flops else f"{'':>6}"
        per = f"{value / flops[side]:>8.3f}" if side in flops else f"{'':>8}"
        print(f"{side:<19} {value:>9.1f} {base / value:>6.1f}x {fl} {per}")
    print(
        f"worst relative difference from computeABADerivatives ({DEFAULT_VARIANT}): "
        f"ddq_dq {per_state(dq, ref[0]):.1e}, ddq_dv {per_state(dv, ref[1]):.1e}"
    )
    _, idq, idv = dk.inverse_derivatives(x, qd, tau, num_threads=1)
    ref_id = rnea_loop(model, q, qd, tau)
    print(
        f"inverse kernel against computeRNEADerivatives: dtau_dq {per_state(idq, ref_id[0]):.1e}, "
        f"dtau_dv {per_state(idv, ref_id[1]):.1e}"
    )
    fastest = min(VARIANTS, key=lambda v: ns[f"{v} kernel"])
    print(
        f"fastest variant: {fastest}, {ns['pin loop'] / ns[f'{fastest} kernel']:.2f}x the pin loop"
    )
    return ns


def accuracy(n: int) -> None:
    """Each robot's compiled Jacobian against ``computeABADerivatives`` on n random states."""
    print(f"worst per-state relative difference from computeABADerivatives, {n} random states")
    print(f"{'robot':<28} {'ddq':>8} {'ddq_dq':>8} {'ddq_dv':>8} {'flops':>6}")
    for name in robots.names():
        robot = robots.get(name)
        model, data = robot.model, robot.model.createData()
        dk = derivative_kernel_for(model, name)
        x, qd, tau = states(robot.nv, n, seed=42)
        want: list[list] = [[], [], []]
        for q, v, u in zip(robot.configuration(x), qd, tau, strict=True):
            dq, dv, _ = pin.computeABADerivatives(model, data, q, v, u)
            for k, value in enumerate((data.ddq, dq, dv)):
                want[k].append(np.array(value))
        got = dk.derivatives(x, qd, tau)
        errs = [per_state(a, np.array(w)) for a, w in zip(got, want, strict=True)]
        flops = dk.source(f"forward_derivatives_{DEFAULT_VARIANT}").flops
        print(f"{name:<28} " + " ".join(f"{e:>8.1e}" for e in errs) + f" {flops:>6}")


def radau(name: str, rtol: float, repeat: int, method: str = "Radau") -> None:
    """5 s under PD plus gravity by an implicit method: the backend's Jacobian, then the generated."""
    from scipy.integrate import solve_ivp

    from rrt_pin.simulate.closed_loop import ClosedLoop
    from rrt_pin.simulate.scipy_runs import first_order
    from scripts.bench.robot_sim import scene

    robot, law, q0, qf = scene(name)
    nv = robot.nv
    loop = ClosedLoop(robot, law)
    f = first_order(loop.acceleration(), nv)
    y0 = np.concatenate((q0, np.zeros(nv)))
    dk = derivative_kernel_for(robot.model, name)
    generated = dk.closed_loop_jac(np.array(law.kp), np.array(law.kd), np.array(law.qf))
    jacs = {
        "pinocchio jac": lambda t, y: loop.jacobian(t, y[:nv], y[nv:]),
        "generated jac": generated,
    }
    y = np.concatenate((q0 + 0.01, 0.1 * np.ones(nv)))
    assert np.allclose(jacs["pinocchio jac"](0.0, y), generated(0.0, y), rtol=1e-11, atol=1e-9)
    results: dict[str, object] = {}

    def side(key: str) -> Callable[[], object]:
        def go() -> object:
            results[key] = solve_ivp(
                f, (0.0, 5.0), y0, method=method, rtol=rtol, atol=rtol * 1e-2, jac=jacs[key]
            )
            return results[key]

        return go

    medians = interleaved({k: side(k) for k in jacs}, repeat, inner=1)
    a, b = results["pinocchio jac"], results["generated jac"]
    diff = float(np.abs(a.y[:, -1] - b.y[:, -1]).max())
    print(
        f"\n{name}: {method}, 5 s, rtol {rtol:g}; f evaluations {a.nfev}, "
        f"Jacobians {a.njev}/{b.njev}, LU {a.nlu}; final states differ by {diff:.1e}"
    )
    for k, t in medians.items():
        print(f"{k:<15} {1e3 * t:>9.2f} ms")
    ratio = medians["pinocchio jac"] / medians["generated jac"]
    print(f"run time, pinocchio jac / generated jac = {ratio:.2f}")


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, default=2_000, help="states a call")
    ap.add_argument("--repeat", type=int, default=9, help="timed rounds (median)")
    ap.add_argument("--inner", type=int, default=3, help="timed calls a side a round")
    ap.add_argument("--robots", default=",".join(ROBOTS), help="comma-separated robot names")
    ap.add_argument("--radau", action="store_true", help="time Radau runs with each Jacobian")
    ap.add_argument("--rtol", type=float, default=1e-8, help="Radau's rtol (atol = rtol/100)")
    ap.add_argument("--method", default="Radau", help="with --radau: Radau, BDF or LSODA")
    ap.add_argument("--accuracy", type=int, default=0, help="check N states of every robot")
    args = ap.parse_args()
    print(f"pinocchio {pin.__version__}, numpy {np.__version__}")
    if args.accuracy:
        accuracy(args.accuracy)
        return 0
    for name in args.robots.split(","):
        if args.radau:
            radau(name, args.rtol, args.repeat, args.method)
        else:
            bench(name, args.samples, args.repeat, args.inner)
    return 0


if __name__ == "__main__":
    sys.exit(main())
