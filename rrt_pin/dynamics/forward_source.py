"""Straight-line source of the mass matrix, bias, gravity and forward dynamics of a model (numba-free).

For a fixed-base ``pin.Model`` that :mod:`rrt_pin.dynamics.rnea_source` supports
(revolute, prismatic and continuous joints, trees, armature), the functions here trace
Featherstone's algorithms through that module's constant-folding scalar tracer into the
straight-line Python of one sample, in Pinocchio's conventions (local frames, motion =
(linear, angular), the root accelerated by −gravity):

* :func:`mass_matrix_source`: M(q) by the composite-rigid-body algorithm (CRBA): the
  composite inertias are kept as (mass, first moment, rotational inertia about the
  frame's origin), ten numbers, and only the pairs (i, j) with j an ancestor of i (or
  i itself) are computed; the others are structural zeros. Armature adds to the diagonal.
* :func:`bias_source`: b(q, q̇) = C(q, q̇)·q̇ + G(q), the RNEA with q̈ = 0.
* :func:`gravity_source`: G(q), the RNEA with q̇ = q̈ = 0.
* :func:`forward_source`: q̈ = M⁻¹(τ − b), either by the articulated-body algorithm
  (``"aba"``, articulated inertias as symmetric 6×6 blocks) or by CRBA, the bias and an
  unrolled sparse LDLᵀ (``"crba"``, Featherstone's LTDL factorization H = LᵀDL: the
  sparsity is the parent array of the velocity coordinates, a tree has no fill-in).

All kernels take joint *coordinates*: nv values, the angle of a continuous joint
included (its cosine and sine are computed inside), as :class:`rrt_pin.robot.Robot`
hands them. Constants of the model are folded, products by 0 and 1 dropped, and
rotation entries within :data:`SNAP` of 0 or ±1 (rounding of a URDF's π/2) taken as
exact. Each distinct operation is emitted once: sharing a tracer, the bias and the mass
matrix of ``"crba"`` compute the joint transforms once.

Units: q in rad or m, q̇ in rad/s or m/s, τ in N·m (revolute) or N (prismatic),
q̈ in rad/s² or m/s², M in kg·m² (revolute pairs), kg (prismatic) or kg·m (mixed).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from rrt_pin.core.errors import InputError
from rrt_pin.dynamics.rnea_source import (
    _KINDS,
    Scalar,
    _live,
    _rotation,
    _Spatial,
    _Tracer,
    check_supported,
    count_flops,
)

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "SNAP",
    "VARIANTS",
    "GeneratedFunction",
    "bias_source",
    "forward_source",
    "gravity_source",
    "mass_matrix_source",
]

#: Rotation and axis entries this close to 0, 1 or −1 are taken as exactly that: a URDF's
#: rpy of π/2 leaves ~1e-16 where 0 is meant (the result moves by ~1e-16 relative).
SNAP = 1e-15
#: The two forward-dynamics algorithms :func:`forward_source` generates.
VARIANTS = ("aba", "crba")

Vec = list  # three Scalars
Mat = list  # three rows of three Scalars
Motion = tuple  # (linear, angular): two Vecs
Sym6 = list  # six rows of six Scalars, symmetric


@dataclass(frozen=True)
class GeneratedFunction:
    """The straight-line code of one quantity of one model, for one sample.

    Attributes:
        name: what it computes (``mass_matrix``, ``bias``, ``gravity``, ``forward_aba``,
            ``forward_crba``).
        nv: velocity size (joint coordinates per sample).
        inputs: the arrays read, in order, from ``q``, ``v`` (q̇) and ``tau`` (τ); each
            ``x[k]`` with k < nv.
        shape: the result's shape, (nv,) or (nv, nv).
        lines: the statements, assigning temporaries ``t<n>``.
        outputs: the result's entries, row-major: a temporary, or a constant as text.
        flops: floating-point operations a sample (+, −, ·, /, unary −; sin, cos apart).
        transcendentals: sine and cosine evaluations a sample.
    """

    name: str
    nv: int
    inputs: tuple[str, ...]
    shape: tuple[int, ...]
    lines: tuple[str, ...]
    outputs: tuple[str, ...]
    flops: int
    transcendentals: int

    @property
    def nq(self) -> int:
        """Coordinates a sample takes (joint coordinates: nv)."""
        return self.nv

    def function(self) -> str:
        """A plain Python function ``name(*inputs, out)`` writing one sample's result into ``out``.

        ``out`` has :attr:`shape`; it needs ``cos`` and ``sin`` in its namespace.
        """
        body = [f"    {line}" for line in self.lines]
        for flat, x in enumerate(self.outputs):
            index = ", ".join(str(k) for k in _unravel(flat, self.shape))
            body.append(f"    out[{index}] = {x}")
        head = f"def {self.name}({', '.join(self.inputs)}, out):"
        return "\n".join([head, *body, "    return out", ""])


def _unravel(flat: int, shape: tuple[int, ...]) -> tuple[int, ...]:
    return (flat,) if len(shape) == 1 else divmod(flat, shape[1])


class _Ops(_Tracer):
    """The RNEA tracer with a reciprocal (ABA's and LDLᵀ's pivots)."""

    def inv(self, a: Scalar) -> Scalar:
        if isinstance(a, float):
            return 1.0 / a
        return self._emit(("inv", a), f"1.0 / {a}")


def _snap(x: float) -> float:
    for exact in (0.0, 1.0, -1.0):
        if abs(x - exact) <= SNAP:
            return exact
    return float(x)


@dataclass
class _Link:
    """One joint and its child body, traced for one sample."""

    parent: int  # parent joint (0: the base)
    k: int  # velocity index
    s: Motion  # constant motion subspace (linear, angular)
    fixed: tuple[Mat, Vec]  # the joint's placement in its parent's frame
    joint: tuple[Mat, Vec]  # the joint's own motion Mⱼ(q) (traced)
    armature: float
    inertia: tuple[float, Vec, Mat]  # mass, first moment m·c, inertia about the origin


def _body_inertia(inertia: Any) -> tuple[float, Vec, Mat]:
    """(m, h = m·c, I_O = I_c + m(|c|²·1 − c cᵀ)): the body's inertia about its frame's origin."""
    m = float(inertia.mass)
    c = [float(x) for x in inertia.lever]
    ic = [[float(x) for x in row] for row in inertia.inertia]
    cc = sum(x * x for x in c)
    i_o = [
        [ic[r][k] + m * ((cc if r == k else 0.0) - c[r] * c[k]) for k in range(3)] for r in range(3)
    ]
    return m, [m * x for x in c], i_o


def _links(model: pin.Model, t: _Ops) -> list[_Link]:
    """The traced joints of ``model`` (index 0: None, the base), reading ``q[idx_v]``."""
    import numpy as np

    check_supported(model)
    armature = [float(x) for x in model.armature]
    links: list[Any] = [None]
    for i in range(1, model.njoints):
        jm = model.joints[i]
        kind = _KINDS[jm.shortname()]
        data = jm.createData()
        q0 = np.zeros(jm.nq)
        if kind == "C":
            q0[0] = 1.0
        jm.calc(data, q0)
        s6 = [_snap(x) for x in np.asarray(data.S, dtype=float).reshape(6)]
        s_lin, s_ang = s6[:3], s6[3:]
        placement = model.jointPlacements[i]
        fixed = (
            [[_snap(x) for x in row] for row in placement.rotation],
            [float(x) for x in placement.translation],
        )
        k = jm.idx_v
        x = t.input("q", k)
        if kind == "P":
            eye = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
            joint = (eye, [t.mul(x, u) for u in s_lin])
        else:  # revolute or continuous: both take the angle
            joint = (_rotation(t, s_ang, t.call("cos", x), t.call("sin", x)), [0.0, 0.0, 0.0])
        links.append(
            _Link(
                parent=int(model.parents[i]),
                k=k,
                s=(s_lin, s_ang),
                fixed=fixed,
                joint=joint,
                armature=armature[k],
                inertia=_body_inertia(model.inertias[i]),
            )
        )
    return links


class _Algebra(_Spatial):
    """Spatial algebra of the generated algorithms: transforms along a joint, inertias."""

    t: _Ops

    def down(self, link: _Link, m: Motion) -> Motion:
        """A motion of the parent's frame in the child's frame."""
        return self.act_inv_motion(link.joint, self.act_inv_motion(link.fixed, m))

    def up(self, link: _Link, f: Motion) -> Motion:
        """A force of the child's frame in the parent's frame."""
        return self.act_force(link.fixed, self.act_force(link.joint, f))

    def madd(self, a: Motion, b: Motion) -> Motion:
        return self.vadd(a[0], b[0]), self.vadd(a[1], b[1])

    def sdot(self, s: Motion, f: Motion) -> Scalar:
        """Sᵀ f: a motion subspace's column against a force."""
        return self.t.add(self.t.dot(s[0], f[0]), self.t.dot(s[1], f[1]))

    def body_times(self, inertia: tuple[Scalar, Vec, Mat], m: Motion) -> Motion:
        """I·m with I as (mass, h, I_O): f = mass·v − h × w, n = I_O w + h × v."""
        mass, h, i_o = inertia
        v, w = m
        lin = self.vsub(self.scale(mass, v), self.cross(h, w))
        return lin, self.vadd(self.matvec(i_o, w), self.cross(h, v))

    def body_act(self, rp: tuple[Mat, Vec], inertia: tuple[Scalar, Vec, Mat]) -> tuple:
        """A body inertia of a frame expressed in the frame where that frame is at (R, p).

        mass' = mass, y = R h, h' = y + mass·p,
        I' = R I Rᵀ − [p]ₓ[h']ₓ − [y]ₓ[p]ₓ (entry by entry: [a]ₓ[b]ₓ = b aᵀ − (a·b)·1).
        """
        t = self.t
        r, p = rp
        mass, h, i_o = inertia
        y = self.matvec(r, h)
        h2 = self.vadd(y, self.scale(mass, p))
        rot = self.rotate_sym(r, i_o)
        diag = t.add(t.dot(p, h2), t.dot(y, p))
        out = [[0.0] * 3 for _ in range(3)]
        for a in range(3):
            for b in range(a, 3):
                e = t.sub(t.sub(rot[a][b], t.mul(h2[a], p[b])), t.mul(p[a], y[b]))
                out[a][b] = out[b][a] = t.add(e, diag) if a == b else e
        return mass, h2, out

    def rotate_sym(self, r: Mat, m: Mat) -> Mat:
        """R M Rᵀ of a symmetric M (upper triangle computed)."""
        rm = [[self.t.dot(r[a], [m[0][c], m[1][c], m[2][c]]) for c in range(3)] for a in range(3)]
        out = [[0.0] * 3 for _ in range(3)]
        for a in range(3):
            for b in range(a, 3):
                out[a][b] = out[b][a] = self.t.dot(rm[a], r[b])
        return out

    def rotate(self, r: Mat, m: Mat) -> Mat:
        """R M Rᵀ."""
        rm = [[self.t.dot(r[a], [m[0][c], m[1][c], m[2][c]]) for c in range(3)] for a in range(3)]
        return [[self.t.dot(rm[a], r[b]) for b in range(3)] for a in range(3)]

    def matmul(self, a: Mat, b: Mat) -> Mat:
        return [[self.t.dot(a[r], [b[0][c], b[1][c], b[2][c]]) for c in range(3)] for r in range(3)]

    def sym_act(self, rp: tuple[Mat, Vec], m6: Sym6) -> Sym6:
        """Xᵀ A X of a symmetric 6×6 A of a frame at (R, p), X the motion transform into it.

        Rotated block by block (R Aᵢⱼ Rᵀ), then shifted with P = [p]ₓ:
        A₁₂' = A₁₂ − A₁₁P, A₂₂' = A₂₂ + PA₁₂ + (PA₁₂)ᵀ − PA₁₁P.
        """
        t = self.t
        r, p = rp
        a11 = [row[:3] for row in m6[:3]]
        a12 = [row[3:] for row in m6[:3]]
        a22 = [row[3:] for row in m6[3:]]
        if r != [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]:
            a11, a12, a22 = self.rotate_sym(r, a11), self.rotate(r, a12), self.rotate_sym(r, a22)
        if any(x != 0.0 for x in p):
            skew = [[0.0, t.neg(p[2]), p[1]], [p[2], 0.0, t.neg(p[0])], [t.neg(p[1]), p[0], 0.0]]
            a11p = self.matmul(a11, skew)
            pa12 = self.matmul(skew, a12)
            pa11p = self.matmul(skew, a11p)
            a12 = [[t.sub(a12[i][j], a11p[i][j]) for j in range(3)] for i in range(3)]
            new22 = [[0.0] * 3 for _ in range(3)]
            for i in range(3):
                for j in range(i, 3):
                    e = t.add(t.add(a22[i][j], pa12[i][j]), pa12[j][i])
                    new22[i][j] = new22[j][i] = t.sub(e, pa11p[i][j])
            a22 = new22
        out: Sym6 = [[0.0] * 6 for _ in range(6)]
        for i in range(3):
            for j in range(3):
                out[i][j], out[i + 3][j + 3] = a11[i][j], a22[i][j]
                out[i][j + 3] = out[j + 3][i] = a12[i][j]
        return out

    def sym_times(self, m6: Sym6, m: Motion) -> Motion:
        x = [*m[0], *m[1]]
        out = [self.t.dot(row, x) for row in m6]
        return out[:3], out[3:]


