"""Straight-line source of Pinocchio's RNEA for one fixed-base model (numba-free).

:func:`rnea_source` reads a ``pin.Model`` (parents, joint placements, joint types
and axes, inertias, gravity, ``idx_q``/``idx_v``) and runs a plain spatial-algebra
recursive Newton–Euler algorithm on a tiny expression tracer: every scalar is a
Python float (a constant of the model) or the name of a temporary, products by 0
and 1 and sums with 0 are folded away, constants are folded, and each distinct
operation is emitted once. The result is the straight-line Python of one sample,
``τ = M(q)·q̈ + C(q, q̇)·q̇ + G(q)``, in Pinocchio's conventions (local frames,
motion = (linear, angular), the root accelerated by −gravity):

* forward pass, joint i of parent λ(i), ``ⁱXλ = (placementᵢ · Mⱼ(qᵢ))⁻¹``:
  ``vᵢ = ⁱXλ vλ + Sᵢ q̇ᵢ``, ``aᵢ = ⁱXλ aλ + Sᵢ q̈ᵢ + vᵢ × Sᵢ q̇ᵢ``,
  ``fᵢ = Iᵢ aᵢ + vᵢ ×* Iᵢ vᵢ``;
* backward pass: ``τᵢ = Sᵢᵀ fᵢ``, ``fλ += λXᵢ* fᵢ``.

The joints' armature (``model.armature``, rotor inertia) adds ``armature · q̈`` to each
effort, as in Pinocchio's ``rnea``. Joints handled (anything else makes the model
unsupported, :class:`UnsupportedJoint`):
revolute about x, y, z or any axis (``JointModelRX/RY/RZ``, ``RevoluteUnaligned``),
prismatic along x, y, z or any axis (``PX/PY/PZ``, ``PrismaticUnaligned``) and
continuous (``RUBX/RUBY/RUBZ``, ``RevoluteUnboundedUnaligned``: two configuration
entries (cos θ, sin θ), used as given, as Pinocchio does). Fixed joints are
already merged into the placements by Pinocchio; trees (``model.parents``) work.

Units: q in rad or m (continuous joints: cos θ, sin θ), q̇ in rad/s or m/s, q̈ in
rad/s² or m/s²; τ in N·m (revolute) or N (prismatic).
"""

from __future__ import annotations

import ast
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from rrt_pin.core.errors import InputError

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "MAX_JOINTS",
    "GeneratedRnea",
    "UnsupportedJoint",
    "check_supported",
    "count_flops",
    "rnea_source",
    "unsupported_joint",
]

#: Joint model types, by ``shortname()``: revolute (R), prismatic (P), continuous (C).
_KINDS = {
    "JointModelRX": "R",
    "JointModelRY": "R",
    "JointModelRZ": "R",
    "JointModelRevoluteUnaligned": "R",
    "JointModelPX": "P",
    "JointModelPY": "P",
    "JointModelPZ": "P",
    "JointModelPrismaticUnaligned": "P",
    "JointModelRUBX": "C",
    "JointModelRUBY": "C",
    "JointModelRUBZ": "C",
    "JointModelRevoluteUnboundedUnaligned": "C",
}

Scalar = float | str  # a constant, or the name of a temporary
#: Most joints a generated RNEA is made for: its source grows with the joints (about
#: 170 operations each) and numba's compile time faster than that.
MAX_JOINTS = 64


class UnsupportedJoint(InputError):
    """A joint of the model is of a type the generated RNEA does not handle."""


@dataclass(frozen=True)
class GeneratedRnea:
    """The straight-line RNEA of one model, for one sample.

    Attributes:
        nq: configuration size (continuous joints take two entries).
        nv: velocity size (efforts computed).
        lines: the statements, reading ``q[k]``, ``v[k]``, ``a[k]`` (k < nq, nv, nv)
            and assigning temporaries; ``tau`` holds what each effort is.
        tau: per coordinate, the temporary (or the constant) that is its effort.
        flops: floating-point operations a sample (+, −, ·, unary −; sin, cos apart).
        transcendentals: sine and cosine evaluations a sample.
    """

    nq: int
    nv: int
    lines: tuple[str, ...]
    tau: tuple[str, ...]
    flops: int
    transcendentals: int

    def function(self, name: str = "rnea") -> str:
        """A plain Python function ``name(q, v, a, tau)`` that writes τ of one sample into ``tau``."""
        body = [f"    {line}" for line in self.lines]
        body += [f"    tau[{k}] = {t}" for k, t in enumerate(self.tau)]
        return "\n".join([f"def {name}(q, v, a, tau):", *body, "    return tau", ""])


