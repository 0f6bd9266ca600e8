"""The seed's numbers: the RRT arm's geometry, masses, inertias, task and gains.

Every field keeps the seed's symbol. Units are SI throughout: lengths [m],
masses [kg], moments of inertia [kg·m²], angles [rad], the slider's q3 [m],
times [s], gains in N·m·s/rad and N·m/rad (joints 1, 2) or N·s/m and N/m
(joint 3).
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

from rrt_pin.errors import ParameterError, SceneError

__all__ = ["PARAM_DOCS", "Params", "param_names", "parse_number", "parse_overrides"]

#: One line of documentation per parameter: meaning and unit.
PARAM_DOCS: dict[str, str] = {
    "L1": "distance A→C1, half the length of link 1 [m]",
    "L2": "distance B→C2, half the length of link 2 [m]",
    "m1": "mass of link 1 [kg]",
    "m2": "mass of link 2 [kg]",
    "m3": "mass of the slider, link 3 [kg]",
    "I1x": "central moment of link 1 about ı1 [kg·m²] (default m1·L1²/3)",
    "I1y": "central moment of link 1 about ȷ1 [kg·m²] (default m1·L1²/3)",
    "I1z": "central moment of link 1 about k1 [kg·m²] (default 0)",
    "I2x": "central moment of link 2 about ı2 [kg·m²] (default m2·L2²/3)",
    "I2y": "central moment of link 2 about ȷ2 [kg·m²] (default m2·L2²/3)",
    "I2z": "central moment of link 2 about k2 [kg·m²] (default 0)",
    "I3x": "central moment of link 3 about ı2 [kg·m²]",
    "I3y": "central moment of link 3 about ȷ2 [kg·m²]",
    "I3z": "central moment of link 3 about k2 [kg·m²]",
    "g": "gravitational acceleration, along −ı0 (down) [m/s²]",
    "q10": "initial q1 [rad]",
    "q20": "initial q2 [rad]",
    "q30": "initial q3 [m]",
    "qd10": "initial q̇1 [rad/s]",
    "qd20": "initial q̇2 [rad/s]",
    "qd30": "initial q̇3 [m/s]",
    "q1f": "final (target) q1 [rad]",
    "q2f": "final (target) q2 [rad]",
    "q3f": "final (target) q3 [m]",
    "Tp": "duration of the prescribed motion of eq. (30) [s]",
    "beta01": "damping gain of joint 1 [N·m·s/rad]",
    "gamma01": "stiffness gain of joint 1 [N·m/rad]",
    "beta12": "damping gain of joint 2 [N·m·s/rad]",
    "gamma12": "stiffness gain of joint 2 [N·m/rad]",
    "beta23": "damping gain of joint 3 [N·s/m]",
    "gamma23": "stiffness gain of joint 3 [N/m]",
}

_POSITIVE = ("L1", "L2", "m1", "m2", "m3", "Tp")
_NONNEGATIVE = ("beta01", "gamma01", "beta12", "gamma12", "beta23", "gamma23")
_BODIES = {"1": ("I1x", "I1y", "I1z"), "2": ("I2x", "I2y", "I2z"), "3": ("I3x", "I3y", "I3z")}


@dataclass(frozen=True)
class Params:
    """The RRT arm and its tasks, with the seed's values as defaults (SI units).

    The rods' central moments default to the seed's uniform-rod values
    (I1x = I1y = m1·L1²/3, I1z = 0; I2x = I2y = m2·L2²/3, I2z = 0) computed
    from the masses and lengths actually given, unless set explicitly.

    Raises:
        ParameterError: a value is not finite, a mass, length or Tp is not
            positive, a gain is negative, or a body's principal moments are
            negative or break the triangle inequality.
    """

    L1: float = 0.4
    L2: float = 0.7
    m1: float = 90.0
    m2: float = 60.0
    m3: float = 40.0
    I1x: float = field(default=None)  # type: ignore[assignment]
    I1y: float = field(default=None)  # type: ignore[assignment]
    I1z: float = 0.0
    I2x: float = field(default=None)  # type: ignore[assignment]
    I2y: float = field(default=None)  # type: ignore[assignment]
    I2z: float = 0.0
    I3x: float = 5.0
    I3y: float = 4.0
    I3z: float = 1.0
    g: float = 9.81
    q10: float = math.pi / 18
    q20: float = math.pi / 6
    q30: float = 0.25
    qd10: float = 0.0
    qd20: float = 0.0
    qd30: float = 0.0
    q1f: float = math.pi / 3
    q2f: float = math.pi / 3
    q3f: float = 0.3
    Tp: float = 15.0
    beta01: float = 450.0
    gamma01: float = 300.0
    beta12: float = 200.0
    gamma12: float = 300.0
    beta23: float = 150.0
    gamma23: float = 50.0

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if value is None:
                continue
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise ParameterError(f.name, value, "must be a real number")
            if not math.isfinite(value):
                raise ParameterError(f.name, value, "must be finite")
            object.__setattr__(self, f.name, float(value))
        for name in _POSITIVE:
            if getattr(self, name) <= 0.0:
                raise ParameterError(name, getattr(self, name), "must be > 0")
        rod1 = self.m1 * self.L1**2 / 3.0
        rod2 = self.m2 * self.L2**2 / 3.0
        for name, default in (("I1x", rod1), ("I1y", rod1), ("I2x", rod2), ("I2y", rod2)):
            if getattr(self, name) is None:
                object.__setattr__(self, name, default)
        for name in _NONNEGATIVE:
            if getattr(self, name) < 0.0:
                raise ParameterError(name, getattr(self, name), "gain must be >= 0")
        for names in _BODIES.values():
            moments = [getattr(self, n) for n in names]
            for n, v in zip(names, moments, strict=True):
                if v < 0.0:
                    raise ParameterError(n, v, "principal moment of inertia must be >= 0")
            slack = 1e-12 * sum(moments)
            for i, n in enumerate(names):
                others = sum(moments) - moments[i]
                if moments[i] > others + slack:
                    a, b = (names[j] for j in range(3) if j != i)
                    raise ParameterError(
                        n,
                        moments[i],
                        f"violates the triangle inequality {n} <= {a} + {b} "
                        f"= {moments[(i + 1) % 3] + moments[(i + 2) % 3]!r}",
                    )

    # Derived quantities -------------------------------------------------
    @property
    def LB(self) -> float:
        """Distance A→B = 2·L1 [m]."""
        return 2.0 * self.L1

    @property
    def q0(self) -> tuple[float, float, float]:
        """Initial configuration (q1 [rad], q2 [rad], q3 [m])."""
        return (self.q10, self.q20, self.q30)

    @property
    def qd0(self) -> tuple[float, float, float]:
        """Initial velocity (q̇1 [rad/s], q̇2 [rad/s], q̇3 [m/s])."""
        return (self.qd10, self.qd20, self.qd30)

    @property
    def qf(self) -> tuple[float, float, float]:
        """Final configuration (q1f [rad], q2f [rad], q3f [m])."""
        return (self.q1f, self.q2f, self.q3f)

    @property
    def kp(self) -> tuple[float, float, float]:
        """Stiffness gains (γ01, γ12, γ23) of eq. (31)."""
        return (self.gamma01, self.gamma12, self.gamma23)

    @property
    def kd(self) -> tuple[float, float, float]:
        """Damping gains (β01, β12, β23) of eq. (31)."""
        return (self.beta01, self.beta12, self.beta23)

    def as_dict(self) -> dict[str, float]:
        """All fields by name (SI units)."""
        return {f.name: getattr(self, f.name) for f in fields(self)}

    def with_overrides(self, overrides: Mapping[str, Any]) -> Params:
        """A copy with some fields replaced; refuses unknown names.

        Rod inertias that were left at their default follow new masses and
        lengths (they are recomputed unless given explicitly).
        """
        unknown = sorted(set(overrides) - set(PARAM_DOCS))
        if unknown:
            raise SceneError(
                f"unknown parameter {unknown[0]!r}; valid names: {', '.join(param_names())}"
            )
        values = dict(overrides)
        for name in ("I1x", "I1y", "I2x", "I2y"):
            if name not in values and getattr(self, name) == _rod_default(self, name):
                values[name] = None
        return replace(self, **values)


def _rod_default(p: Params, name: str) -> float:
    if name.startswith("I1"):
        return p.m1 * p.L1**2 / 3.0
    return p.m2 * p.L2**2 / 3.0


def param_names() -> list[str]:
    """The parameter names, in the seed's order."""
    return [f.name for f in fields(Params)]