def _body_matrix(inertia: tuple[float, Vec, Mat]) -> Sym6:
    """The 6×6 spatial inertia [[m·1, −[h]ₓ], [[h]ₓ, I_O]] (constants)."""
    m, h, i_o = inertia
    hx = [[0.0, -h[2], h[1]], [h[2], 0.0, -h[0]], [-h[1], h[0], 0.0]]
    out = [[0.0] * 6 for _ in range(6)]
    for i in range(3):
        out[i][i] = m
        for j in range(3):
            out[i][j + 3] = -hx[i][j]
            out[i + 3][j] = hx[i][j]
            out[i + 3][j + 3] = i_o[i][j]
    return out


def _gravity(model: pin.Model) -> Motion:
    """The base's acceleration, −gravity (linear, angular)."""
    g = model.gravity
    return [-float(x) for x in g.linear], [-float(x) for x in g.angular]


def _velocities(sp: _Algebra, links: list[_Link], with_v: bool) -> tuple[list, list]:
    """Each body's velocity, and its joint's velocity S·q̇ (None: at rest)."""
    zero = [0.0, 0.0, 0.0]
    vel: list[Any] = [(zero, zero)]
    vj: list[Any] = [None]
    for link in links[1:]:
        qd = sp.t.input("v", link.k) if with_v else 0.0
        sq = (sp.scale(qd, link.s[0]), sp.scale(qd, link.s[1]))
        vel.append(sp.madd(sp.down(link, vel[link.parent]), sq))
        vj.append(sq)
    return vel, vj


