#!/usr/bin/env python
"""Calibrate the default tolerances and the error estimate; write ``rrt_pin/simulate/calibration.py``.

For every adaptive method on every backend that runs it, each problem of the accuracy
catalogue (``rrt_pin.simulate.accuracy.PROBLEMS``) and the two robot problems
(``ROBOT_PROBLEMS``: UR5 and Panda, 5 s under PD plus gravity, when example-robot-data
is installed) runs at a ladder of tolerances, rtol = 1e-3 … 1e-13 in half decades
(atol = rtol/100 [rad, m, rad/s, m/s]), and is compared with its reference (rtol
1e-13, ``rrt_pin.simulate.accuracy.reference``):

* **worst error** of each rung: max |q − q_ref| over the output times, the
  coordinates and the problems [rad or m], made non-decreasing in rtol (a looser
  rung is never credited with a smaller error than a tighter one);
* **safety factor**, measured by leaving one problem out: for each problem, each
  method and each accuracy 1e-3 … 1e-9, the rung chosen from the other problems
  alone, and that problem's error there over the accuracy; the factor is the
  largest such ratio (at least 1). The defaults then take the loosest rung whose
  worst error times the factor is within the accuracy asked for;
* **the estimate's companion**: the estimate of a run at rung i is
  |q_i − q_(i−j)| / (k^p − 1) with a companion j half decades looser (k = 10^(j/2));
  per method, the rate p is fitted over the problems (the geometric mean of the
  exact factor) at the rungs the accuracies 1e-6, 1e-8, 1e-10 choose, and j (1 to 4)
  is the companion of least median cost (its right-hand-side evaluations over the
  run's) among those that keep every estimate within 0.3–3× of the true error; a
  companion ten times tighter (k = 1/10, e ≈ |q_i − q_(i+2)| / (1 − 10⁻ᵖ)) competes
  too (dearer, but its difference is nearly the whole error).

Runs of one problem and method stop tightening below an error of 1e-11 [rad or m]
(the references agree to ~5e-12) or after a run that takes more than --budget
seconds (its tighter rungs then count the last error measured).

    .venv/bin/python -m scripts.bench.calibrate [--methods odepack,DOP853] [--raw PATH]
        [--from-raw PATH] [--write] [--budget 20]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from rrt_pin.core.errors import InputError, RrtPinError
from rrt_pin.simulate import AccuracyWarning, methods
from rrt_pin.simulate.accuracy import PROBLEMS, ROBOT_PROBLEMS, max_error, reference

#: rtol of each rung, loosest first (atol = rtol / ATOL_RATIO).
LADDER = [10.0 ** (-k / 2) for k in range(6, 27)]
ATOL_RATIO = 100.0
#: Errors below this are the references' own disagreement [rad or m].
FLOOR = 1e-11
#: The accuracies of the leave-one-out measurement [rad or m] (down to 100 times the
#: references' disagreement and odepack's own floor on the fast oscillation, 1.6e-10).
ACCURACIES = [10.0**-k for k in range(3, 10)]
#: Companions, in half decades looser than the run (at most 100 times; -2: ten times
#: tighter, the fallback when no looser one brackets the error).
COMPANIONS = (1, 2, 3, 4, -2)
#: The estimate's cost target (companion's evaluations over the run's) and bracket.
COST_TARGET = 0.5
BRACKET = (0.3, 3.0)
OUT = Path(__file__).resolve().parents[2] / "rrt_pin" / "simulate" / "calibration.py"


def plan(only: set[str] | None) -> list[tuple[str, str]]:
    out = []
    for m in methods.METHODS.values():
        if not m.adaptive or (only and m.name not in only):
            continue
        out.extend((b, m.name) for b in ("pinocchio", "compiled") if m.runs_on(b))
    return out


def problems() -> dict:
    out = dict(PROBLEMS)
    for name, p in ROBOT_PROBLEMS.items():
        try:
            p.arm  # noqa: B018
        except RrtPinError as e:
            print(f"skipping {name}: {e}", file=sys.stderr)
            continue
        out[name] = p
    return out


def measure(pairs, scenes, budget: float) -> dict:
    """Raw measurements: per (backend, method, problem) the rungs' errors, evaluations, diffs."""
    raw: dict = {}
    refs = {}
    for backend, method in pairs:
        for name, problem in scenes.items():
            if backend not in problem.backends:
                continue
            if name not in refs:
                refs[name] = reference(problem).q
            ref = refs[name]
            try:  # compiles what the run needs (not timed against the budget)
                problem.run(backend=backend, method=method, rtol=1e-4, atol=1e-6,
                            estimate_error=False)  # fmt: skip
            except InputError as e:  # a method this problem's robot does not run (adams, the arm)
                print(f"{backend}/{method}/{name}: skipped: {e}", file=sys.stderr)
                continue
            except RrtPinError:
                pass
            rungs, qs = [], []
            for i, rtol in enumerate(LADDER):
                start = time.perf_counter()
                try:
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore", AccuracyWarning)
                        run = problem.run(backend=backend, method=method, rtol=rtol,
                                          atol=rtol / ATOL_RATIO, estimate_error=False)  # fmt: skip
                except RrtPinError as e:
                    rungs.append({"rtol": rtol, "error": math.inf, "evals": 0, "failed": str(e)})
                    qs.append(None)
                    continue
                took = time.perf_counter() - start
                q = np.array(run.q)
                diffs = {
                    str(j): max_error(q, qs[i - j])
                    for j in COMPANIONS
                    if 0 < j <= i and qs[i - j] is not None
                }
                rungs.append({"rtol": rtol, "error": max_error(q, ref), "evals": int(run.n_evals),
                              "time": took, "diffs": diffs})  # fmt: skip
                qs.append(q)
                if rungs[-1]["error"] < FLOOR or took > budget:
                    break
            key = f"{backend}/{method}/{name}"
            raw[key] = rungs
            worst = min(r["error"] for r in rungs)
            print(f"{key:<36} {len(rungs):>2} rungs, tightest error {worst:.1e}", flush=True)
    return raw


