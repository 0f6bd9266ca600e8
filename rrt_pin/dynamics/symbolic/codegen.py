"""Generate ``rrt_pin/dynamics/_kernel_terms.py``, the arm's dynamics expressions, from the sympy derivation.

The kernel's ``terms`` is straight-line Python made by common-subexpression
elimination (``sympy.cse``) of the mass matrix, the velocity terms and the
gravity terms of Kane's equations, using only ``sin``, ``cos`` (from numpy)
and arithmetic: it runs on floats, on numpy arrays and under ``numba.njit``.
Its ``inverse_terms`` (τ) and ``forward_terms`` (the diagonal of M, c and G) are
printed from hand-factored plans (``SHARED_LINES``, ``INVERSE_LINES``,
``FORWARD_LINES``) that :func:`check_inverse_plan` proves equal to Kane's
equations before every write; ``INVERSE_FLOPS``/``FORWARD_FLOPS`` count their
operations.

Usage::

    python -m rrt_pin.dynamics.symbolic.codegen            # rewrite rrt_pin/dynamics/_kernel_terms.py
    python -m rrt_pin.dynamics.symbolic.codegen --check    # exit 1 if the file is stale
    python -m rrt_pin.dynamics.symbolic.codegen -o PATH    # write elsewhere
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import sympy as sp
from sympy.printing.pycode import PythonCodePrinter

from rrt_pin.dynamics.symbolic.eom import equations_of_motion
from rrt_pin.dynamics.symbolic.simplify import readable
from rrt_pin.dynamics.symbolic.symbols import PARAM_NAMES
from rrt_pin.io.files import atomic_write_text

__all__ = [
    "INVERSE_CONSTANTS",
    "FORWARD_LINES",
    "INVERSE_LINES",
    "SHARED_LINES",
    "KERNEL_PATH",
    "OUTPUT_NAMES",
    "check_inverse_plan",
    "kernel_expressions",
    "kernel_source",
    "main",
    "flop_count",
]

#: Where the generated kernel lives.
KERNEL_PATH = Path(__file__).resolve().parents[1] / "_kernel_terms.py"
#: The names ``terms`` returns, in order.
OUTPUT_NAMES = ("M11", "M12", "M13", "M22", "M23", "M33", "c1", "c2", "c3", "G1", "G2", "G3")
_STATE_NAMES = ("q1", "q2", "q3", "qd1", "qd2", "qd3")


def kernel_expressions() -> tuple[tuple[sp.Symbol, ...], tuple[sp.Expr, ...]]:
    """The arguments and the 12 expressions of ``terms``, from Kane's equations.

    Returns:
        (arguments: q1, q2, q3, qd1, qd2, qd3 and the parameters in
        ``PARAM_ORDER``; expressions: M11, M12, M13, M22, M23, M33, c1, c2,
        c3, G1, G2, G3).
    """
    eom = equations_of_motion("kane")
    names = dict(zip(eom.states, _STATE_NAMES, strict=True))
    rename = {s: sp.Symbol(n, real=True) for s, n in names.items()}
    args = (*(rename[s] for s in eom.states), *eom.parameters)
    M = eom.mass_matrix
    keys = [rename[eom.qd[i]] * rename[eom.qd[j]] for i in range(3) for j in range(i, 3)]
    entries = [M[0, 0], M[0, 1], M[0, 2], M[1, 1], M[1, 2], M[2, 2]]
    exprs = [
        *(e.xreplace(rename) for e in entries),
        *(readable(e.xreplace(rename), keys) for e in eom.velocity_terms),
        *(sp.factor(e.xreplace(rename)) for e in eom.gravity),
    ]
    return args, tuple(exprs)


# The inverse dynamics τ = M(q)·q̈ + c(q, q̇) + G(q), factored by hand and PROVED equal
# to Kane's equations by check_inverse_plan() every time the kernel is generated: the
# structural zeros M12 = M13 = M23 = G1 = 0 are never multiplied, q3 enters only
# through r = L2 + q3 (the distance B→C3 [m]), and the products that several joints
# share are computed once. Per call, parameter-only combinations (INVERSE_CONSTANTS);
# per sample, cos q2 (c2) and sin q2 (s2) are inputs, so a caller computes them
# vectorized (numpy, or Cephes' polynomials under numba) and only once.
#: (name, Python expression in the parameters), evaluated once per call.
INVERSE_CONSTANTS = (
    ("kM11", "I1x + I2z + I3z + L1**2*(m1 + 4*(m2 + m3))"),
    ("kP", "I2x - I2z + I3x - I3z + m2*L2**2"),
    ("kM22", "I2y + I3y + m2*L2**2"),
    ("kS", "m2*L2"),
    ("L1x2", "2*L1"),
    ("m3L1x2", "2*L1*m3"),
    ("gm3", "g*m3"),
)
#: (name, Python expression): the first lines of ``inverse_terms`` and ``forward_terms``.
SHARED_LINES = (
    ("r", "L2 + q3"),  # B→C3 [m]
    ("mr", "m3*r"),
    ("mrr", "mr*r"),
    ("S", "kS + mr"),  # first moment of links 2 and 3 about B along k2 [kg·m]
    ("u", "L1x2*S"),
    ("H", "c2*(kP + mrr) + u"),
    ("x19", "s2*H"),
    ("x15", "c2*(m3L1x2 + c2*mr)"),
    ("w1", "qd1*qd1"),
)
#: (name, Python expression), the lines of ``inverse_terms`` after SHARED_LINES.
INVERSE_LINES = (
    ("tau1", "(kM11 + c2*(H + u))*qdd1 + 2*qd1*(qd3*x15 - qd2*x19)"),
    ("tau2", "(kM22 + mrr)*qdd2 + w1*x19 + (2*qd2*qd3*mr + g*c2*S)"),
    ("tau3", "m3*qdd3 - (qd2*qd2*mr + w1*x15) + gm3*s2"),
)
#: (name, Python expression), the lines of ``forward_terms`` after SHARED_LINES: the
#: diagonal of M (M12 = M13 = M23 = 0, M33 = m3, proved), c and the non-zero G.
FORWARD_LINES = (
    ("M11", "kM11 + c2*(H + u)"),
    ("M22", "kM22 + mrr"),
    ("n1", "2*qd1*(qd3*x15 - qd2*x19)"),
    ("n2", "w1*x19 + 2*qd2*qd3*mr"),
    ("n3", "-(qd2*qd2*mr + w1*x15)"),
    ("G2", "g*c2*S"),
    ("G3", "gm3*s2"),
)
_INVERSE_INPUTS = ("c2", "s2", "q3", "qd1", "qd2", "qd3", "qdd1", "qdd2", "qdd3")


def flop_count(source: str) -> int:
    """Floating-point operations of one Python expression: +, −, ·, /, and x**2 as one product."""
    import ast

    count = 0
    for node in ast.walk(ast.parse(source, mode="eval")):
        if isinstance(node, ast.BinOp):
            if isinstance(node.op, ast.Pow):
                if not (isinstance(node.right, ast.Constant) and node.right.value == 2):
                    raise ValueError(f"only squares are counted, not {ast.unparse(node)}")
            count += 1
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            count += 1
    return count


def check_inverse_plan() -> None:
    """Prove the plans of ``inverse_terms`` and ``forward_terms`` equal to Kane's equations.

    τ_i = Σ_j M_ij q̈_j + c_i + G_i with M, c, G of :func:`kernel_expressions`;
    forward_terms' M11, M22, c and G2, G3 those of Kane, and M12 = M13 = M23 =
    G1 = 0, M33 = m3. Each difference, a polynomial in c2 = cos q2 and
    s2 = sin q2, must vanish modulo c2² + s2² − 1.

    Raises:
        AssertionError: a line of the plan is wrong.
    """
    args, exprs = kernel_expressions()
    by_name = {str(a): a for a in args}
    c2, s2 = sp.symbols("c2 s2", real=True)
    qdd = sp.symbols("qdd1 qdd2 qdd3", real=True)
    scope: dict[str, sp.Expr] = {**by_name, "c2": c2, "s2": s2}
    scope.update({str(a): a for a in qdd})
    for name, source in (*INVERSE_CONSTANTS, *SHARED_LINES, *INVERSE_LINES, *FORWARD_LINES):
        scope[name] = sp.sympify(source, locals=scope)
    M11, M12, M13, M22, M23, M33, cv1, cv2, cv3, G1, G2, G3 = exprs
    M = sp.Matrix([[M11, M12, M13], [M12, M22, M23], [M13, M23, M33]])
    tau = M * sp.Matrix(qdd) + sp.Matrix([cv1, cv2, cv3]) + sp.Matrix([G1, G2, G3])
    q2 = by_name["q2"]
    claims = {f"tau{i + 1}": tau[i] for i in range(3)}
    # forward_terms: the structural zeros it leaves out, then its outputs.
    claims.update({"0 (M12)": M12, "0 (M13)": M13, "0 (M23)": M23, "0 (G1)": G1})
    claims.update({"M11": M11, "M22": M22, "m3": M33, "G2": G2, "G3": G3})
    claims.update({"n1": cv1, "n2": cv2, "n3": cv3})
    for name, kane in claims.items():
        mine = scope[name] if name in scope else sp.Integer(0)
        difference = sp.expand(mine - kane.subs({sp.cos(q2): c2, sp.sin(q2): s2}))
        remainder = sp.rem(sp.Poly(difference, s2), sp.Poly(s2**2 + c2**2 - 1, s2))
        assert sp.expand(remainder.as_expr()) == 0, f"{name} of the plan differs: {remainder}"


def _inverse_source() -> str:
    check_inverse_plan()
    params = ", ".join(PARAM_NAMES)
    consts = "\n".join(f"    {n} = {src}" for n, src in INVERSE_CONSTANTS)
    names = ", ".join(n for n, _ in INVERSE_CONSTANTS)
    lines = "\n".join(f"    {n} = {src}" for n, src in (*SHARED_LINES, *INVERSE_LINES))
    flops = sum(flop_count(src) for _, src in (*SHARED_LINES, *INVERSE_LINES))
    fwd_lines = "\n".join(f"    {n} = {src}" for n, src in (*SHARED_LINES, *FORWARD_LINES))
    fwd_flops = sum(flop_count(src) for _, src in (*SHARED_LINES, *FORWARD_LINES))
    trailing = ("m3", "L2", "g", *(n for n, _ in INVERSE_CONSTANTS))
    signature = ", ".join((*_INVERSE_INPUTS, *trailing))
    fwd_signature = ", ".join((*_INVERSE_INPUTS[:6], *trailing))
    fwd_names = ", ".join(n for n, _ in FORWARD_LINES)
    return (
        "\n\n#: Floating-point operations of ``inverse_terms`` per sample (sin and cos excluded).\n"
        f"INVERSE_FLOPS = {flops}\n"
        "#: Floating-point operations of ``forward_terms`` per sample (sin and cos excluded).\n"
        f"FORWARD_FLOPS = {fwd_flops}\n\n\n"
        f"def inverse_constants({params}):\n"
        f"{_CONSTANTS_DOC}"
        "    # fmt: off\n" + consts + "\n    # fmt: on\n"
        f"    return (m3, L2, g, {names})\n\n\n"
        f"def inverse_terms(\n    {signature}\n):\n"
        f"{_INVERSE_DOC}"
        "    # fmt: off\n" + lines + "\n    # fmt: on\n"
        "    return (tau1, tau2, tau3)\n\n\n"
        f"def forward_terms({fwd_signature}):\n"
        f"{_FORWARD_DOC}"
        "    # fmt: off\n" + fwd_lines + "\n    # fmt: on\n"
        f"    return ({fwd_names})\n"
    )


_FORWARD_DOC = '''    """The non-zero terms of M(q)·q̈ + c(q, q̇) + G(q) = τ, for the forward dynamics.

    M is diagonal (M12 = M13 = M23 = 0 and M33 = m3, proved when generated) and
    G1 = 0, so q̈ = ((τ1 − n1) / M11, (τ2 − n2 − G2) / M22, (τ3 − n3 − G3) / m3).
    ``FORWARD_FLOPS`` operations a sample, sine and cosine excluded.

    Args:
        c2: cos q2 [1].
        s2: sin q2 [1].
        q3: slider position C2→C3 [m].
        qd1: q̇1 [rad/s].
        qd2: q̇2 [rad/s].
        qd3: q̇3 [m/s].
        m3: mass of link 3 [kg].
        L2: distance B→C2 [m].
        g: gravitational acceleration [m/s²].
        kM11: see :func:`inverse_terms` (the trailing arguments are the same).
        kP: see :func:`inverse_terms`.
        kM22: see :func:`inverse_terms`.
        kS: see :func:`inverse_terms`.
        L1x2: see :func:`inverse_terms`.
        m3L1x2: see :func:`inverse_terms`.
        gm3: see :func:`inverse_terms`.

    Returns:
        (M11 [kg·m²], M22 [kg·m²], c1 [N·m], c2 [N·m], c3 [N], G2 [N·m], G3 [N]).
    """
'''


_CONSTANTS_DOC = '''    """The per-call constants of :func:`inverse_terms`: combinations of the parameters.

    Takes the parameters in ``PARAM_ORDER`` (SI units), as ``terms`` does.

    Returns:
        (m3 [kg], L2 [m], g [m/s²], kM11 [kg·m²], kP [kg·m²], kM22 [kg·m²],
        kS [kg·m], L1x2 [m], m3L1x2 [kg·m], gm3 [N]), the trailing arguments of
        :func:`inverse_terms` in order.
    """
'''

_INVERSE_DOC = '''    """τ = M(q)·q̈ + c(q, q̇) + G(q) from cos q2 and sin q2, at one sample or many.

    The hand-factored form of ``rrt_pin.dynamics.symbolic.codegen.INVERSE_LINES``, proved
    equal to Kane's equations when generated: no product by a structural zero of
    M or G, products shared by the joints computed once, ``INVERSE_FLOPS``
    operations a sample.

    Args:
        c2: cos q2 [1].
        s2: sin q2 [1].
        q3: slider position C2→C3 [m].
        qd1: q̇1 [rad/s].
        qd2: q̇2 [rad/s].
        qd3: q̇3 [m/s].
        qdd1: q̈1 [rad/s²].
        qdd2: q̈2 [rad/s²].
        qdd3: q̈3 [m/s²].
        m3: mass of link 3 [kg].
        L2: distance B→C2 [m].
        g: gravitational acceleration [m/s²].
        kM11: I1x + I2z + I3z + L1²·(m1 + 4·(m2 + m3)) [kg·m²].
        kP: I2x − I2z + I3x − I3z + m2·L2² [kg·m²].
        kM22: I2y + I3y + m2·L2² [kg·m²].
        kS: m2·L2 [kg·m].
        L1x2: 2·L1 = LB [m].
        m3L1x2: 2·L1·m3 [kg·m].
        gm3: g·m3 [N].

    Returns:
        (T01x [N·m], T12y [N·m], F23z [N]).
    """
'''


class _Printer(PythonCodePrinter):
    """Python code with bare ``sin``/``cos`` (imported from numpy by the kernel)."""

    def __init__(self) -> None:
        super().__init__({"fully_qualified_modules": False, "standard": "python3"})


def _body() -> str:
    args, exprs = kernel_expressions()
    temporaries, reduced = sp.cse(list(exprs), symbols=sp.numbered_symbols("x"), order="canonical")
    printer = _Printer()
    lines = [f"    {name} = {printer.doprint(value)}" for name, value in temporaries]
    for name, value in zip(OUTPUT_NAMES, reduced, strict=True):
        text = printer.doprint(value)
        if value.is_number:
            text = repr(float(value))
        lines.append(f"    {name} = {text}")
    signature = ", ".join(str(a) for a in args)
    return (
        f"def terms(\n    {signature}\n):\n"
        f"{_TERMS_DOC}"
        "    # fmt: off\n" + "\n".join(lines) + "\n    # fmt: on\n"
        f"    return ({', '.join(OUTPUT_NAMES)})\n"
    )


_TERMS_DOC = '''    """Mass-matrix entries, velocity terms and gravity terms at one state or many.

    M(q)·q̈ + c(q, q̇) + G(q) = τ = (T01x [N·m], T12y [N·m], F23z [N]).

    Args:
        q1: angle of link 1 about ı0 [rad].
        q2: angle of link 2 about ȷ1 [rad].
        q3: slider position C2→C3 [m].
        qd1: q̇1 [rad/s].
        qd2: q̇2 [rad/s].
        qd3: q̇3 [m/s].
        L1: distance A→C1 [m] (LB = 2·L1).
        L2: distance B→C2 [m].
        m1: mass of link 1 [kg].
        m2: mass of link 2 [kg].
        m3: mass of link 3 [kg].
        I1x: central moment of link 1 about ı1 [kg·m²].
        I1y: central moment of link 1 about ȷ1 [kg·m²].
        I1z: central moment of link 1 about k1 [kg·m²].
        I2x: central moment of link 2 about ı2 [kg·m²].
        I2y: central moment of link 2 about ȷ2 [kg·m²].
        I2z: central moment of link 2 about k2 [kg·m²].
        I3x: central moment of link 3 about ı2 [kg·m²].
        I3y: central moment of link 3 about ȷ2 [kg·m²].
        I3z: central moment of link 3 about k2 [kg·m²].
        g: gravitational acceleration [m/s²].

    All arguments are floats or broadcastable numpy arrays; under
    ``numba.njit`` floats or arrays.

    Returns:
        (M11, M12, M13, M22, M23, M33 [kg·m², kg·m, kg], c1, c2, c3 and
        G1, G2, G3 [N·m, N·m, N]); entries that do not depend on the state
        are plain floats.
    """
'''

_HEADER = '''"""Expressions of the RRT arm's dynamics, GENERATED from the sympy derivation: do not edit.

