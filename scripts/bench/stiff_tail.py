#!/usr/bin/env python
"""Where DOP853's evaluations go on a robot's scene: the tail its stability sets, and a handover study.

The scene is ``scripts.bench.robot_sim``'s (UR5 and Panda, 15 s under PD plus gravity
from qf + 0.3 rad, outputs every 10 ms). Its closed loop settles in ~3 s, after which
DOP853's step is set by its stability region, not by the tolerance: the Jacobian's
eigenvalues are real down to −76 /s (UR5) and −170 /s (Panda), and DOP853 is stable to
|h·λ| ≈ 6 on the negative real axis.

For each robot and rtol (atol = rtol/100) this prints:

* DOP853 alone (SciPy's, step by step on ``pin.aba``; the compiled DOP853 takes the
  same steps): evaluations, accepted steps, and the share of them with h·ρ̂ > 3.25
  (Hairer's stiffness test in DOP853: ρ̂ = |f(y₁) − f(y₁₂)| / |y₁ − y₁₂| from the step's
  last stage), with their evaluations;
* a handover (this script's Python prototype; rrt-pin's compiled one, with a two-way
  switch, is ``method="DOP853-RKC"``): DOP853 until ``--after`` consecutive
  steps pass that test, then the Runge–Kutta–Chebyshev method (Sommeijer, Shampine and
  Verwer 1997: order 2, s stages, stable along the negative real axis to ≈ 0.65·s²;
  its own error estimate and step control, s from a power-iteration estimate of the
  spectral radius, cubic Hermite output) to the end: its evaluations (every one,
  those of the spectral radius included) and errors.

Errors: max |q − q_ref| at every output time and at the last, against the compiled
DOP853 at rtol 1e-13. Counts of evaluations, not times (the prototype is Python):

    .venv/bin/python -m scripts.bench.stiff_tail [--robots ur5,panda] [--rtols 1e-8,1e-10]
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
import pinocchio as pin
from scipy.integrate import DOP853
from scipy.integrate._ivp.dop853_coefficients import A as D8_A

from scripts.bench.robot_sim import TF, run, scene

#: DOP853's stiffness test (Hairer and Wanner, DOP853's source): h·ρ̂ above this.
STIFF = 3.25
#: RKC's damping (its authors' value).
EPS = 2.0 / 13.0


def closed_loop(name: str):
    """The scene's ẏ = f(t, y) on Pinocchio, counting its calls."""
    robot, law, q0, qf = scene(name)
    model, data, nv = robot.model, robot.model.createData(), robot.nv
    kp, kd = np.array(law.kp), np.array(law.kd)
    calls = [0]

    def f(_t: float, y: np.ndarray) -> np.ndarray:
        calls[0] += 1
        q, v = y[:nv], y[nv:]
        c = robot.configuration(q)
        tau = -kd * v - kp * (q - qf) + pin.computeGeneralizedGravity(model, data, c)
        return np.concatenate([v, pin.aba(model, data, c, v, tau)])

    return robot, np.concatenate([q0, np.zeros(nv)]), f, calls


def rkc_step(f, t: float, y: np.ndarray, fy: np.ndarray, h: float, s: int) -> np.ndarray:
    """One RKC step of s stages (Sommeijer, Shampine and Verwer's recurrence)."""
    w0 = 1.0 + EPS / s**2
    T, dT, d2T = np.zeros(s + 1), np.zeros(s + 1), np.zeros(s + 1)
    T[0], T[1], dT[1] = 1.0, w0, 1.0
    for j in range(2, s + 1):
        T[j] = 2 * w0 * T[j - 1] - T[j - 2]
        dT[j] = 2 * T[j - 1] + 2 * w0 * dT[j - 1] - dT[j - 2]
        d2T[j] = 4 * dT[j - 1] + 2 * w0 * d2T[j - 1] - d2T[j - 2]
    w1 = dT[s] / d2T[s]
    b = np.zeros(s + 1)
    b[2:] = d2T[2:] / dT[2:] ** 2
    b[0] = b[1] = b[2]
    c = np.zeros(s + 1)
    c[1] = b[1] * w1
    older, old = y, y + c[1] * h * fy
    for j in range(2, s + 1):
        mu, nu = 2 * b[j] * w0 / b[j - 1], -b[j] / b[j - 2]
        mut = 2 * b[j] * w1 / b[j - 1]
        gt = -(1 - b[j - 1] * T[j - 1]) * mut
        new = (
            (1 - mu - nu) * y
            + mu * old
            + nu * older
            + h * (mut * f(t + c[j - 1] * h, old) + gt * fy)
        )
        c[j] = mu * c[j - 1] + nu * c[j - 2] + mut + gt
        older, old = old, new
    return old


