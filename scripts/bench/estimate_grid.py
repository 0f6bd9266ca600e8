#!/usr/bin/env python3
"""A candidate error estimate, measured: Richardson on DOP853's own accepted step grid.

Not used by rrt-pin yet: this measures whether it would meet the estimate's rules (within
0.3–3× of the true error, at most 0.5× the run's cost). For each problem of the accuracy
catalogue (the chapter's arm; ``fast-motion`` apart), at rtol 1e-8 and 1e-10:

* run A: SciPy's DOP853 on ``pin.aba`` (the problem's law), dense output;
* run B: DOP853 through every second node of A's accepted steps, one step each (half the
  steps, no rejection, no error control), dense output;
* the estimate of A's error: max over the output times of |A − B| / d, for d = 255
  (2⁸ − 1: DOP853's order 8 at the nodes), 127 (2⁷ − 1: its order-7 dense output) and
  180 (between), against A's true error (a rtol 1e-13 reference).

B costs half A's accepted steps (A also pays its rejected ones). Where the doubled steps
leave DOP853's stability region (stiff problems: the steps are set by stability, not
accuracy), B diverges and the line says so: such runs need another estimate.

    .venv/bin/python -m scripts.bench.estimate_grid

``--stable``: the variant that keeps B inside the stability region, on the whole catalogue
and UR5 and Panda (5 s under PD plus gravity). A pair of A's steps is merged only where
2h·ρ ≤ 3 (ρ: the spectral radius of ∂f/∂y at the pair's start, by finite differences;
DOP853's real stability boundary is ~6); elsewhere B follows A with its difference carried
unchanged (no evaluation). R = |A − B|/180 over the output times; L = the largest
DOP853 local-error estimate of q over the steps not merged (what R cannot see there);
the estimate would be max(R, L). Cost: B's evaluations over A's. ``--stable --exact``:
a pair is merged where DOP853's stability function keeps |R(2hλ)| ≤ 1 for every eigenvalue.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp
from scipy.integrate._ivp.rk import DOP853

from rrt_pin.simulate.accuracy import PROBLEMS, ROBOT_PROBLEMS


def rhs_for(problem):
    """(f(t, y), y0, output times, nv) of a catalogue problem, on ``pin.aba``."""
    robot = problem.arm
    law = problem.controller(robot)
    model, data = robot.model, robot.model.createData()
    n = robot.nv

    def f(t, y):
        q, v = y[:n], y[n:]
        tau = np.asarray(law.efforts(t, q, v), dtype=float)
        return np.concatenate([v, pin.aba(model, data, q, v, tau)])

    q0, qd0 = problem.start(robot)
    return f, np.concatenate([q0, qd0]), problem.times(), n


def through(f, y0, nodes):
    """DOP853 from node to node, one step each (huge tolerances: every step accepted)."""
    s = DOP853(f, nodes[0], y0, nodes[-1], rtol=1e3, atol=1e3, first_step=nodes[1] - nodes[0])
    pieces = []
    for k in range(1, len(nodes)):
        s.h_abs = nodes[k] - s.t
        s.step()
        if s.status == "failed" or not np.all(np.isfinite(s.y)):
            return None
        pieces.append((s.t, s.dense_output()))
    return pieces


def at(pieces, t):
    ends = np.array([end for end, _ in pieces])
    which = np.minimum(np.searchsorted(ends, t), len(pieces) - 1)
    return np.array([pieces[k][1](ti) for k, ti in zip(which, t, strict=True)])


def main() -> None:
    warnings.simplefilter("ignore")
    print(
        "| problem | rtol | A's steps | true error | est/true, d=255 | d=127 | d=180 | B/A evaluations |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    for name, problem in PROBLEMS.items():
        if name == "fast-motion":  # a tracked motion: its law is not a function of the state alone
            continue
        f, y0, t, _ = rhs_for(problem)
        ref = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", rtol=1e-13, atol=1e-15, t_eval=t)
        for rtol in (1e-8, 1e-10):
            a = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", rtol=rtol, atol=rtol / 100,
                          dense_output=True)  # fmt: skip
            A = a.sol(t).T
            true = float(np.abs(A[:, :3] - ref.y.T[:, :3]).max())
            nodes = a.t[::2] if (a.t.size - 1) % 2 == 0 else np.append(a.t[::2], a.t[-1])
            pieces = through(f, y0, nodes)
            steps = a.t.size - 1
            if pieces is None:
                print(f"| {name} | {rtol:.0e} | {steps} | {true:.2e} | B unstable | | | |")
                continue
            d = float(np.abs(A[:, :3] - at(pieces, t)[:, :3]).max())
            cost = 15 * (nodes.size - 1) / a.nfev  # B: 12 stages + 3 for the dense output
            print(f"| {name} | {rtol:.0e} | {steps} | {true:.2e} | {d / 255 / true:.2f} | "
                  f"{d / 127 / true:.2f} | {d / 180 / true:.2f} | {cost:.2f} |")  # fmt: skip


def _one_step(f, t0, y0, t1):
    """One DOP853 step from t0 to t1: (y1, dense output, local error estimate), or None."""
    s = DOP853(f, t0, y0, t1, rtol=1e3, atol=1e3, first_step=t1 - t0)
    s.h_abs = t1 - t0
    s.step()
    if s.status == "failed" or not np.all(np.isfinite(s.y)):
        return None
    return s.y, s.dense_output(), np.abs(s._estimate_error(s.K, t1 - t0))


def _stability(z: complex) -> float:
    """|R(z)|, DOP853's stability function (its 12 stages) at z = hλ."""
    from scipy.integrate._ivp import dop853_coefficients as c

    a, b = c.A[:12, :12], c.B
    return abs(1 + z * b @ np.linalg.solve(np.eye(12) - z * a, np.ones(12)))