Generated by ``python -m rrt_pin.dynamics.symbolic.codegen`` (or ``scripts/generate_kernel.py``)
from Kane's equations in ``rrt_pin/dynamics/symbolic``; ``tests/test_kernel.py`` fails
when this file drifts from the derivation. Only the expressions are generated:
:mod:`rrt_pin.dynamics.kernel` (ordinary code) wraps them for arrays of states.

``terms`` is straight-line code (common subexpressions eliminated) using only
``sin``, ``cos`` and arithmetic, so it runs on floats, on numpy arrays
(vectorized over samples) and unchanged under ``numba.njit``. ``inverse_terms``
is the inverse dynamics alone, hand-factored in the generator and proved equal
to Kane's equations there: no product by a structural zero, shared products
computed once, cos q2 and sin q2 taken as inputs. The parameters come in the
order of :data:`rrt_pin.robot.params.PLANT_FIELDS`. Units: q [rad, rad, m], q̇ [rad/s,
rad/s, m/s], q̈ [rad/s², rad/s², m/s²], τ = (T01x [N·m], T12y [N·m], F23z [N]).
"""

from __future__ import annotations

from numpy import cos, sin

__all__ = [
    "FORWARD_FLOPS",
    "INVERSE_FLOPS",
    "forward_terms",
    "inverse_constants",
    "inverse_terms",
    "terms",
]


'''


def kernel_source() -> str:
    """The full text of ``rrt_pin/dynamics/_kernel_terms.py`` (deterministic)."""
    return _HEADER + _body() + _inverse_source()


def main(argv: list[str] | None = None) -> int:
    """Write (or ``--check``) the generated kernel; returns the exit status."""
    parser = argparse.ArgumentParser(
        prog="python -m rrt_pin.dynamics.symbolic.codegen", description=__doc__.splitlines()[0]
    )
    parser.add_argument("-o", "--output", type=Path, default=KERNEL_PATH, help="file to write")
    parser.add_argument(
        "--check", action="store_true", help="only compare; exit 1 if the file differs"
    )
    args = parser.parse_args(argv)
    source = kernel_source()
    if args.check:
        current = args.output.read_text(encoding="utf-8") if args.output.exists() else ""
        if current != source:
            print(f"{args.output} is stale: regenerate it", file=sys.stderr)
            return 1
        return 0

    atomic_write_text(args.output, source)
    print(f"wrote {args.output}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
