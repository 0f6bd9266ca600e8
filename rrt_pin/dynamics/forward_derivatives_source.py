"""Straight-line source of the forward dynamics and its Jacobian, by tangent propagation (numba-free).

:func:`forward_derivatives_source` differentiates the straight-line q̈ = M(q)⁻¹(τ − b(q, q̇))
of :func:`rrt_pin.dynamics.forward_source.forward_source` in forward mode: each statement
``t = f(a, b)`` of the generated code is replayed on a fresh constant-folding tracer
together with its tangent along every direction asked (one a joint coordinate, then one a
joint velocity, then, if asked, one an effort), ``ṫ = ∂f/∂a·ȧ + ∂f/∂b·ḃ``. A tangent that
is a structural zero (the statement does not depend on that direction) is not stored, so
that a joint's coordinate reaches only what it moves; constants are folded and each
distinct operation emitted once, as in the code differentiated. The result is one
function writing q̈ and its Jacobian, ``out[:, 0] = q̈``, ``out[:, 1 + j] = ∂q̈/∂xⱼ``.

Joint coordinates are those of :class:`rrt_pin.robot.Robot` (a continuous joint's angle,
not its cosine and sine), so the derivative along a coordinate is the one in the tangent
space that Pinocchio's ``computeABADerivatives`` gives.

:func:`closed_loop_derivatives_source` does the same for the closed loop of PD plus the
model's gravity, τ = G(q) − kd·q̇ − kp·(q − qf): by ABA(q, q̇, τ_PD + G(q)) = ABA₀(q, q̇, τ_PD)
(ABA₀ on the model without gravity, as :mod:`rrt_pin.simulate.closed_loop` folds it) it
differentiates ABA₀ with the efforts bound to the law, ``kp``, ``kd``, ``qf`` read as
inputs of zero tangent: the Jacobian an implicit method asks of the loop, with no ∂G/∂q.

Units: as :mod:`rrt_pin.dynamics.forward_source`; ∂q̈/∂q in 1/s² (revolute pairs),
∂q̈/∂q̇ in 1/s, ∂q̈/∂τ = M⁻¹ in 1/(kg·m²) (revolute pairs).
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING

from rrt_pin.core.errors import InputError
from rrt_pin.dynamics.forward_source import (
    VARIANTS,
    GeneratedFunction,
    _finish,
    _Ops,
    forward_source,
)
from rrt_pin.dynamics.rnea_source import Scalar

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "DIRECTIONS",
    "closed_loop_derivatives_source",
    "forward_derivatives_source",
    "replay",
]

#: The inputs :func:`forward_derivatives_source` may differentiate along, in their order.
DIRECTIONS = ("q", "v", "tau")

Tangent = dict  # direction index -> Scalar; a direction absent is a structural zero
_BINARY = re.compile(r"^(\S+) ([-+*]) (\S+)$")
_INPUT = re.compile(r"^(\w+)\[(\d+)\]$")
_CALL = re.compile(r"^(sin|cos)\((t\d+)\)$")


def _value(x: str, primal: dict[str, Scalar]) -> Scalar:
    return primal[x] if x.startswith("t") else float(x)


def _tangent_of(x: str, tangent: dict[str, Tangent]) -> Tangent:
    return tangent.get(x, {}) if x.startswith("t") else {}


def _combine(t: _Ops, pairs: list[tuple[Scalar, Tangent]]) -> Tangent:
    """Σ factor·tangent over the pairs, direction by direction (zeros dropped)."""
    out: Tangent = {}
    for factor, tan in pairs:
        for d, x in tan.items():
            term = t.mul(factor, x)
            out[d] = t.add(out[d], term) if d in out else term
    return {d: x for d, x in out.items() if x != 0.0}


def replay(
    t: _Ops,
    gen: GeneratedFunction,
    bindings: dict[tuple[str, int], tuple[Scalar, Tangent]],
) -> tuple[list[Scalar], list[Tangent]]:
    """Trace ``gen``'s statements on ``t`` with their tangents; its outputs' values and tangents.

    Args:
        t: the tracer to emit on.
        gen: straight-line code (statements ``tN = a op b``, ``-a``, ``1.0 / a``,
            ``sin(a)``, ``cos(a)`` or an input ``x[k]``).
        bindings: each input ``(array, k)`` the code reads: its value on ``t`` and its
            tangent (an input not bound reads ``array[k]`` of ``t``, of zero tangent).
    """
    primal: dict[str, Scalar] = {}
    tangent: dict[str, Tangent] = {}
    for line in gen.lines:
        name, expr = line.split(" = ", 1)
        if m := _INPUT.match(expr):
            key = (m[1], int(m[2]))
            value, tan = bindings.get(key) or (t.input(*key), {})
        elif m := _BINARY.match(expr):
            a, b = _value(m[1], primal), _value(m[3], primal)
            da, db = _tangent_of(m[1], tangent), _tangent_of(m[3], tangent)
            if m[2] == "+":
                value, tan = t.add(a, b), _combine(t, [(1.0, da), (1.0, db)])
            elif m[2] == "-":
                value, tan = t.sub(a, b), _combine(t, [(1.0, da), (-1.0, db)])
            else:
                value, tan = t.mul(a, b), _combine(t, [(b, da), (a, db)])
        elif expr.startswith("1.0 / "):
            a = primal[expr[6:]]
            value = t.inv(a)
            da = tangent.get(expr[6:], {})
            tan = _combine(t, [(t.neg(t.mul(value, value)), da)]) if da else {}
        elif m := _CALL.match(expr):
            a, da = primal[m[2]], tangent.get(m[2], {})
            value = t.call(m[1], a)
            if da:
                slope = t.call("cos", a) if m[1] == "sin" else t.neg(t.call("sin", a))
                tan = _combine(t, [(slope, da)])
            else:
                tan = {}
        elif expr.startswith("-t"):
            value, tan = t.neg(primal[expr[1:]]), _combine(t, [(-1.0, tangent[expr[1:]])])
        else:  # pragma: no cover - the generators emit nothing else
            raise ValueError(f"cannot differentiate the statement {line!r}")
        primal[name] = value
        if tan:
            tangent[name] = tan
    values = [_value(x, primal) for x in gen.outputs]
    return values, [_tangent_of(x, tangent) for x in gen.outputs]


def _directions(nv: int, wrt: tuple[str, ...]) -> dict[tuple[str, int], int]:
    """Each input differentiated along: its direction's index."""
    return {(x, k): i * nv + k for i, x in enumerate(wrt) for k in range(nv)}


