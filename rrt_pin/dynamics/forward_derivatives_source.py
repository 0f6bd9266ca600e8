"""Straight-line source of the forward dynamics and its Jacobian, by tangent propagation (numba-free).

:func:`replay` differentiates generated straight-line code in forward mode: each statement
``t = f(a, b)`` of the generated code is replayed on a fresh constant-folding tracer
together with its tangent along every direction asked (one a joint coordinate, then one a
joint velocity, then, if asked, one an effort), ``ṫ = ∂f/∂a·ȧ + ∂f/∂b·ḃ``. A tangent that
is a structural zero (the statement does not depend on that direction) is not stored, so
that a joint's coordinate reaches only what it moves; constants are folded and each
distinct operation emitted once, as in the code differentiated. The result is one
function writing a value and its Jacobian, ``out[:, 0] = y``, ``out[:, 1 + j] = ∂y/∂xⱼ``:

* :func:`forward_derivatives_source`: q̈ = M(q)⁻¹(τ − b(q, q̇)) with ∂q̈/∂q, ∂q̈/∂q̇ (and
  M⁻¹ = ∂q̈/∂τ), by one of :data:`VARIANTS`: the tangents of the generated ABA or
  CRBA + LDLᵀ (:func:`rrt_pin.dynamics.forward_source.forward_source`), or (the default)
  q̈ by ABA and ∂q̈/∂x = −M⁻¹·∂ID/∂x from the tangents of the generated inverse dynamics
  at a = q̈ and one tree-sparse LDLᵀ, the identity Pinocchio's ``computeABADerivatives``
  uses, with fewer operations;
* :func:`inverse_derivatives_source`: τ = ID(q, q̇, q̈) with ∂τ/∂q, ∂τ/∂q̇ (as
  ``computeRNEADerivatives``; a computed-torque law's Jacobian);
* :func:`gravity_derivatives_source`: G(q) with ∂G/∂q.

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
    GeneratedFunction,
    _Algebra,
    _crba,
    _finish,
    _gravity,
    _ldlt_solve,
    _links,
    _Ops,
    _start,
    _velocities,
    forward_source,
    gravity_source,
)
from rrt_pin.dynamics.rnea_source import Scalar

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "DEFAULT_VARIANT",
    "DIRECTIONS",
    "VARIANTS",
    "closed_loop_derivatives_source",
    "forward_derivatives_source",
    "gravity_derivatives_source",
    "inverse_derivatives_source",
    "replay",
]

#: The inputs :func:`forward_derivatives_source` may differentiate along, in their order.
DIRECTIONS = ("q", "v", "tau")
#: How the Jacobian is generated: ``"aba"``, ``"crba"``: the tangents of that generated
#: forward dynamics, statement by statement; ``"rnea"``: q̈ by ABA, then
#: ∂q̈/∂x = M⁻¹(∂τ/∂x − ∂ID/∂x) with the tangents of the generated inverse dynamics at
#: a = q̈ and one sparse LDLᵀ of M (Carpentier and Mansard's identity, as Pinocchio's
#: ``computeABADerivatives``).
VARIANTS = ("aba", "crba", "rnea")
#: The variant of the fewest operations on UR5 and Panda (``scripts/bench/forward_derivatives.py``).
DEFAULT_VARIANT = "rnea"

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
            value, tan = t.neg(primal[expr[1:]]), _combine(t, [(-1.0, tangent.get(expr[1:], {}))])
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


def _check(variant: str, wrt: tuple[str, ...]) -> None:
    if not wrt or any(x not in DIRECTIONS for x in wrt) or len(set(wrt)) != len(wrt):
        raise InputError(f"wrt={wrt!r} must be distinct entries of {', '.join(DIRECTIONS)}")
    if variant not in VARIANTS:
        raise InputError(f"variant={variant!r} is unknown; known: {', '.join(VARIANTS)}")


def forward_derivatives_source(
    model: pin.Model, variant: str = DEFAULT_VARIANT, wrt: tuple[str, ...] = ("q", "v")
) -> GeneratedFunction:
    """q̈ and its Jacobian along ``wrt``: ``forward_derivatives_<variant>(q, v, tau, out)``.

    ``out`` is (nv, 1 + len(wrt)·nv): ``out[:, 0]`` q̈, then ∂q̈/∂q (``"q"``), ∂q̈/∂q̇
    (``"v"``) and ∂q̈/∂τ = M(q)⁻¹ (``"tau"``), nv columns each, in the order of ``wrt``.

    Args:
        model: a fixed-base Pinocchio model with supported joints.
        variant: ``"aba"`` or ``"crba"``: that forward dynamics, differentiated statement
            by statement; ``"rnea"``: q̈ by ABA, then −M⁻¹ times the inverse dynamics'
            tangents at a = q̈ (see :data:`VARIANTS`).
        wrt: the inputs to differentiate along, a subsequence of :data:`DIRECTIONS`.

    Raises:
        InputError: an unknown ``variant`` or ``wrt``.
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    _check(variant, wrt)
    nv = model.nv
    t = _Ops()
    seeds = {key: (t.input(*key), {d: 1.0}) for key, d in _directions(nv, wrt).items()}
    name = f"forward_derivatives_{variant}"
    inputs = ("q", "v", "tau")
    if variant == "rnea":
        efforts = {("tau", k): (t.input("tau", k), {}) for k in range(nv)}
        values, tangents, columns = _by_inverse_dynamics(t, model, wrt, efforts)
        return _jacobian_function(name, model, t, inputs, values, tangents, columns)
    values, tangents = replay(t, forward_source(model, variant), seeds)
    return _jacobian_function(name, model, t, inputs, values, tangents, len(wrt) * nv)