def _rnea(model: pin.Model, sp: _Algebra, links: list[_Link], with_v: bool) -> list[Scalar]:
    """τ of q̈ = 0: the bias b(q, q̇) (``with_v``) or gravity G(q)."""
    vel, vj = _velocities(sp, links, with_v)
    acc: list[Any] = [_gravity(model)]
    force: list[Any] = [None]
    for i, link in enumerate(links[1:], start=1):
        v = vel[i]
        a = sp.madd(sp.down(link, acc[link.parent]), sp.motion_cross(v, vj[i]))
        acc.append(a)
        force.append(
            sp.madd(
                sp.body_times(link.inertia, a), sp.force_cross(v, sp.body_times(link.inertia, v))
            )
        )
    tau: list[Scalar] = [0.0] * model.nv
    for i in range(len(links) - 1, 0, -1):
        link = links[i]
        tau[link.k] = sp.sdot(link.s, force[i])
        if link.parent > 0:
            force[link.parent] = sp.madd(force[link.parent], sp.up(link, force[i]))
    return tau


def _crba(model: pin.Model, sp: _Algebra, links: list[_Link]) -> list[list[Scalar]]:
    """M(q) (rows of Scalars; structural zeros 0.0), armature on the diagonal."""
    t = sp.t
    composite: list[Any] = [None] + [link.inertia for link in links[1:]]
    for i in range(len(links) - 1, 0, -1):
        link = links[i]
        if link.parent > 0:
            moved = sp.body_act(link.fixed, sp.body_act(link.joint, composite[i]))
            mine = composite[link.parent]
            composite[link.parent] = (
                t.add(mine[0], moved[0]),
                sp.vadd(mine[1], moved[1]),
                [sp.vadd(mine[2][r], moved[2][r]) for r in range(3)],
            )
    m: list[list[Scalar]] = [[0.0] * model.nv for _ in range(model.nv)]
    for i in range(1, len(links)):
        link = links[i]
        f = sp.body_times(composite[i], link.s)
        m[link.k][link.k] = t.add(sp.sdot(link.s, f), link.armature)
        j = i
        while links[j].parent > 0:
            f = sp.up(links[j], f)
            j = links[j].parent
            m[link.k][links[j].k] = m[links[j].k][link.k] = sp.sdot(links[j].s, f)
    return m