def errors_by_rung(rungs: list[dict]) -> list[float]:
    """Each rung's error, the last one measured standing for the tighter ones."""
    errs = [r["error"] for r in rungs]
    return errs + [errs[-1]] * (len(LADDER) - len(errs))


def envelope(per_problem: dict[str, list[float]]) -> list[float]:
    """Worst error of each rung over the problems, non-decreasing in rtol (loosest first)."""
    worst = [max(col) for col in zip(*per_problem.values(), strict=True)]
    for i in range(len(worst) - 2, -1, -1):
        worst[i] = max(worst[i], worst[i + 1])
    return worst


def choose(worst: list[float], accuracy: float, safety: float = 1.0) -> int:
    """The loosest rung whose worst error × safety is within accuracy (else the tightest)."""
    for i, e in enumerate(worst):
        if e * safety <= accuracy:
            return i
    return len(worst) - 1


def safety_factor(raw: dict, pairs) -> tuple[float, str]:
    """Leave one problem out: the largest error / accuracy of the rung the others choose."""
    best, where = 1.0, "none above 1"
    for backend, method in pairs:
        per = {k.split("/")[2]: errors_by_rung(v) for k, v in raw.items()
               if k.startswith(f"{backend}/{method}/")}  # fmt: skip
        for left in per:
            others = {k: v for k, v in per.items() if k != left}
            if not others:
                continue
            worst = envelope(others)
            for acc in ACCURACIES:
                i = choose(worst, acc)
                if worst[i] > acc:  # the ladder cannot reach it: not a generalisation test
                    continue
                ratio = per[left][i] / acc
                if math.isfinite(ratio) and ratio > best:  # a failed run: no generalisation test
                    best, where = ratio, f"{backend} {method}, {left} at {acc:g}"
    return best, where


