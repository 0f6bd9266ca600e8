"""The seed's numbers: the RRT arm's geometry, masses, inertias, task and gains.

Every field keeps the seed's symbol. Units are SI throughout: lengths [m],
masses [kg], moments of inertia [kg·m²], angles [rad], the slider's q3 [m],
times [s], gains in N·m·s/rad and N·m/rad (joints 1, 2) or N·s/m and N/m
(joint 3).
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from typing import Any

from rrt_pin.core.errors import ArgumentTypeError, OverrideError, ParameterError
from rrt_pin.core.expr import MAX_LENGTH, ExpressionError, evaluate

__all__ = [
    "PARAM_DOCS",
    "PLANT_FIELDS",
    "Params",
    "check_columns",
    "check_params",
    "checked",
    "param_names",
    "parse_number",
    "parse_overrides",
    "plant_difference",
]

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

#: The fields the arm's model depends on (not its initial state, target, gains or Tp).
PLANT_FIELDS = (
    "L1", "L2", "m1", "m2", "m3", "I1x", "I1y", "I1z", "I2x", "I2y", "I2z", "I3x", "I3y", "I3z", "g",
)  # fmt: skip

_POSITIVE = ("L1", "L2", "m1", "m2", "m3", "Tp")
_NONNEGATIVE = ("beta01", "gamma01", "beta12", "gamma12", "beta23", "gamma23")
_ROD_DEFAULTS = {"I1x": ("m1", "L1"), "I1y": ("m1", "L1"), "I2x": ("m2", "L2"), "I2y": ("m2", "L2")}
_BODIES = {"1": ("I1x", "I1y", "I1z"), "2": ("I2x", "I2y", "I2z"), "3": ("I3x", "I3y", "I3z")}


@dataclass(frozen=True)
class Params:
    """The RRT arm and its tasks, with the seed's values as defaults (SI units).

    The rods' central moments default to the seed's uniform-rod values
    (I1x = I1y = m1·L1²/3, I1z = 0; I2x = I2y = m2·L2²/3, I2z = 0) computed
    from the masses and lengths actually given, unless set explicitly.

    Every value must be a real number: Python ints and floats, NumPy scalars
    (``np.float32``...) and 0-d arrays are accepted and stored as Python floats;
    booleans, strings and complex numbers are refused. Derived values (the rod
    inertias m·L²/3, LB = 2·L1, a body's sum of moments) must be finite too.

    Raises:
        ParameterError: a value is not a real number, is too large for a float or
            not finite, a mass, length or Tp is not positive, a gain is negative,
            a derived value overflows, or a body's principal moments are
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
        for name in _names():
            value = getattr(self, name)
            if type(value) is float and value - value == 0.0:  # finite: the common case
                continue
            if value is None and name in _ROD_DEFAULTS:
                continue
            object.__setattr__(self, name, _real(name, value))
        for name in _POSITIVE:
            if getattr(self, name) <= 0.0:
                raise ParameterError(name, getattr(self, name), "must be > 0")
        if not math.isfinite(self.LB):
            raise ParameterError("L1", self.L1, "too large: LB = 2·L1 overflows")
        for name, (mass, length) in _ROD_DEFAULTS.items():
            if getattr(self, name) is None:
                object.__setattr__(self, name, _rod_moment(self, mass, length, name))
        for name in _NONNEGATIVE:
            if getattr(self, name) < 0.0:
                raise ParameterError(name, getattr(self, name), "gain must be >= 0")
        for names in _BODIES.values():
            moments = [getattr(self, n) for n in names]
            for n, v in zip(names, moments, strict=True):
                if v < 0.0:
                    raise ParameterError(n, v, "principal moment of inertia must be >= 0")
            total = sum(moments)
            if not math.isfinite(total):
                big = max(names, key=lambda n: getattr(self, n))
                raise ParameterError(
                    big, getattr(self, big), f"too large: {' + '.join(names)} overflows"
                )
            slack = 1e-12 * total
            for i, n in enumerate(names):
                others = total - moments[i]
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
            raise OverrideError(
                f"unknown parameter {unknown[0]!r}; valid names: {', '.join(param_names())}"
            )
        values = dict(overrides)
        for name in ("I1x", "I1y", "I2x", "I2y"):
            if name not in values and getattr(self, name) == _rod_default(self, name):
                values[name] = None
        return replace(self, **values)


def _rod_default(p: Params, name: str) -> float:
    mass, length = _ROD_DEFAULTS[name]
    try:
        return getattr(p, mass) * getattr(p, length) ** 2 / 3.0
    except OverflowError:
        return math.inf


def _rod_moment(p: Params, mass: str, length: str, name: str) -> float:
    """The uniform rod's default moment m·L²/3, refused (naming the culprit) when it overflows."""
    m, L = getattr(p, mass), getattr(p, length)
    try:
        square = L**2
    except OverflowError:
        square = math.inf
    if not math.isfinite(square):
        raise ParameterError(
            length, L, f"too large: the rod inertia {name} = {mass}·{length}²/3 overflows"
        )
    value = m * square / 3.0
    if not math.isfinite(value):
        raise ParameterError(
            mass,
            m,
            f"too large: the rod inertia {name} = {mass}·{length}²/3 overflows ({length}={L!r})",
        )
    return value


def check_columns(table: Mapping[str, Any]) -> tuple[Any, list[str | None]]:
    """:class:`Params`' checks on columns of values, one row a parameter set (a sweep's).

    ``table`` maps every field to a 1-D array (the rod moments filled in, as
    ``m·L²/3`` where defaulted). Returns which rows break a rule, and the first rule
    each breaks (None where none): not finite, not > 0, a negative gain or moment, a
    moment above the sum of the other two, ``LB = 2·L1`` overflowing.
    """
    import numpy as np

    count = len(next(iter(table.values())))
    bad = np.zeros(count, dtype=bool)
    why: list[str | None] = [None] * count

    def mark(mask: Any, reason: str) -> None:
        for i in np.flatnonzero(mask & ~bad):
            why[i] = reason
        bad[:] |= mask

    with np.errstate(over="ignore", invalid="ignore"):
        for name, col in table.items():
            mark(~np.isfinite(col), f"{name} is not finite")
        for name in _POSITIVE:
            mark(table[name] <= 0, f"{name} must be > 0")
        mark(~np.isfinite(2.0 * table["L1"]), "L1 is too large: LB = 2·L1 overflows")
        for name in _NONNEGATIVE:
            mark(table[name] < 0, f"{name} must be >= 0")
        for names in _BODIES.values():
            moments = [table[n] for n in names]
            total = moments[0] + moments[1] + moments[2]
            for i, n in enumerate(names):
                mark(moments[i] < 0, f"{n} must be >= 0")
                mark(
                    moments[i] > total - moments[i] + 1e-12 * total,
                    f"{n} breaks the triangle inequality",
                )
    return bad, why


def checked(values: Mapping[str, float]) -> Params:
    """A :class:`Params` of every field's value, a row that passed :func:`check_columns`.

    No check is repeated (a sweep makes thousands a second); anything else builds
    ``Params(**values)``, which checks.
    """
    made = object.__new__(Params)
    made.__dict__.update(values)
    return made


@functools.cache
def _names() -> tuple[str, ...]:
    """The fields' names, in order (``dataclasses.fields`` builds them at every call)."""
    return tuple(f.name for f in fields(Params))


def _real(name: str, value: object) -> float:
    """``value`` as a finite Python float, or a ParameterError naming ``name``.

    Accepts Python ints and floats, ``numbers.Real`` (e.g. ``Fraction``), NumPy
    scalars and 0-d arrays of integer or float dtype (without importing NumPy);
    refuses booleans, complex numbers, strings, and integers too large for a float.
    """
    if isinstance(value, bool) or type(value).__name__ in ("bool_", "bool"):
        raise ParameterError(name, value, "must be a real number, not a boolean")
    dtype = getattr(value, "dtype", None)
    if dtype is not None and hasattr(value, "ndim") and hasattr(value, "item"):
        kind = getattr(dtype, "kind", "")
        if value.ndim != 0 or kind not in ("i", "u", "f"):  # type: ignore[attr-defined]
            raise ParameterError(name, _shown(value), "must be a real number (a scalar)")
        value = value.item()  # type: ignore[attr-defined]
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ParameterError(name, _shown(value), "must be a real number")
    try:
        out = float(value)
    except OverflowError:
        raise ParameterError(
            name, _shorten(value), "too large for a float (beyond ±1.8e308)"
        ) from None
    if not math.isfinite(out):
        raise ParameterError(name, out, "must be finite")
    return out


def check_params(value: object, name: str = "params") -> Params:
    """``value`` if it is a :class:`Params`.

    A dict of overrides is not applied silently over some default: it is refused,
    with the call that builds one.

    Raises:
        ArgumentTypeError: ``value`` is not a Params.
    """
    if isinstance(value, Params):
        return value

    hint = " (e.g. Params(**overrides))" if isinstance(value, dict) else ""
    raise ArgumentTypeError(
        name,
        f"{name} must be a rrt_pin.Params{hint}, not {type(value).__name__}: {_shorten(value)}",
    )


def plant_difference(a: Params, b: Params) -> str | None:
    """The first of :data:`PLANT_FIELDS` in which two arms differ, e.g. ``"L1 = 1 vs 0.5"``."""
    for field_name in PLANT_FIELDS:
        x, y = getattr(a, field_name), getattr(b, field_name)
        if x != y:
            return f"{field_name} = {x:.6g} vs {y:.6g}"
    return None


def param_names() -> list[str]:
    """The parameter names, in the seed's order."""
    return [f.name for f in fields(Params)]


def parse_number(text: str, name: str = "value") -> float:
    """Parse a number or a small arithmetic expression such as ``pi/3``.

    Accepts floats (``nan`` and ``inf`` parse, to be refused by validation),
    ``pi``, ``tau``, ``e``, ``+ - * / **`` and parentheses, evaluated in floats
    by :func:`rrt_pin.core.expr.evaluate`: bounded in length (200 characters) and
    nesting, so ``9**9**9`` is refused at once instead of computed for ever.

    Raises:
        OverrideError: the text is not such an expression, or it overflows, is
            complex, or is too long or too deeply nested; the message names
            ``name`` and the text.
    """
    if isinstance(text, str) and len(text.strip()) > MAX_LENGTH:
        raise OverrideError(
            f"{name}={_shorten(text)} is not a number ({len(text.strip())} characters long; "
            f"at most {MAX_LENGTH} are allowed)"
        )
    try:
        return float(text)
    except OverflowError:
        raise OverrideError(f"{name}={_shorten(text)} is not a number (too large)") from None
    except (TypeError, ValueError):
        pass
    try:
        return evaluate(str(text))
    except ExpressionError as e:
        raise OverrideError(f"{name}={_shorten(text)} is not a number ({e})") from None


def _shorten(value: object, limit: int = 60) -> str:
    """``repr(value)``, cut to about ``limit`` characters (error messages stay one short line)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        digits = int(value.bit_length() * math.log10(2)) + 1
        return f"<{'-' if value < 0 else ''}integer of about {digits} digits>"
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 5] + "…" + text[-4:]


def _shown(value: object, limit: int = 60) -> object:
    """``value`` itself when its repr is short, else a shortened repr (for ParameterError)."""
    if isinstance(value, int) and not isinstance(value, bool) and value.bit_length() > 128:
        return _shorten(value, limit)
    return value if len(repr(value)) <= limit else _shorten(value, limit)


def parse_overrides(items: list[str] | None) -> dict[str, float]:
    """Parse ``NAME=VALUE`` strings (from ``--set``) into a dict.

    Raises:
        OverrideError: an item has no ``=``, names an unknown parameter, or its
            value is not a number.
    """
    out: dict[str, float] = {}
    for item in items or []:
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep:
            raise OverrideError(f"--set {item!r}: expected NAME=VALUE")
        if name not in PARAM_DOCS:
            raise OverrideError(
                f"--set {name}: unknown parameter; valid names: {', '.join(param_names())}"
            )
        out[name] = parse_number(value, name)
    return out
