#!/usr/bin/env python
"""The accuracy catalogue: the defaults' global error, its estimate and their cost, in one run.

Sections:

1. references: every problem of ``rrt_pin.simulate.accuracy.PROBLEMS`` at rtol 1e-13, atol 1e-15
   with the compiled DOP853 (the problems it runs) and, independently, scipy's DOP853
   on ``pin.aba`` (``rrt_pin.simulate.reference.reference_run``); a second method checks
   them: Radau (implicit Runge–Kutta) on the chapter's run, odepack (LSODA, multistep)
   at rtol 1e-13 on the others. The table gives their disagreement.
2. catalogue: per problem and backend, the default's error max |q − q_ref|, its
   estimate (``result.error_estimate``), their ratio, the run's time and the
   estimate's (medians over --repeat interleaved rounds), and the old defaults
   (rtol 1e-9, atol 1e-11) for comparison.
3. work-precision over the catalogue: each candidate setting's worst error over the
   problems against its total time; the script marks the settings on each backend's
   Pareto front (nothing on that backend is both faster and more accurate).

    .venv/bin/python -m scripts.bench.accuracy [--repeat 3] [--problems a,b] [--sections 2,3] [--markdown]
"""

from __future__ import annotations

import argparse
import statistics
import time
import warnings

from rrt_pin.simulate import AccuracyWarning
from rrt_pin.simulate.accuracy import ACCURACY, PROBLEMS, max_error, reference

#: Candidate settings of the work-precision section: (backend, method, rtol); atol = rtol/100.
CANDIDATES = (
    *(("pinocchio", "odepack", r) for r in (1e-9, 1e-10, 1e-11, 1e-12, 1e-13)),
    *(("pinocchio", "DOP853", r) for r in (1e-9, 1e-10, 1e-11)),
    *(("compiled", "DOP853", r) for r in (1e-9, 1e-10, 1e-11, 1e-12)),
    *(("compiled", "RK45", r) for r in (1e-9, 1e-10)),
)
DEFAULTS = {"pinocchio": ("odepack", 1e-12), "compiled": ("DOP853", 1e-10)}


def _time(f, repeat: int) -> float:
    """Median wall time [s] of f over ``repeat`` calls (bursts of ≥ 5 ms for short calls)."""
    samples = []
    for _ in range(repeat):
        n, t0 = 0, time.perf_counter()
        while True:
            f()
            n += 1
            if time.perf_counter() - t0 >= 0.005:
                break
        samples.append((time.perf_counter() - t0) / n)
    return statistics.median(samples)


def references(names: list[str]) -> dict:
    """Section 1: references and their cross-checks."""
    from rrt_pin.simulate.reference import reference_run

    refs, rows = {}, []
    for name in names:
        problem = PROBLEMS[name]
        robot = problem.arm
        d = robot.defaults
        law = problem.controller(robot)
        t = problem.times()
        scipy_ref = reference(problem, backend="pinocchio").q
        second = "Radau" if name == "chapter" else "odepack"
        if second == "Radau":
            other = reference_run(robot.model, law, d.q0, d.qd0, t, methods=("Radau",)).q
        else:
            other = problem.run(method="odepack", rtol=1e-13, atol=1e-15, estimate_error=False).q
        if "compiled" in problem.backends:
            ref = reference(problem, backend="compiled").q
            vs_scipy = max_error(ref, scipy_ref)
        else:
            ref, vs_scipy = scipy_ref, float("nan")
        refs[name] = ref
        rows.append((name, vs_scipy, second, max_error(scipy_ref, other)))
        print(
            f"{name:<18} compiled vs scipy DOP853 {vs_scipy:8.1e}   "
            f"scipy DOP853 vs {second:<7} {max_error(scipy_ref, other):8.1e}",
            flush=True,
        )
    return refs