def companion(raw: dict, backend: str, method: str, rungs: list[int]) -> dict:
    """The estimate's companion, measured at the rungs the accuracies 1e-6, 1e-8, 1e-10 choose.

    Among the companions whose estimate stays within :data:`BRACKET` of the true error
    on every problem (errors above 10·FLOOR), the one of least median cost (ties: the
    least worst cost); when none does, the narrowest bracket.
    """
    rows = []  # (j, problem, exact factor e/diff, cost)
    for key, runs in raw.items():
        if not key.startswith(f"{backend}/{method}/"):
            continue
        for i in sorted(set(rungs)):
            if i >= len(runs) or runs[i]["error"] < 10 * FLOOR:
                continue
            r = runs[i]
            for j in COMPANIONS:
                if j > 0:
                    d, other = r.get("diffs", {}).get(str(j)), runs[i - j]
                elif i - j < len(runs):  # tighter: the tighter rung's diff to this one
                    d, other = runs[i - j].get("diffs", {}).get(str(-j)), runs[i - j]
                else:
                    continue
                if d is None or d <= 0 or not other["evals"]:
                    continue
                rows.append((j, key.split("/")[2], r["error"] / d, other["evals"] / r["evals"]))
    candidates = []
    for j in COMPANIONS:
        sel = [x for x in rows if x[0] == j]
        if not sel:
            continue
        logs = np.log([x[2] for x in sel])
        factor = float(np.exp(logs.mean()))  # e ≈ factor · diff
        low, high = factor / float(np.exp(logs.max())), factor / float(np.exp(logs.min()))
        costs = [x[3] for x in sel]
        k = 10.0 ** (j / 2)
        rate = math.log(abs(1.0 + (1.0 if j > 0 else -1.0) / factor)) / math.log(k)
        row = {"j": j, "k": k, "rate": rate,
               "low": low, "high": high, "median_cost": float(np.median(costs)),
               "cost": max(costs), "n": len(sel), "ok": BRACKET[0] <= low and high <= BRACKET[1]}  # fmt: skip
        candidates.append(row)
        print(f"  {backend:<9} {method:<8} companion ×{k:<5.3g} rate p {row['rate']:.3f}  "
              f"estimate/true {low:.2f}–{high:.2f}  cost median {row['median_cost']:.2f}, "
              f"worst {row['cost']:.2f}  ({len(sel)} runs){'' if row['ok'] else '  outside'}")  # fmt: skip
    fits = [c for c in candidates if c["ok"]]
    if fits:
        return min(fits, key=lambda c: (c["median_cost"], c["cost"]))
    return min(candidates, key=lambda c: c["high"] / c["low"]) if candidates else {}


def summarise(raw: dict, pairs) -> dict:
    safety, where = safety_factor(raw, pairs)
    print(f"safety factor (leave one problem out): {safety:.3g} ({where})")
    table, estimate = {}, {}
    for backend, method in pairs:
        per = {k.split("/")[2]: errors_by_rung(v) for k, v in raw.items()
               if k.startswith(f"{backend}/{method}/")}  # fmt: skip
        worst = envelope(per)
        raw_worst = [max(col) for col in zip(*per.values(), strict=True)]
        names = list(per)
        which = [names[int(np.argmax(col))] for col in zip(*per.values(), strict=True)]
        table[(backend, method)] = tuple(zip(LADDER, raw_worst, which, strict=True))
        chosen = [choose(worst, acc, safety) for acc in (1e-6, 1e-8, 1e-10)]
        print(f"{backend:<9} {method:<8} accuracy 1e-6, 1e-8, 1e-10 -> rtol "
              f"{', '.join(f'{LADDER[i]:.3g}' for i in chosen)}")  # fmt: skip
        estimate[(backend, method)] = companion(raw, backend, method, chosen)
    return {"safety": safety, "where": where, "table": table, "estimate": estimate}