_BINOPS = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}
_UNOPS = {ast.USub: operator.neg, ast.UAdd: operator.pos}
_NAMES = {"pi": math.pi, "tau": math.tau, "e": math.e}


def parse_number(text: str, name: str = "value") -> float:
    """Parse a number or a small arithmetic expression such as ``pi/3``.

    Accepts floats (``nan`` and ``inf`` parse, to be refused by validation),
    ``pi``, ``tau``, ``e``, ``+ - * / **`` and parentheses.

    Raises:
        SceneError: the text is not such an expression.
    """
    try:
        return float(text)
    except (TypeError, ValueError):
        pass
    try:
        return float(_eval(ast.parse(str(text).strip(), mode="eval").body))
    except (SyntaxError, ValueError, TypeError, ZeroDivisionError, OverflowError) as e:
        raise SceneError(f"{name}={text!r} is not a number ({e})") from e


def _eval(node: ast.AST) -> float:
    if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
        if isinstance(node.value, bool):
            raise ValueError("booleans are not numbers")
        return node.value
    if isinstance(node, ast.Name) and node.id in _NAMES:
        return _NAMES[node.id]
    if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
        return _BINOPS[type(node.op)](_eval(node.left), _eval(node.right))
    if isinstance(node, ast.UnaryOp) and type(node.op) in _UNOPS:
        return _UNOPS[type(node.op)](_eval(node.operand))
    raise ValueError("only numbers, pi, tau, e and + - * / ** are allowed")


def parse_overrides(items: list[str] | None) -> dict[str, float]:
    """Parse ``NAME=VALUE`` strings (from ``--set``) into a dict.

    Raises:
        SceneError: an item has no ``=``, names an unknown parameter, or its
            value is not a number.
    """
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep:
            raise SceneError(f"--set {item!r}: expected NAME=VALUE")
        if name not in PARAM_DOCS:
            raise SceneError(
                f"--set {name}: unknown parameter; valid names: {', '.join(param_names())}"
            )
        out[name] = parse_number(value, name)
    return out