def _ldlt_solve(t: _Ops, m: list[list[Scalar]], parent: list[int], rhs: list[Scalar]) -> list:
    """The solution x of M x = rhs by Featherstone's LTDL: M = LᵀDL, L unit lower, tree-sparse.

    ``parent[k]``: the velocity index of coordinate k's parent (−1: the base); a parent's
    index is smaller than its children's. Only the entries (k, j), j an ancestor of k, are
    read or written: the factorization of a tree has no fill-in.
    """
    n = len(rhs)
    h = [row[:] for row in m]
    inv_d: list[Scalar] = [0.0] * n
    for k in range(n - 1, -1, -1):
        inv_d[k] = t.inv(h[k][k])
        i = parent[k]
        while i >= 0:
            a = t.mul(h[k][i], inv_d[k])
            j = i
            while j >= 0:
                h[i][j] = t.sub(h[i][j], t.mul(a, h[k][j]))
                j = parent[j]
            h[k][i] = a
            i = parent[i]
    x = list(rhs)
    for i in range(n - 1, -1, -1):  # Lᵀ y = rhs
        j = parent[i]
        while j >= 0:
            x[j] = t.sub(x[j], t.mul(h[i][j], x[i]))
            j = parent[j]
    x = [t.mul(x[i], inv_d[i]) for i in range(n)]
    for i in range(n):  # L x = D⁻¹ y
        j = parent[i]
        while j >= 0:
            x[i] = t.sub(x[i], t.mul(h[i][j], x[j]))
            j = parent[j]
    return x