class _Tracer:
    """Scalar operations with constant folding, each distinct one emitted once."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self._seen: dict[tuple, str] = {}

    def _emit(self, key: tuple, text: str) -> str:
        name = self._seen.get(key)
        if name is None:
            name = f"t{len(self.lines)}"
            self.lines.append(f"{name} = {text}")
            self._seen[key] = name
        return name

    @staticmethod
    def _c(x: Scalar) -> str:
        return repr(float(x)) if isinstance(x, float) else x

    def input(self, array: str, k: int) -> str:
        return self._emit(("in", array, k), f"{array}[{k}]")

    def add(self, a: Scalar, b: Scalar) -> Scalar:
        if isinstance(a, float) and isinstance(b, float):
            return a + b
        if a == 0.0:
            return b
        if b == 0.0:
            return a
        x, y = sorted((a, b), key=str)
        return self._emit(("+", x, y), f"{self._c(x)} + {self._c(y)}")

    def neg(self, a: Scalar) -> Scalar:
        if isinstance(a, float):
            return -a
        return self._emit(("neg", a), f"-{a}")

    def sub(self, a: Scalar, b: Scalar) -> Scalar:
        if isinstance(a, float) and isinstance(b, float):
            return a - b
        if b == 0.0:
            return a
        if a == 0.0:
            return self.neg(b)
        return self._emit(("-", a, b), f"{self._c(a)} - {self._c(b)}")

    def mul(self, a: Scalar, b: Scalar) -> Scalar:
        if isinstance(a, float) and isinstance(b, float):
            return a * b
        if a == 0.0 or b == 0.0:
            return 0.0
        if a == 1.0:
            return b
        if b == 1.0:
            return a
        if a == -1.0:
            return self.neg(b)
        if b == -1.0:
            return self.neg(a)
        x, y = sorted((a, b), key=str)
        return self._emit(("*", x, y), f"{self._c(x)} * {self._c(y)}")

    def call(self, fn: str, a: Scalar) -> str:
        return self._emit((fn, a), f"{fn}({a})")

    def dot(self, xs: list[Scalar], ys: list[Scalar]) -> Scalar:
        out: Scalar = 0.0
        for x, y in zip(xs, ys, strict=True):
            out = self.add(out, self.mul(x, y))
        return out


Vec = list  # three Scalars
Mat = list  # three rows of three Scalars


class _Spatial:
    """The spatial algebra of RNEA on a tracer (Pinocchio's conventions)."""

    def __init__(self, t: _Tracer) -> None:
        self.t = t

    def vadd(self, a: Vec, b: Vec) -> Vec:
        return [self.t.add(x, y) for x, y in zip(a, b, strict=True)]

    def vsub(self, a: Vec, b: Vec) -> Vec:
        return [self.t.sub(x, y) for x, y in zip(a, b, strict=True)]

    def scale(self, s: Scalar, a: Vec) -> Vec:
        return [self.t.mul(s, x) for x in a]

    def cross(self, a: Vec, b: Vec) -> Vec:
        t = self.t
        return [
            t.sub(t.mul(a[1], b[2]), t.mul(a[2], b[1])),
            t.sub(t.mul(a[2], b[0]), t.mul(a[0], b[2])),
            t.sub(t.mul(a[0], b[1]), t.mul(a[1], b[0])),
        ]

    def matvec(self, m: Mat, x: Vec) -> Vec:
        return [self.t.dot(row, x) for row in m]

    def mattvec(self, m: Mat, x: Vec) -> Vec:
        return [self.t.dot([m[0][i], m[1][i], m[2][i]], x) for i in range(3)]

    # Motions and forces are (linear, angular) pairs of 3-vectors; an SE3 is (R, p).
    def act_inv_motion(self, rp: tuple[Mat, Vec], m: tuple[Vec, Vec]) -> tuple[Vec, Vec]:
        """M⁻¹·m: w' = Rᵀ w, v' = Rᵀ (v − p × w)."""
        r, p = rp
        v, w = m
        return self.mattvec(r, self.vsub(v, self.cross(p, w))), self.mattvec(r, w)

    def act_force(self, rp: tuple[Mat, Vec], f: tuple[Vec, Vec]) -> tuple[Vec, Vec]:
        """M·f: f' = R f, n' = R n + p × R f."""
        r, p = rp
        lin = self.matvec(r, f[0])
        return lin, self.vadd(self.matvec(r, f[1]), self.cross(p, lin))

    def motion_cross(self, a: tuple[Vec, Vec], b: tuple[Vec, Vec]) -> tuple[Vec, Vec]:
        """The motion cross product a × b = (w × v₂ + v × w₂, w × w₂)."""
        v, w = a
        v2, w2 = b
        return self.vadd(self.cross(w, v2), self.cross(v, w2)), self.cross(w, w2)

    def force_cross(self, a: tuple[Vec, Vec], f: tuple[Vec, Vec]) -> tuple[Vec, Vec]:
        """The force cross product a ×* f = (w × f, w × n + v × f)."""
        v, w = a
        return self.cross(w, f[0]), self.vadd(self.cross(w, f[1]), self.cross(v, f[0]))

    def inertia_times(self, inertia: tuple[float, Vec, Mat], m: tuple[Vec, Vec]) -> tuple[Vec, Vec]:
        """I·m: f = mass (v − c × w), n = I_c w + c × f (I_c about the centre of mass)."""
        mass, c, ic = inertia
        v, w = m
        lin = self.scale(mass, self.vsub(v, self.cross(c, w)))
        return lin, self.vadd(self.matvec(ic, w), self.cross(c, lin))


def _floats(x: Any) -> list[float]:
    return [float(v) for v in x]


def unsupported_joint(model: pin.Model) -> str | None:
    """Why the generated RNEA cannot compute ``model`` (its first unsupported joint), or None.

    Cheap: reads the joint types only.
    """
    if model.njoints - 1 > MAX_JOINTS:
        return (
            f"the model has {model.njoints - 1} joints; the generated RNEA is made for "
            f"at most {MAX_JOINTS}"
        )
    for i in range(1, model.njoints):
        name = model.joints[i].shortname()
        if name not in _KINDS:
            return (
                f"joint {str(model.names[i])!r} is a {name.removeprefix('JointModel')} joint "
                f"({name}): the generated RNEA handles revolute, prismatic and continuous "
                "joints only"
            )
    return None


def check_supported(model: pin.Model) -> None:
    """Refuse a model the generated RNEA cannot compute.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous (the
            message names the joint and its type), or there are more than
            :data:`MAX_JOINTS` joints.
    """
    why = unsupported_joint(model)
    if why is not None:
        raise UnsupportedJoint(f"{why}; use backend='pinocchio'")


def _joint(model: pin.Model, i: int) -> tuple[str, Vec, Vec]:
    """Kind (R, P, C), linear and angular parts of the joint's constant motion subspace S."""
    import numpy as np

    jm = model.joints[i]
    kind = _KINDS[jm.shortname()]
    data = jm.createData()
    q = np.zeros(jm.nq)
    if kind == "C":
        q[0] = 1.0
    jm.calc(data, q)
    s = np.asarray(data.S, dtype=float).reshape(6)
    return kind, _floats(s[:3]), _floats(s[3:])


def rnea_source(model: pin.Model) -> GeneratedRnea:
    """The straight-line RNEA of ``model`` (its gravity included) for one sample.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    check_supported(model)
    joints = [_joint(model, i) for i in range(1, model.njoints)]
    t = _Tracer()
    sp = _Spatial(t)
    zero = [0.0, 0.0, 0.0]
    g = model.gravity
    n = model.njoints
    vel: list[Any] = [(zero, zero)] + [None] * (n - 1)
    acc: list[Any] = [([-x for x in _floats(g.linear)], [-x for x in _floats(g.angular)])]
    acc += [None] * (n - 1)
    force: list[Any] = [None] * n
    transforms: list[Any] = [None] * n
    subspace: list[Any] = [None] * n
    qdds: list[Scalar] = [0.0] * model.nv
    for i in range(1, n):
        kind, s_lin, s_ang = joints[i - 1]
        jm = model.joints[i]
        parent = int(model.parents[i])
        placement = model.jointPlacements[i]
        fixed = ([_floats(r) for r in placement.rotation], _floats(placement.translation))
        qd, qdd = t.input("v", jm.idx_v), t.input("a", jm.idx_v)
        qdds[jm.idx_v] = qdd
        if kind == "P":
            x = t.input("q", jm.idx_q)
            joint = ([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], sp.scale(x, s_lin))
        else:
            if kind == "C":
                c, s = t.input("q", jm.idx_q), t.input("q", jm.idx_q + 1)
            else:
                x = t.input("q", jm.idx_q)
                c, s = t.call("cos", x), t.call("sin", x)
            joint = (_rotation(t, s_ang, c, s), zero)
        transforms[i] = (fixed, joint)
        subspace[i] = (s_lin, s_ang)
        sq = (sp.scale(qd, s_lin), sp.scale(qd, s_ang))
        v = sp.act_inv_motion(joint, sp.act_inv_motion(fixed, vel[parent]))
        v = (sp.vadd(v[0], sq[0]), sp.vadd(v[1], sq[1]))
        a = sp.act_inv_motion(joint, sp.act_inv_motion(fixed, acc[parent]))
        a = (sp.vadd(a[0], sp.scale(qdd, s_lin)), sp.vadd(a[1], sp.scale(qdd, s_ang)))
        vx = sp.motion_cross(v, sq)
        a = (sp.vadd(a[0], vx[0]), sp.vadd(a[1], vx[1]))
        vel[i], acc[i] = v, a
        inertia = model.inertias[i]
        inert = (float(inertia.mass), _floats(inertia.lever), [_floats(r) for r in inertia.inertia])
        ia = sp.inertia_times(inert, a)
        cor = sp.force_cross(v, sp.inertia_times(inert, v))
        force[i] = (sp.vadd(ia[0], cor[0]), sp.vadd(ia[1], cor[1]))
    tau: list[Scalar] = [0.0] * model.nv
    armature = _floats(model.armature)
    for i in range(n - 1, 0, -1):
        s_lin, s_ang = subspace[i]
        f = force[i]
        k = model.joints[i].idx_v
        # τ = Sᵀ f, then + armature · q̈ (rotor inertia), as Pinocchio's rnea adds it last
        tau[k] = t.add(t.add(t.dot(s_lin, f[0]), t.dot(s_ang, f[1])), t.mul(armature[k], qdds[k]))
        parent = int(model.parents[i])
        if parent > 0:
            fixed, joint = transforms[i]
            fp = sp.act_force(fixed, sp.act_force(joint, f))
            force[parent] = (sp.vadd(force[parent][0], fp[0]), sp.vadd(force[parent][1], fp[1]))
    outputs = tuple(t._c(x) for x in tau)
    lines = _live(t.lines, outputs)
    return GeneratedRnea(
        nq=model.nq,
        nv=model.nv,
        lines=lines,
        tau=outputs,
        flops=count_flops(lines),
        transcendentals=sum(line.split(" = ", 1)[1].startswith(("sin(", "cos(")) for line in lines),
    )


def _live(lines: list[str], outputs: tuple[str, ...]) -> tuple[str, ...]:
    """The statements the outputs depend on, in order (the others are dropped)."""
    import re

    needed = {o for o in outputs if not o[:1].isdigit() and not o.startswith("-")}
    kept = []
    for line in reversed(lines):
        name, expr = line.split(" = ", 1)
        if name in needed:
            kept.append(line)
            needed.update(re.findall(r"\bt\d+\b", expr))
    return tuple(reversed(kept))


def _rotation(t: _Tracer, axis: Vec, c: Scalar, s: Scalar) -> Mat:
    """Rotation by the angle of cosine ``c`` and sine ``s`` about the unit ``axis`` (Rodrigues).

    R = c·I + s·[u]ₓ + (1 − c)·u uᵀ; about a coordinate axis the entries fold to
    cos, ±sin, 0 and 1.
    """
    ux, uy, uz = axis
    one_c = t.sub(1.0, c)
    cross = [[0.0, -uz, uy], [uz, 0.0, -ux], [-uy, ux, 0.0]]
    out = []
    for r in range(3):
        row = []
        for k in range(3):
            outer = axis[r] * axis[k]
            if outer == 1.0:  # the axis' own direction: unchanged (c + (1 − c) = 1)
                row.append(1.0)
                continue
            diag = c if r == k else 0.0
            row.append(t.add(t.add(diag, t.mul(s, cross[r][k])), t.mul(one_c, outer)))
        out.append(row)
    return out


def count_flops(lines: tuple[str, ...] | list[str]) -> int:
    """Arithmetic operations (+, −, ·, /, unary −) in statements ``name = expression``."""
    count = 0
    for line in lines:
        expr = line.split("=", 1)[1]
        for node in ast.walk(ast.parse(expr.strip(), mode="eval")):
            if isinstance(node, ast.BinOp) or (
                isinstance(node, ast.UnaryOp)
                and isinstance(node.op, ast.USub)
                and not isinstance(node.operand, ast.Constant)  # a negative constant
            ):
                count += 1
    return count
