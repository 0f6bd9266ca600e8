"""A bounded evaluator for the small arithmetic expressions users type as numbers.

``pi/3``, ``-2*tau``, ``(1 + 2) ** 0.5``: float literals, the names ``pi``,
``tau`` and ``e``, the operators ``+ - * / **``, unary ``+``/``-`` and
parentheses. Everything is computed in floats (never Python's unbounded
integers), so every expression finishes in microseconds: ``9**9**9`` overflows
at once and is refused rather than computed for ever. The text length and the
nesting depth are capped too, so the parser never recurses deeply.

Only the standard library is imported (``rrt_pin.robot.params`` must stay cheap).
"""

from __future__ import annotations

import ast
import math

__all__ = ["MAX_DEPTH", "MAX_LENGTH", "ExpressionError", "evaluate"]

#: Longest expression accepted, in characters.
MAX_LENGTH = 200
#: Deepest nesting of operators and parentheses accepted.
MAX_DEPTH = 100

_NAMES = {"pi": math.pi, "tau": math.tau, "e": math.e}


class ExpressionError(ValueError):
    """An expression is not allowed or does not evaluate to a finite real number."""


def evaluate(text: str) -> float:
    """Evaluate a small arithmetic expression in floats.

    Args:
        text: e.g. ``"pi/3"`` or ``"2*e**-1"``.

    Returns:
        The value, always a finite float.

    Raises:
        ExpressionError: the text is too long, too deeply nested, not such an
            expression, divides by zero, overflows, or is not real (``1j``,
            ``(-8)**(1/3)``).
    """
    if not isinstance(text, str):
        raise ExpressionError(f"expected text, got {type(text).__name__}")
    text = text.strip()
    if len(text) > MAX_LENGTH:
        raise ExpressionError(f"{len(text)} characters long; at most {MAX_LENGTH} are allowed")
    if not text:
        raise ExpressionError("empty")
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as e:
        raise ExpressionError(f"invalid syntax: {e.msg}") from None
    except (RecursionError, MemoryError):  # pragma: no cover - prevented by MAX_LENGTH
        raise ExpressionError("too deeply nested") from None
    return _eval(tree.body, 0)


def _eval(node: ast.AST, depth: int) -> float:
    if depth > MAX_DEPTH:
        raise ExpressionError(f"nested more than {MAX_DEPTH} levels deep")
    if isinstance(node, ast.Constant):
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float, complex)):
            raise ExpressionError(f"{value!r} is not a number")
        if isinstance(value, complex):
            raise ExpressionError("complex numbers are not allowed")
        return _finite(float(value) if isinstance(value, float) else _int_to_float(value))
    if isinstance(node, ast.Name):
        if node.id in _NAMES:
            return _NAMES[node.id]
        raise ExpressionError(f"unknown name {node.id!r}; only pi, tau and e are allowed")
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        operand = _eval(node.operand, depth + 1)
        return -operand if isinstance(node.op, ast.USub) else operand
    if isinstance(node, ast.BinOp) and isinstance(
        node.op, (ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow)
    ):
        left = _eval(node.left, depth + 1)
        right = _eval(node.right, depth + 1)
        return _finite(_binop(node.op, left, right))
    raise ExpressionError("only numbers, pi, tau, e and + - * / ** are allowed")


def _binop(op: ast.operator, a: float, b: float) -> float:
    if isinstance(op, ast.Add):
        return a + b
    if isinstance(op, ast.Sub):
        return a - b
    if isinstance(op, ast.Mult):
        return a * b
    if isinstance(op, ast.Div):
        if b == 0.0:
            raise ExpressionError("division by zero")
        return a / b
    try:
        return math.pow(a, b)  # floats only: never a complex result, never a big int
    except OverflowError:
        raise ExpressionError("overflows beyond ±1.8e308") from None
    except ValueError:
        if a == 0.0:
            raise ExpressionError("zero raised to a negative power") from None
        raise ExpressionError("a negative number to a fractional power is not real") from None


def _int_to_float(value: int) -> float:
    try:
        return float(value)
    except OverflowError:
        raise ExpressionError("overflows beyond ±1.8e308") from None


def _finite(value: float) -> float:
    if not math.isfinite(value):
        raise ExpressionError("overflows beyond ±1.8e308")
    return value