def _aba(model: pin.Model, sp: _Algebra, links: list[_Link]) -> list[Scalar]:
    """q̈ by the articulated-body algorithm (articulated inertias as symmetric 6×6)."""
    t = sp.t
    n = len(links)
    vel, vj = _velocities(sp, links, with_v=True)
    bias_acc: list[Any] = [None] * n
    art: list[Any] = [None] * n
    pa: list[Any] = [None] * n
    for i in range(1, n):
        link = links[i]
        bias_acc[i] = sp.motion_cross(vel[i], vj[i])
        art[i] = _body_matrix(link.inertia)
        pa[i] = sp.force_cross(vel[i], sp.body_times(link.inertia, vel[i]))
    u_col: list[Any] = [None] * n
    inv_d: list[Any] = [None] * n
    u: list[Any] = [None] * n
    for i in range(n - 1, 0, -1):
        link = links[i]
        u_col[i] = sp.sym_times(art[i], link.s)
        inv_d[i] = t.inv(t.add(sp.sdot(link.s, u_col[i]), link.armature))
        u[i] = t.sub(t.input("tau", link.k), sp.sdot(link.s, pa[i]))
        if link.parent == 0:
            continue
        ud = [t.mul(inv_d[i], x) for x in (*u_col[i][0], *u_col[i][1])]
        col = [*u_col[i][0], *u_col[i][1]]
        ia: Sym6 = [[0.0] * 6 for _ in range(6)]
        for r in range(6):
            for c in range(r, 6):
                ia[r][c] = ia[c][r] = t.sub(art[i][r][c], t.mul(ud[r], col[c]))
        p = sp.madd(pa[i], sp.sym_times(ia, bias_acc[i]))
        p = sp.madd(p, (sp.scale(u[i], ud[:3]), sp.scale(u[i], ud[3:])))
        moved = sp.sym_act(link.fixed, sp.sym_act(link.joint, ia))
        mine = art[link.parent]
        art[link.parent] = [[t.add(mine[r][c], moved[r][c]) for c in range(6)] for r in range(6)]
        pa[link.parent] = sp.madd(pa[link.parent], sp.up(link, p))
    acc: list[Any] = [_gravity(model)] + [None] * (n - 1)
    qdd: list[Scalar] = [0.0] * model.nv
    for i in range(1, n):
        link = links[i]
        a = sp.madd(sp.down(link, acc[link.parent]), bias_acc[i])
        x = t.mul(inv_d[i], t.sub(u[i], sp.sdot(u_col[i], a)))
        qdd[link.k] = x
        acc[i] = sp.madd(a, (sp.scale(x, link.s[0]), sp.scale(x, link.s[1])))
    return qdd