def closed_loop_derivatives_source(
    model: pin.Model, variant: str = DEFAULT_VARIANT
) -> GeneratedFunction:
    """q̈ of PD plus gravity and its Jacobian: ``closed_loop_derivatives(q, v, kp, kd, qf, out)``.

    τ = G(q) − kd·q̇ − kp·(q − qf), each gain and target per joint [N·m/rad, N·m·s/rad,
    rad] (N/m, N·s/m, m for prismatic joints). ``out`` is (nv, 1 + 2nv): ``out[:, 0]``
    q̈, then ∂q̈/∂q and ∂q̈/∂q̇ of the loop (the law's derivatives included).

    Raises:
        InputError: an unknown ``variant``.
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    import pinocchio as pin

    _check(variant, ("q", "v"))
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
    inputs = ("q", "v", "kp", "kd", "qf")
    name = "closed_loop_derivatives"
    if variant == "rnea":
        efforts = {key: bindings[key] for key in bindings if key[0] == "tau"}
        values, tangents, columns = _by_inverse_dynamics(t, free, ("q", "v"), efforts)
        return _jacobian_function(name, model, t, inputs, values, tangents, columns)
    values, tangents = replay(t, forward_source(free, variant), bindings)
    return _jacobian_function(name, model, t, inputs, values, tangents, 2 * nv)


def inverse_derivatives_source(model: pin.Model) -> GeneratedFunction:
    """τ = ID(q, q̇, q̈) and its Jacobian: ``inverse_derivatives(q, v, a, out)``.

    ``out`` is (nv, 1 + 2nv): ``out[:, 0]`` τ, then ∂τ/∂q and ∂τ/∂q̇ (∂τ/∂q̈ is M(q)), as
    Pinocchio's ``computeRNEADerivatives``: what a computed-torque law's Jacobian needs.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    nv = model.nv
    t = _Ops()
    seeds = {key: (t.input(*key), {d: 1.0}) for key, d in _directions(nv, ("q", "v")).items()}
    values, tangents = replay(t, _rnea_with_acceleration(model), seeds)
    inputs = ("q", "v", "a")
    return _jacobian_function("inverse_derivatives", model, t, inputs, values, tangents, 2 * nv)