def render(result: dict) -> str:
    lines = [
        '"""The calibration of the default tolerances and of the error estimate (generated).',
        "",
        "Written by ``scripts/bench/calibrate.py`` (do not edit by hand; run it again after a",
        "change to a method or to the accuracy catalogue). :func:`rrt_pin.simulate.options.resolve`",
        "reads :data:`WORST` and :data:`SAFETY` to choose the tolerances for the accuracy asked",
        "for; :mod:`rrt_pin.simulate.estimate` reads :data:`COMPANIONS`.",
        '"""',
        "",
        "from __future__ import annotations",
        "",
        '__all__ = ["ATOL_RATIO", "COMPANIONS", "SAFETY", "WORST"]',
        "",
        "#: The measured safety factor: leaving one problem of the calibration out, the",
        "#: largest ratio of its error to the accuracy asked for at the rung the other",
        f"#: problems choose ({result['where']}).",
        f"SAFETY = {result['safety']:.3g}",
        "#: atol = rtol / ATOL_RATIO [rad, m, rad/s, m/s] at every rung.",
        f"ATOL_RATIO = {ATOL_RATIO:g}",
        "#: (backend, method) -> ((rtol, worst max |q − q_ref| over the calibration's",
        "#: problems [rad or m], the problem), ...), loosest first.",
        "WORST: dict[tuple[str, str], tuple[tuple[float, float, str], ...]] = {",
    ]
    for key, rows in result["table"].items():
        lines.append(f'    ("{key[0]}", "{key[1]}"): (')
        for r, e, name in rows:
            shown = f"{e:.3g}" if math.isfinite(e) else 'float("inf")'  # inf: a run failed
            lines.append(f'        ({r!r}, {shown}, "{name}"),')  # the rtol measured, exactly
        lines.append("    ),")
    lines += [
        "}",
        "#: (backend, method) -> (k, p): the estimate's companion runs at k times the run's",
        "#: rtol and atol, and the run's error is |q − q_companion| / (k^p − 1), p the",
        "#: measured rate of error ∝ tolᵖ.",
        "COMPANIONS: dict[tuple[str, str], tuple[float, float]] = {",
    ]
    for key, c in result["estimate"].items():
        if c:
            lines.append(f'    ("{key[0]}", "{key[1]}"): ({c["k"]:.4g}, {c["rate"]:.3g}),')
    lines.append("}")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--methods", default=None, help="comma-separated methods (default: all)")
    ap.add_argument("--backends", default=None, help="comma-separated backends (default: all)")
    ap.add_argument("--problems", default=None, help="comma-separated problems (default: all)")
    ap.add_argument(
        "--merge",
        action="append",
        default=[],
        help="raw measurements (JSON) to merge into --from-raw's or the new ones",
    )
    ap.add_argument("--raw", default=None, help="write the raw measurements (JSON) here")
    ap.add_argument("--from-raw", default=None, help="read them from here instead of running")
    ap.add_argument("--write", action="store_true", help=f"write {OUT.name}")
    ap.add_argument("--budget", type=float, default=20.0, help="seconds a run may take [s]")
    args = ap.parse_args(argv)
    pairs = plan(set(args.methods.split(",")) if args.methods else None)
    if args.backends:
        pairs = [p for p in pairs if p[0] in args.backends.split(",")]
    if args.from_raw:
        raw = json.loads(Path(args.from_raw).read_text())
    else:
        scenes = problems()
        if args.problems:
            scenes = {k: v for k, v in scenes.items() if k in args.problems.split(",")}
        raw = measure(pairs, scenes, args.budget)
        if args.raw:
            Path(args.raw).write_text(json.dumps(raw))
    for path in args.merge:
        raw.update(json.loads(Path(path).read_text()))
    have = {tuple(k.split("/")[:2]) for k in raw}
    pairs = [p for p in plan(None) if p in have]
    result = summarise(raw, pairs)
    if args.write:
        OUT.write_text(render(result))
        print(f"wrote {OUT}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
