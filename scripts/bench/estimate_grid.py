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
"""

from __future__ import annotations

import warnings

import numpy as np
import pinocchio as pin
from scipy.integrate import solve_ivp
from scipy.integrate._ivp.rk import DOP853

from rrt_pin.simulate.accuracy import PROBLEMS


def rhs_for(problem):
    """(f(t, y), y0, output times) of a catalogue problem, on ``pin.aba``."""
    robot = problem.arm
    law = problem.controller(robot)
    model, data = robot.model, robot.model.createData()

    def f(t, y):
        q, v = y[:3], y[3:]
        tau = np.asarray(law.efforts(t, q, v), dtype=float)
        return np.concatenate([v, pin.aba(model, data, q, v, tau)])

    q0, qd0 = problem.start(robot)
    return f, np.concatenate([q0, qd0]), problem.times()


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
        f, y0, t = rhs_for(problem)
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


if __name__ == "__main__":
    main()