def catalogue(names: list[str], refs: dict, repeat: int) -> list[tuple]:
    """Section 2: the defaults (and the old defaults) on every problem."""
    rows = []
    for name in names:
        problem = PROBLEMS[name]
        for backend in problem.backends:
            for label, kw in (("default", {}), ("old default", {"rtol": 1e-9, "atol": 1e-11})):
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", AccuracyWarning)
                    run = problem.run(backend=backend, **kw)
                    plain = _time(
                        lambda s=problem, b=backend, k=kw: s.run(
                            backend=b, estimate_error=False, **k
                        ),
                        repeat,
                    )
                    whole = _time(lambda s=problem, b=backend, k=kw: s.run(backend=b, **k), repeat)
                err = max_error(run.q, refs[name])
                est = run.error_estimate
                rows.append((name, backend, label, run.method, run.rtol, err, est, plain, whole))
                print(
                    f"{name:<18} {backend:<9} {label:<11} {run.method:<7} rtol {run.rtol:<6.0e} "
                    f"error {err:8.1e}  estimate {est:8.1e} (x{est / err:5.2f})  "
                    f"run {plain * 1e3:8.2f} ms  with estimate {whole * 1e3:8.2f} ms "
                    f"(x{whole / plain:4.2f})",
                    flush=True,
                )
    return rows


def work_precision(names: list[str], refs: dict, repeat: int) -> list[tuple]:
    """Section 3: worst error over the problems against total time, per candidate setting."""
    rows = []
    for backend, method, rtol in CANDIDATES:
        worst, total, worst_scene = 0.0, 0.0, ""
        for name in names:
            problem = PROBLEMS[name]
            if backend not in problem.backends:
                continue
            kw = dict(backend=backend, method=method, rtol=rtol, atol=rtol / 100)
            run = problem.run(estimate_error=False, **kw)
            err = max_error(run.q, refs[name])
            if err > worst:
                worst, worst_scene = err, name
            total += _time(lambda s=problem, k=kw: s.run(estimate_error=False, **k), repeat)
        rows.append((backend, method, rtol, worst, worst_scene, total))
    for row in rows:
        backend, method, rtol, worst, worst_scene, total = row
        front = not any(
            o[0] == backend and o[5] < total and o[3] < worst for o in rows if o is not row
        )
        default = DEFAULTS[backend] == (method, rtol)
        print(
            f"{backend:<9} {method:<7} rtol {rtol:<6.0e} worst error {worst:8.1e} ({worst_scene}) "
            f"total {total * 1e3:9.1f} ms{'  front' if front else ''}"
            f"{'  <- default' if default else ''}{'  meets 1e-8' if worst <= ACCURACY else ''}",
            flush=True,
        )
    return rows


def markdown(rows: list[tuple]) -> str:
    """Section 2 as the table of docs/benchmarks.md."""
    out = [
        "| problem | backend | setting | error max \\|q − q_ref\\| | estimate | estimate / error "
        "| run | run + estimate |",
        "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: |",
    ]
    for name, backend, label, method, rtol, err, est, plain, whole in rows:
        out.append(
            f"| {name} | {backend} | {label}: {method} {rtol:.0e} | {err:.1e} | {est:.1e} "
            f"| {est / err:.2f} | {plain * 1e3:.3g} ms | {whole * 1e3:.3g} ms |"
        )
    return "\n".join(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3, help="timing rounds (median)")
    parser.add_argument("--problems", default=",".join(PROBLEMS), help="comma-separated names")
    parser.add_argument("--markdown", action="store_true", help="print section 2 as markdown")
    parser.add_argument(
        "--sections", default="1,2,3", help="which sections to run after the references"
    )
    args = parser.parse_args()
    names = args.problems.split(",")
    sections = set(args.sections.split(","))
    print("1. references (rtol 1e-13): disagreement max |q_a − q_b| [rad or m]")
    refs = references(names)
    if "2" in sections:
        print("\n2. catalogue: defaults, their estimate and cost (medians)")
        rows = catalogue(names, refs, args.repeat)
        worst = max(r[5] for r in rows if r[2] == "default")
        ratios = [r[6] / r[5] for r in rows]
        print(
            f"   worst default error {worst:.1e} (target {ACCURACY:g}); estimate/error in "
            f"[{min(ratios):.2f}, {max(ratios):.2f}]"
        )
        if args.markdown:
            print(markdown(rows))
    if "3" in sections:
        print("\n3. work-precision over the catalogue (atol = rtol/100)")
        work_precision(names, refs, args.repeat)


if __name__ == "__main__":
    main()