def _finish(
    name: str, model: pin.Model, t: _Ops, inputs: tuple[str, ...], values: list, matrix: bool
) -> GeneratedFunction:
    outputs = tuple(t._c(x) for x in values)
    lines = _live(t.lines, outputs)
    shape = (model.nv, model.nv) if matrix else (model.nv,)
    return GeneratedFunction(
        name=name,
        nv=model.nv,
        inputs=inputs,
        shape=shape,
        lines=lines,
        outputs=outputs,
        flops=count_flops(lines),
        transcendentals=sum(line.split(" = ", 1)[1].startswith(("sin(", "cos(")) for line in lines),
    )


def _start(model: pin.Model) -> tuple[_Ops, _Algebra, list[_Link]]:
    t = _Ops()
    sp = _Algebra(t)
    return t, sp, _links(model, t)


def mass_matrix_source(model: pin.Model) -> GeneratedFunction:
    """The straight-line M(q) of ``model`` (CRBA), for one sample: ``mass_matrix(q, out)``.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    t, sp, links = _start(model)
    flat = [x for row in _crba(model, sp, links) for x in row]
    return _finish("mass_matrix", model, t, ("q",), flat, matrix=True)


def bias_source(model: pin.Model) -> GeneratedFunction:
    """The straight-line b(q, q̇) = C(q, q̇)·q̇ + G(q) of ``model``: ``bias(q, v, out)``.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    t, sp, links = _start(model)
    return _finish("bias", model, t, ("q", "v"), _rnea(model, sp, links, with_v=True), False)


def gravity_source(model: pin.Model) -> GeneratedFunction:
    """The straight-line G(q) of ``model``: ``gravity(q, out)``.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    t, sp, links = _start(model)
    return _finish("gravity", model, t, ("q",), _rnea(model, sp, links, with_v=False), False)


def forward_source(model: pin.Model, variant: str = "aba") -> GeneratedFunction:
    """The straight-line q̈ = M(q)⁻¹(τ − b(q, q̇)) of ``model``: ``forward_<variant>(q, v, tau, out)``.

    Args:
        model: a fixed-base Pinocchio model with supported joints.
        variant: ``"aba"`` (articulated-body algorithm) or ``"crba"`` (M by CRBA, b by
            RNEA, then the sparse LDLᵀ solve).

    Raises:
        InputError: an unknown ``variant``.
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    if variant not in VARIANTS:
        raise InputError(f"variant={variant!r} is unknown; known: {', '.join(VARIANTS)}")
    t, sp, links = _start(model)
    if variant == "aba":
        qdd = _aba(model, sp, links)
    else:
        bias = _rnea(model, sp, links, with_v=True)
        m = _crba(model, sp, links)
        parent = [-1] * model.nv
        for link in links[1:]:
            parent[link.k] = links[link.parent].k if link.parent > 0 else -1
        rhs = [t.sub(t.input("tau", k), bias[k]) for k in range(model.nv)]
        qdd = _ldlt_solve(t, m, parent, rhs)
    return _finish(f"forward_{variant}", model, t, ("q", "v", "tau"), qdd, matrix=False)