def gravity_derivatives_source(model: pin.Model) -> GeneratedFunction:
    """G(q) and ∂G/∂q: ``gravity_derivatives(q, out)``, ``out`` (nv, 1 + nv), G in column 0.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    nv = model.nv
    t = _Ops()
    seeds = {key: (t.input(*key), {d: 1.0}) for key, d in _directions(nv, ("q",)).items()}
    values, tangents = replay(t, gravity_source(model), seeds)
    return _jacobian_function("gravity_derivatives", model, t, ("q",), values, tangents, nv)


def _rnea_with_acceleration(model: pin.Model) -> GeneratedFunction:
    """τ = M(q)·a + b(q, q̇) (RNEA, armature included): ``inverse(q, v, a, out)``."""
    t, sp, links = _start(model)
    vel, vj = _velocities(sp, links, with_v=True)
    acc: list = [_gravity(model)]
    force: list = [None]
    for i, link in enumerate(links[1:], start=1):
        a_k = t.input("a", link.k)
        joint = (sp.scale(a_k, link.s[0]), sp.scale(a_k, link.s[1]))
        a = sp.madd(sp.madd(sp.down(link, acc[link.parent]), joint), sp.motion_cross(vel[i], vj[i]))
        acc.append(a)
        inertia_v = sp.body_times(link.inertia, vel[i])
        force.append(sp.madd(sp.body_times(link.inertia, a), sp.force_cross(vel[i], inertia_v)))
    tau: list[Scalar] = [0.0] * model.nv
    for i in range(len(links) - 1, 0, -1):
        link = links[i]
        tau[link.k] = t.add(sp.sdot(link.s, force[i]), t.mul(link.armature, t.input("a", link.k)))
        if link.parent > 0:
            force[link.parent] = sp.madd(force[link.parent], sp.up(link, force[i]))
    return _finish("inverse", model, t, ("q", "v", "a"), tau, matrix=False)


def _by_inverse_dynamics(
    t: _Ops,
    model: pin.Model,
    wrt: tuple[str, ...],
    efforts: dict[tuple[str, int], tuple[Scalar, Tangent]],
) -> tuple[list[Scalar], list[Tangent], int]:
    """q̈ by ABA and ∂q̈/∂x = M⁻¹·(∂τ/∂x − ∂ID(q, q̇, a)/∂x) at a = q̈, as Pinocchio does.

    ``efforts``: τ of each joint, ``("tau", k)``, its value on ``t`` and its tangent along
    the q and q̇ directions (a law's derivatives; empty for efforts given). The inverse
    dynamics are traced along q and q̇ with a held at q̈; M by CRBA and its tree-sparse
    LDLᵀ serve every column (each distinct operation is emitted once); ∂q̈/∂τ (``"tau"`` in
    ``wrt``) is M⁻¹, solved column by column. Returns q̈, the rows' tangents, the columns.
    """
    nv = model.nv
    sp = _Algebra(t)
    links = _links(model, t)
    primal = {("q", k): (t.input("q", k), {}) for k in range(nv)}
    primal.update({("v", k): (t.input("v", k), {}) for k in range(nv)})
    qdd, _ = replay(t, forward_source(model, "aba"), {**primal, **efforts})
    directions = _directions(nv, tuple(x for x in wrt if x != "tau"))
    bindings = {key: (t.input(*key), {d: 1.0}) for key, d in directions.items()}
    bindings.update({("a", k): (qdd[k], {}) for k in range(nv)})
    _, id_tangents = replay(t, _rnea_with_acceleration(model), bindings)
    m = _crba(model, sp, links)
    parent = [-1] * nv
    for link in links[1:]:
        parent[link.k] = links[link.parent].k if link.parent > 0 else -1
    columns: list[list[Scalar]] = []
    for d in range(len(directions)):
        rhs = [
            t.sub(efforts[("tau", k)][1].get(d, 0.0), id_tangents[k].get(d, 0.0)) for k in range(nv)
        ]
        columns.append(_ldlt_solve(t, m, parent, rhs))
    if "tau" in wrt:
        for j in range(nv):
            columns.append(_ldlt_solve(t, m, parent, [float(k == j) for k in range(nv)]))
    rows = [{c: col[r] for c, col in enumerate(columns) if col[r] != 0.0} for r in range(nv)]
    return qdd, rows, len(columns)
