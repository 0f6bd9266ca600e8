"""Canonical forms for trigonometric polynomials in q2 (and q1): the derivation's normal form.

Every entry of M and f is a polynomial in sin qi, cos qi and the other symbols.
Reducing it modulo sin² + cos² − 1 (lex order, sin first) leaves sin qi to at
most the first power: a unique representative, so two derivations agree exactly
when their normal forms are equal.
"""

from __future__ import annotations

import sympy as sp

__all__ = ["readable", "trig_normal"]


def trig_normal(expr: sp.Expr, angles: tuple[sp.Symbol, ...]) -> sp.Expr:
    """``expr`` reduced modulo sin²(a) + cos²(a) − 1 for every angle a in ``angles``.

    Args:
        expr: a polynomial in sin(a), cos(a) (double angles allowed) and other symbols.
        angles: plain symbols of the angles [rad].
    """
    expr = sp.expand(sp.expand_trig(expr))
    gens: list[sp.Symbol] = []
    back: dict[sp.Symbol, sp.Expr] = {}
    rules: list[sp.Expr] = []
    for a in angles:
        s, c = sp.Dummy(f"s_{a}"), sp.Dummy(f"c_{a}")
        expr = expr.subs({sp.sin(a): s, sp.cos(a): c})
        gens += [s, c]
        back.update({s: sp.sin(a), c: sp.cos(a)})
        rules.append(s**2 + c**2 - 1)
    if not gens or not expr.has(*gens):
        return sp.expand(expr.subs(back))
    _, remainder = sp.reduced(sp.expand(expr), rules, *gens, order="lex")
    return sp.expand(remainder.subs(back))


def readable(expr: sp.Expr, keys: list[sp.Expr], angles: tuple[sp.Symbol, ...] = ()) -> sp.Expr:
    """``expr`` collected for display.

    Collected on the monomials ``keys`` (e.g. q̈r, q̇r·q̇s, efforts, g); each
    coefficient is collected on the powers of sin and cos of ``angles`` with
    factored coefficients (left unfactored when they hold floating-point numbers).
    """
    trig = [f(a) for a in angles for f in (sp.cos, sp.sin)]

    def factor(c: sp.Expr) -> sp.Expr:
        return c if c.has(sp.Float) else sp.factor(c)

    def inner(c: sp.Expr) -> sp.Expr:
        if not trig:
            return factor(c)
        return sp.collect(sp.expand(c), trig, func=factor)

    return sp.collect(sp.expand(expr), keys, func=inner)