def _eigenvalues(f, t, y):
    """The eigenvalues of ∂f/∂y at (t, y), by forward differences."""
    f0, n = f(t, y), y.size
    jac = np.empty((n, n))
    for i in range(n):
        e = 1e-7 * max(1.0, abs(y[i]))
        z = y.copy()
        z[i] += e
        jac[:, i] = (f(t, z) - f0) / e
    return np.linalg.eigvals(jac)


def stable(bound: float = 3.0, exact: bool = False) -> None:
    """The stability-aware variant (see the module): one line a problem and rtol.

    ``exact``: merge a pair where |R(2hλ)| ≤ 1 for every eigenvalue λ of ∂f/∂y at both
    its nodes (DOP853's own stability region, ~6 on the real and imaginary axes) instead
    of 2h·ρ ≤ ``bound``.
    """
    warnings.simplefilter("ignore")
    print("| problem | rtol | A's steps | median 2h·ρ | true error | R/true | L/true | max/true "
          "| cost |")  # fmt: skip
    print("| --- | ---: | ---: | ---: | ---: | ---: | ---: | ---: | ---: |")
    problems = {k: v for k, v in PROBLEMS.items() if k != "fast-motion"} | ROBOT_PROBLEMS
    for name, problem in problems.items():
        f, y0, t, n = rhs_for(problem)
        ref = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", rtol=1e-13, atol=1e-15, t_eval=t)
        for rtol in (1e-8, 1e-10):
            a = solve_ivp(f, (t[0], t[-1]), y0, method="DOP853", rtol=rtol, atol=rtol / 100,
                          dense_output=True)  # fmt: skip
            true = float(np.abs(a.sol(t).T[:, :n] - ref.y.T[:, :n]).max())
            nodes = a.t
            lam = [_eigenvalues(f, nodes[i], a.y[:, i]) for i in range(nodes.size)]
            rho = [float(np.abs(x).max()) for x in lam]
            pieces, local, evals, k, y = [], 0.0, 0, 0, y0.copy()
            while k < nodes.size - 1:
                pair = k + 2 <= nodes.size - 1
                h2 = nodes[k + 2] - nodes[k] if pair else 0.0
                if exact and pair:
                    pair = max(_stability(h2 * x) for x in (*lam[k], *lam[k + 1])) <= 1.0
                elif pair:
                    pair = h2 * max(rho[k], rho[k + 1]) <= bound
                if pair:
                    step = _one_step(f, nodes[k], y, nodes[k + 2])
                    if step is None:
                        break
                    y, dense, _ = step
                    pieces.append((nodes[k], dense, None))
                    evals += 15
                    k += 2
                    continue
                _, _, err = _one_step(f, nodes[k], a.y[:, k], nodes[k + 1])  # A's own step
                local = max(local, float(err[:n].max()))
                offset = y - a.y[:, k]
                y = a.y[:, k + 1] + offset
                pieces.append((nodes[k], None, offset))
                k += 1
            if k < nodes.size - 1:
                print(
                    f"| {name} | {rtol:.0e} | {nodes.size - 1} | | {true:.2e} | B unstable | | | |"
                )
                continue
            starts = np.array([p[0] for p in pieces])
            which = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(pieces) - 1)
            B = np.array([
                pieces[i][1](ti) if pieces[i][1] is not None else a.sol(ti) + pieces[i][2]
                for i, ti in zip(which, t, strict=True)
            ])  # fmt: skip
            r = float(np.abs(a.sol(t).T[:, :n] - B[:, :n]).max()) / 180.0
            merged = 2.0 * np.diff(nodes) * np.array(rho[:-1])
            print(f"| {name} | {rtol:.0e} | {nodes.size - 1} | {np.median(merged):.1f} | "
                  f"{true:.2e} | {r / true:.2f} | {local / true:.2f} | "
                  f"{max(r, local) / true:.2f} | {evals / a.nfev:.2f} |", flush=True)  # fmt: skip


if __name__ == "__main__":
    if "--stable" in sys.argv[1:]:
        stable(exact="--exact" in sys.argv[1:])
    else:
        main()
