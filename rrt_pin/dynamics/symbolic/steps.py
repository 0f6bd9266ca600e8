"""The intermediate results of the derivation, in the chapter's order, for display.

Vectors are written as sums of components times unit-vector symbols (``i2``,
``j2``, ``k2``…) in the frame the chapter uses for them; every expression is in
plain symbols (``qdot1`` for q̇1, ``qddot1`` for q̈1) with its trigonometric
normal form.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import sympy as sp
from sympy.physics.mechanics import ReferenceFrame, Vector

from rrt_pin.core.errors import ParameterError
from rrt_pin.dynamics.symbolic.simplify import readable, trig_normal
from rrt_pin.dynamics.symbolic.symbols import EFFORTS, g, q_plain, qd_plain, qdd_plain, to_plain
from rrt_pin.dynamics.symbolic.symbols import LATEX_NAMES as SYMBOL_LATEX

__all__ = [
    "LATEX_NAMES",
    "Step",
    "derivation_steps",
    "unit_symbols",
    "vector_components",
]

#: LaTeX of the unit-vector symbols of :func:`unit_symbols` and of the parameters.
LATEX_NAMES = {
    **SYMBOL_LATEX,
    **{
        sp.Symbol(f"{u}{n}"): rf"\hat{{{tex}}}_{{{n}}}"
        for n in range(3)
        for u, tex in (("i", r"\imath"), ("j", r"\jmath"), ("k", "k"))
    },
}


@dataclass(frozen=True)
class Step:
    """One intermediate result.

    Attributes:
        name: the chapter's symbol, e.g. ``vC2``.
        label: where the chapter states it, e.g. ``eq. (10)``.
        value: a sympy expression or matrix; for a vector, its 3×1 matrix of
            components along ``basis``.
        latex: the symbol in LaTeX, e.g. ``v_{C_2}``.
        basis: the unit-vector symbols (e.g. ``i2, j2, k2``) when ``value``
            holds a vector's components, else None.
    """

    name: str
    label: str
    value: sp.Basic
    latex: str
    basis: tuple[sp.Symbol, ...] | None = None

    def expr(self) -> sp.Basic:
        """``value``, with a vector written as Σ component·unit-vector symbol."""
        if self.basis is None:
            return self.value
        return sp.Add(*(c * u for c, u in zip(self.value, self.basis, strict=True)))


def _tidy(expr: sp.Expr) -> sp.Expr:
    expr = trig_normal(to_plain(expr), q_plain[:2])
    keys = [
        *qdd_plain,
        *(qd_plain[i] * qd_plain[j] for i in range(3) for j in range(i, 3)),
        *qd_plain,
        *EFFORTS,
        g,
    ]
    return readable(expr, keys, q_plain[:2])


def vector_components(vector: Vector, frame: ReferenceFrame) -> sp.ImmutableMatrix:
    """The components of ``vector`` along the unit vectors of ``frame`` (3×1)."""
    return sp.ImmutableMatrix([_tidy(vector.dot(e)) for e in (frame.x, frame.y, frame.z)])


def unit_symbols(frame: ReferenceFrame) -> tuple[sp.Symbol, ...]:
    """The unit-vector symbols ``i<n>, j<n>, k<n>`` of frame (n)."""
    n = frame.name[-1]
    return tuple(sp.Symbol(f"{u}{n}") for u in "ijk")


def _vstep(name: str, label: str, vector: Vector, frame: ReferenceFrame, tex: str) -> Step:
    return Step(name, label, vector_components(vector, frame), tex, unit_symbols(frame))


@cache
def derivation_steps(method: str = "kane") -> tuple[Step, ...]:
    """The chapter's intermediate results, then those of ``method`` ("kane" or "lagrange").

    Kinematics and generalized active forces come first (eqs. 2–15), then the
    kinetic energies; Kane adds the inertia moments and the generalized inertia
    forces K*r (eqs. 24–28), Lagrange the left-hand sides d/dt ∂T/∂q̇r − ∂T/∂qr.
    Cached per method.

    Raises:
        ParameterError: ``method`` is neither "kane" nor "lagrange".
    """
    from rrt_pin.dynamics.symbolic import energy, forces, frames, kinematics

    f1, f2 = frames.frame1, frames.frame2
    k = kinematics
    vec = [
        ("omega10", "eq. (5)", k.omega10, f1, r"\omega_{10}"),
        ("omega20", "eq. (6)", k.omega20, f2, r"\omega_{20}"),
        ("alpha10", "eq. (7)", k.alpha10, f1, r"\alpha_{10}"),
        ("alpha20", "eq. (8)", k.alpha20, f2, r"\alpha_{20}"),
        ("rC1", "above eq. (9)", k.rC1, f1, r"r_{C_1}"),
        ("vC1", "eq. (9)", k.vC1, f1, r"v_{C_1}"),
        ("rC2", "above eq. (10)", k.rC2, f2, r"r_{C_2}"),
        ("vC2", "eq. (10)", k.vC2, f2, r"v_{C_2}"),
        ("rC3", "above eq. (11)", k.rC3, f2, r"r_{C_3}"),
        ("vC3", "eq. (11)", k.vC3, f2, r"v_{C_3}"),
        ("aC1", "eq. (12)", k.aC1, f1, r"a_{C_1}"),
        ("aC2", "eq. (13)", k.aC2, f2, r"a_{C_2}"),
        ("aC3", "eq. (14)", k.aC3, f2, r"a_{C_3}"),
        ("vC32", "before eq. (15)", k.vC32, f2, r"v_{C_{32}}"),
        ("G2", "before eq. (15)", forces.G2, f2, r"G_2"),
        ("G3", "before eq. (15)", forces.G3, f2, r"G_3"),
    ]
    out = [
        Step("R10", "eq. (2)", sp.ImmutableMatrix(frames.R10.applyfunc(to_plain)), r"R_{10}"),
        Step("R21", "eq. (4)", sp.ImmutableMatrix(frames.R21.applyfunc(to_plain)), r"R_{21}"),
        *(_vstep(*item) for item in vec),
        *(Step(f"Q{r}", "eq. (15)", _tidy(e), f"Q_{r}") for r, e in enumerate(forces.Q, 1)),
        *(
            Step(f"T{i}", "kinetic energy", _tidy(e), f"T_{i}")
            for i, e in enumerate((energy.T1, energy.T2, energy.T3), 1)
        ),
    ]
    if method == "kane":
        from rrt_pin.dynamics.symbolic import kane

        out += [
            _vstep("Min1", "eq. (24)", kane.Min1, f1, r"M_{in\,1}"),
            _vstep("Min2", "after eq. (24)", kane.Min2, f2, r"M_{in\,2}"),
            _vstep("Min3", "eq. (25)", kane.Min3, f2, r"M_{in\,3}"),
        ]
        out += [
            Step(f"K*{r}", "eq. (28)", _tidy(e), f"K^*_{r}")
            for r, e in enumerate(kane.generalized_inertia_forces(), 1)
        ]
    elif method == "lagrange":
        from rrt_pin.dynamics.symbolic import lagrange

        out += [
            Step(
                f"LHS{r}",
                "d/dt(∂T/∂q̇r) − ∂T/∂qr",
                _tidy(e),
                rf"\frac{{d}}{{dt}}\frac{{\partial T}}{{\partial \dot q_{r}}}"
                rf" - \frac{{\partial T}}{{\partial q_{r}}}",
            )
            for r, e in enumerate(lagrange.lagrange_lhs(), 1)
        ]
    else:
        raise ParameterError("method", method, "must be one of kane, lagrange")
    return tuple(out)
