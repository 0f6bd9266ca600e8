"""``rrt-pin equations``: print the RRT arm's equations of motion, by Kane or Lagrange."""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from rrt_pin.cli.commands._common import add_param_arguments, params_from_args

if TYPE_CHECKING:
    pass

HELP = (
    "print the equations of motion M(q)·q̈ = f(q, q̇, T01x, T12y, F23z) derived symbolically "
    "(q1, q2 [rad], q3 [m]; rows 1, 2 in N·m, row 3 in N); needs sympy"
)

_TITLE = {"kane": "Kane's method, eqs. (16)–(29)", "lagrange": "Lagrange's equations"}


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``rrt-pin equations``."""
    parser.add_argument(
        "--method",
        choices=("kane", "lagrange"),
        default="kane",
        help="derivation: Kane's generalized inertia forces or Lagrange's equations "
        "(default: kane)",
    )
    parser.add_argument(
        "--format",
        choices=("text", "pretty", "latex"),
        default="text",
        help="text: one plain line per equation (qdot1 = q̇1 [rad/s], qddot1 = q̈1 [rad/s²]); "
        "pretty: sympy's 2-D Unicode layout; latex: an align environment (default: text)",
    )
    parser.add_argument(
        "--steps",
        action="store_true",
        help="also print the intermediate results: rotation matrices, angular and linear "
        "velocities and accelerations, Q, kinetic energies, and K* (kane) or "
        "d/dt ∂T/∂q̇r − ∂T/∂qr (lagrange)",
    )
    add_param_arguments(parser)
    parser.epilog = (
        "Parameters stay symbols (SI units: m, kg, kg·m², m/s²) unless --set or --config "
        "is given, which substitutes the numbers."
    )


def run(args: argparse.Namespace) -> int:
    """Derive and print the equations."""
    from rrt_pin.core.extras import require

    sp = require("sympy", "symbolic", "'rrt-pin equations'")
    from rrt_pin.dynamics.symbolic import equations_of_motion

    numeric = bool(args.overrides) or getattr(args, "runfile", None) is not None
    params = params_from_args(args) if numeric else None
    eom = equations_of_motion(args.method, params)
    values = _substitution(params) if params is not None else {}
    lines: list[str] = []
    if args.steps:
        from rrt_pin.dynamics.symbolic.steps import derivation_steps

        steps = derivation_steps(args.method)
        lines += _steps(steps, args.format, values, sp)
    lines += _equations(eom, args.format, sp)
    sys.stdout.write("\n".join(lines) + "\n")
    return 0


def _substitution(params) -> dict:
    import sympy as sp

    from rrt_pin.dynamics.symbolic.symbols import LB, PARAM_NAMES, PARAMS

    values = {s: sp.Float(getattr(params, n)) for s, n in zip(PARAMS, PARAM_NAMES, strict=True)}
    values[LB] = sp.Float(params.LB)
    return values


def _text(expr, fmt: str, sp) -> str:
    if fmt == "pretty":
        return sp.pretty(expr, use_unicode=True, wrap_line=False)
    return sp.sstr(expr, full_prec=False)


def _latex(expr, sp) -> str:
    from rrt_pin.dynamics.symbolic.steps import LATEX_NAMES

    return sp.latex(expr, symbol_names=LATEX_NAMES)


def _vector(step, fmt: str, sp) -> str:
    terms = []
    for c, u in zip(step.value, step.basis, strict=True):
        if c == 0:
            continue
        if fmt == "latex":
            inner = _latex(c, sp)
            unit = _latex(u, sp)
            terms.append(f"\\left({inner}\\right) {unit}" if c.is_Add else f"{inner}\\, {unit}")
        else:
            inner = sp.sstr(c, full_prec=False)
            terms.append(f"({inner})*{u}" if c.is_Add else f"{inner}*{u}")
    if not terms:
        return "0"
    return " + ".join(terms).replace("+ - ", "- ").replace("+ -", "- ")


def _steps(steps, fmt: str, values: dict, sp) -> list[str]:
    out = []
    if fmt == "latex":
        out += ["% Intermediate results (the chapter's symbols; SI units)", r"\begin{align*}"]
    else:
        out += ["# Intermediate results (the chapter's symbols; SI units)"]
    for step in steps:
        if values:
            step = type(step)(
                step.name, step.label, step.value.xreplace(values), step.latex, step.basis
            )
        if fmt == "latex":
            body = _vector(step, fmt, sp) if step.basis else _latex(step.value, sp)
            out.append(f"{step.latex} &= {body} && \\text{{{step.label}}} \\\\")
        elif step.basis:
            out.append(f"{step.name} [{step.label}] = {_vector(step, fmt, sp)}")
        else:
            body = _text(step.value, fmt, sp)
            sep = "\n" if "\n" in body else " "
            out.append(f"{step.name} [{step.label}] ={sep}{body}")
    if fmt == "latex":
        out.append(r"\end{align*}")
    out.append("")
    return out


def _equations(eom, fmt: str, sp) -> list[str]:
    title = f"Equations of motion of the RRT arm ({_TITLE[eom.method]}): M(q)·q̈ = f"
    legend = (
        "q1, q2 [rad], q3 [m]; qdot = q̇, qddot = q̈; T01x, T12y [N·m], F23z [N]; "
        "rows 1, 2 in N·m, row 3 in N"
        + ("" if eom.params is None else "; numbers substituted (SI units)")
        + ("" if eom.params is not None else "; LB = 2·L1 substituted")
    )
    eqs = eom.equations()
    if fmt == "latex":
        body = [f"{_latex(e.lhs, sp)} &= {_latex(e.rhs, sp)} \\\\" for e in eqs]
        return [f"% {title}", f"% {legend}", r"\begin{align}", *body, r"\end{align}"]
    out = [f"# {title}", f"# {legend}"]
    for r, e in enumerate(eqs, 1):
        if fmt == "pretty":
            out += [f"({r})", sp.pretty(e, use_unicode=True, wrap_line=False), ""]
        else:
            lhs, rhs = (sp.sstr(x, full_prec=False) for x in (e.lhs, e.rhs))
            out.append(f"({r}) {lhs} = {rhs}")
    return out