def _jacobian_function(
    name: str,
    model: pin.Model,
    t: _Ops,
    inputs: tuple[str, ...],
    values: list[Scalar],
    tangents: list[Tangent],
    columns: int,
) -> GeneratedFunction:
    """q̈ and its Jacobian as one (nv, 1 + columns) result: column 0 q̈, then ∂q̈/∂xⱼ."""
    flat: list[Scalar] = []
    for value, tan in zip(values, tangents, strict=True):
        flat.append(value)
        flat.extend(tan.get(j, 0.0) for j in range(columns))
    gen = _finish(name, model, t, inputs, flat, matrix=False)
    return GeneratedFunction(
        name=gen.name,
        nv=gen.nv,
        inputs=gen.inputs,
        shape=(model.nv, 1 + columns),
        lines=gen.lines,
        outputs=gen.outputs,
        flops=gen.flops,
        transcendentals=gen.transcendentals,
    )


def forward_derivatives_source(
    model: pin.Model, variant: str = "aba", wrt: tuple[str, ...] = ("q", "v")
) -> GeneratedFunction:
    """q̈ and its Jacobian along ``wrt``: ``forward_derivatives(q, v, tau, out)``.

    ``out`` is (nv, 1 + len(wrt)·nv): ``out[:, 0]`` q̈, then ∂q̈/∂q (``"q"``), ∂q̈/∂q̇
    (``"v"``) and ∂q̈/∂τ = M(q)⁻¹ (``"tau"``), nv columns each, in the order of ``wrt``.

    Args:
        model: a fixed-base Pinocchio model with supported joints.
        variant: the forward dynamics differentiated, ``"aba"`` or ``"crba"``.
        wrt: the inputs to differentiate along, a subsequence of :data:`DIRECTIONS`.

    Raises:
        InputError: an unknown ``variant`` or ``wrt``.
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    if not wrt or any(x not in DIRECTIONS for x in wrt) or len(set(wrt)) != len(wrt):
        raise InputError(f"wrt={wrt!r} must be distinct entries of {', '.join(DIRECTIONS)}")
    if variant not in VARIANTS:
        raise InputError(f"variant={variant!r} is unknown; known: {', '.join(VARIANTS)}")
    nv = model.nv
    t = _Ops()
    seeds = {key: (t.input(*key), {d: 1.0}) for key, d in _directions(nv, wrt).items()}
    values, tangents = replay(t, forward_source(model, variant), seeds)
    name = "forward_derivatives" if variant == "aba" else f"forward_derivatives_{variant}"
    return _jacobian_function(
        name, model, t, ("q", "v", "tau"), values, tangents, columns=len(wrt) * nv
    )


def closed_loop_derivatives_source(model: pin.Model) -> GeneratedFunction:
    """q̈ of PD plus gravity and its Jacobian: ``closed_loop_derivatives(q, v, kp, kd, qf, out)``.

    τ = G(q) − kd·q̇ − kp·(q − qf), each gain and target per joint [N·m/rad, N·m·s/rad,
    rad] (N/m, N·s/m, m for prismatic joints). ``out`` is (nv, 1 + 2nv): ``out[:, 0]``
    q̈, then ∂q̈/∂q and ∂q̈/∂q̇ of the loop (the law's derivatives included).

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    import pinocchio as pin

    free = pin.Model(model)
    free.gravity = pin.Motion.Zero()
    nv = model.nv
    t = _Ops()
    directions = _directions(nv, ("q", "v"))
    bindings: dict[tuple[str, int], tuple[Scalar, Tangent]] = {}
    for k in range(nv):
        q, v = t.input("q", k), t.input("v", k)
        kp, kd = t.input("kp", k), t.input("kd", k)
        pd = t.neg(t.add(t.mul(kd, v), t.mul(kp, t.sub(q, t.input("qf", k)))))
        bindings[("q", k)] = (q, {directions[("q", k)]: 1.0})
        bindings[("v", k)] = (v, {directions[("v", k)]: 1.0})
        bindings[("tau", k)] = (
            pd,
            {directions[("q", k)]: t.neg(kp), directions[("v", k)]: t.neg(kd)},
        )
    values, tangents = replay(t, forward_source(free, "aba"), bindings)
    inputs = ("q", "v", "kp", "kd", "qf")
    return _jacobian_function(
        "closed_loop_derivatives", model, t, inputs, values, tangents, columns=2 * nv
    )