def spectral_radius(f, t: float, y: np.ndarray, fy: np.ndarray, v: np.ndarray):
    """RKC's estimate of ρ(∂f/∂y) by nonlinear power iteration (× 1.2), and its vector."""
    scale = math.sqrt(np.finfo(float).eps) * max(float(np.linalg.norm(y)), 1e-3)
    z = y + v * (scale / max(float(np.linalg.norm(v)), 1e-300))
    rho = 0.0
    for it in range(20):
        d = f(t, z) - fy
        before, rho = rho, float(np.linalg.norm(d)) / scale
        if it > 1 and abs(rho - before) <= 0.01 * max(rho, before):
            break
        z = y + d * (scale / max(float(np.linalg.norm(d)), 1e-300))
    return 1.2 * rho, z - y


def integrate(name: str, rtol: float, t_out: np.ndarray, after: int | None):
    """DOP853, handing over to RKC after ``after`` stiff steps in a row (None: never)."""
    robot, y0, f, calls = closed_loop(name)
    atol = rtol / 100
    out = np.full((t_out.size, y0.size), np.nan)
    out[0], i = y0, 1
    solver = DOP853(f, float(t_out[0]), y0, float(t_out[-1]), rtol=rtol, atol=atol)
    steps = stiff = stiff_evals = streak = 0
    while solver.status == "running":
        t_old, y_old, before = solver.t, solver.y.copy(), calls[0]
        solver.step()
        h, K = solver.t - t_old, solver.K
        y12 = y_old + h * (K[:12].T @ D8_A[11, :12])
        den = float(np.linalg.norm(solver.y - y12))
        h_rho = h * float(np.linalg.norm(K[12] - K[11])) / den if den > 0 else 0.0
        steps += 1
        dense = None
        while i < t_out.size and t_out[i] <= solver.t:
            dense = dense or solver.dense_output()
            out[i], i = dense(t_out[i]), i + 1
        streak = streak + 1 if h_rho > STIFF else 0
        if h_rho > STIFF:
            stiff += 1
            stiff_evals += calls[0] - before
        if after is not None and streak >= after and solver.status == "running":
            break
    switched = solver.t if solver.status == "running" else None
    rkc_steps = 0
    if switched is not None:
        t, y = solver.t, solver.y.copy()
        fy, h = f(t, y), 2.0 * solver.step_size
        rho, v = spectral_radius(f, t, y, fy, solver.K[12] - solver.K[11] + 1e-3)
        while t < t_out[-1]:
            if rkc_steps and rkc_steps % 25 == 0:
                rho, v = spectral_radius(f, t, y, fy, v)
            h = min(h, t_out[-1] - t)
            s = max(2, 1 + int(math.sqrt(1 + 1.54 * h * rho)))
            new = rkc_step(f, t, y, fy, h, s)
            f_new = f(t + h, new)
            est = 0.8 * (y - new) + 0.4 * h * (fy + f_new)
            err = math.sqrt(np.mean((est / (atol + rtol * np.maximum(abs(y), abs(new)))) ** 2))
            rkc_steps += 1
            if err > 1.0:
                h *= 0.8 / err ** (1 / 3)
                continue
            while i < t_out.size and t_out[i] <= t + h:
                x = (t_out[i] - t) / h
                out[i] = (
                    (2 * x**3 - 3 * x**2 + 1) * y + (x**3 - 2 * x**2 + x) * h * fy
                    + (3 * x**2 - 2 * x**3) * new + (x**3 - x**2) * h * f_new
                )  # fmt: skip
                i += 1
            t, y, fy = t + h, new, f_new
            h *= 10.0 if err == 0.0 else min(10.0, 0.8 / err ** (1 / 3))
    return robot, out, calls[0], steps, stiff, stiff_evals, switched, rkc_steps


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--robots", default="ur5,panda")
    ap.add_argument("--rtols", default="1e-8,1e-10")
    ap.add_argument("--after", default="3,8,15", help="handovers after N stiff steps in a row")
    args = ap.parse_args(argv)
    t = np.arange(0.0, TF + 1e-9, 0.01)
    print("| robot | rtol | run | evaluations | vs DOP853 | steps (stiff: h·ρ̂ > 3.25) "
          "| their evaluations | handed over at | RKC steps | max |q error| every output "
          "| at the end |")  # fmt: skip
    print("|---|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|")
    for name in args.robots.split(","):
        robot, law, q0, _ = scene(name)
        ref = run(robot, law, q0, t, "compiled", 1e-13, "DOP853").q
        for rtol in map(float, args.rtols.split(",")):
            alone = None
            for after in [None, *map(int, args.after.split(","))]:
                _, out, evals, steps, stiff, stiff_evals, at, rkc = integrate(name, rtol, t, after)
                err = np.abs(out[:, : robot.nv] - ref)
                alone = alone or evals
                label = "DOP853" if after is None else f"handover after {after}"
                stiff_cols = (
                    f"{steps} ({stiff}, {stiff / steps:.0%}) | {stiff_evals} ({stiff_evals / evals:.0%})"
                    if after is None else f"{steps} | —"
                )  # fmt: skip
                print(f"| {name} | {rtol:.0e} | {label} | {evals:,} | {alone / evals:.2f}× "
                      f"| {stiff_cols} | {'—' if at is None else f'{at:.2f} s'} | {rkc or '—'} "
                      f"| {err.max():.1e} | {err[-1].max():.1e} |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
