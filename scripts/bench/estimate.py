#!/usr/bin/env python
"""The error estimate's cost and how well it brackets the true error, per problem.

For each problem of the accuracy catalogue (``rrt_pin.simulate.accuracy.PROBLEMS``) and the
robot problems (``ROBOT_PROBLEMS``, when example-robot-data is installed), on each backend
that runs it, the default run (method, tolerances chosen for --accuracy) is compared with
the problem's reference (rtol 1e-13): true error max |q − q_ref| [rad or m], the estimate
(``result.error_estimate``), their ratio (the target: 0.3–3), and the cost: the run alone
and the run with its estimate, timed interleaved in one process (medians of --repeat
rounds), the estimate's time being the difference and the cost ratio estimate / run (the
target: ≤ 0.5).

    .venv/bin/python -m scripts.bench.estimate [--repeat 5] [--accuracy 1e-8]
        [--problems a,b] [--backends pinocchio,compiled] [--markdown]
"""

from __future__ import annotations

import argparse
import sys
import warnings

from rrt_pin.core import backends as registry
from rrt_pin.core.errors import RrtPinError
from rrt_pin.simulate import AccuracyWarning, simulate
from rrt_pin.simulate.accuracy import PROBLEMS, ROBOT_PROBLEMS, max_error, reference
from scripts.bench.common import interleaved, verdict

LOW, HIGH, COST = 0.3, 3.0, 0.5
FLOOR = 1e-11  # below this the references disagree [rad or m]


def sides(problem, kw: dict) -> dict:
    """The run alone and with its estimate, on a robot and law built once."""
    robot = problem.arm
    law = problem.controller(robot)
    q0, qd0 = problem.start(robot)
    t = problem.times()
    return {
        "run": lambda: simulate(robot, law, q0, qd0, t, estimate_error=False, **kw),
        "with": lambda: simulate(robot, law, q0, qd0, t, **kw),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--accuracy", type=float, default=None, help="[rad or m] (default 1e-8)")
    ap.add_argument("--problems", default=None)
    ap.add_argument("--backends", default="pinocchio,compiled")
    ap.add_argument("--markdown", action="store_true", help="print a markdown table too")
    args = ap.parse_args(argv)
    problems = {**PROBLEMS, **ROBOT_PROBLEMS}
    if args.problems:
        problems = {k: v for k, v in problems.items() if k in args.problems.split(",")}
    wanted = args.backends.split(",")
    if "compiled" in wanted and not registry.get("compiled").available():
        wanted.remove("compiled")
    warnings.simplefilter("ignore", AccuracyWarning)
    rows = []
    print(f"{'problem':<17} {'backend':<9} {'method':<7} {'rtol':>7} {'true error':>10} "
          f"{'estimate':>9} {'ratio':>6} {'run':>9} {'estimate':>9} {'cost':>5}")  # fmt: skip
    for name, problem in problems.items():
        try:
            ref = reference(problem).q
        except RrtPinError as e:
            print(f"{name}: skipped ({e})", file=sys.stderr)
            continue
        for backend in wanted:
            if backend not in problem.backends:
                continue
            kw = {"backend": backend, "accuracy": args.accuracy}
            funcs = sides(problem, kw)
            run = funcs["with"]()  # also compiles what it needs
            times = interleaved(funcs, args.repeat, inner=1 if problem.tf > 100 else 3)
            error = max_error(run.q, ref)
            est = run.error_estimate
            ratio = max(est, FLOOR) / max(error, FLOOR)
            extra = max(times["with"] - times["run"], 0.0)
            cost = extra / times["run"]
            rows.append((name, backend, run.method, run.rtol, error, est, ratio, times["run"],
                         extra, cost))  # fmt: skip
            print(f"{name:<17} {backend:<9} {run.method:<7} {run.rtol:>7.0e} {error:>10.2e} "
                  f"{est:>9.2e} {ratio:>6.2f} {times['run'] * 1e3:>7.2f}ms "
                  f"{extra * 1e3:>7.2f}ms {cost:>5.2f}", flush=True)  # fmt: skip
    if not rows:
        return 0
    worst_low = min(r[6] for r in rows)
    worst_high = max(r[6] for r in rows)
    worst_cost = max(r[9] for r in rows)
    print(f"estimate/true error {worst_low:.2f}–{worst_high:.2f} (target {LOW}–{HIGH}): "
          f"{verdict(LOW <= worst_low and worst_high <= HIGH)}; cost ≤ {worst_cost:.2f} of the "
          f"run (target ≤ {COST}): {verdict(worst_cost <= COST)}")  # fmt: skip
    if args.markdown:
        print()
        print(
            "| problem | backend | method | rtol | true error | estimate | estimate/true "
            "| run | estimate | cost ratio |"
        )
        print("|---|---|---|---|---|---|---|---|---|---|")
        for name, backend, method, rtol, error, est, ratio, t_run, t_est, cost in rows:
            print(
                f"| {name} | {backend} | {method} | {rtol:.0e} | {error:.2e} | {est:.2e} | "
                f"{ratio:.2f} | {t_run * 1e3:.3g} ms | {t_est * 1e3:.3g} ms | {cost:.2f} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
