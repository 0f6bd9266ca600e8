"""Machine-code dynamics of the RRT arm: the generated closed-form kernel under numba.

Importing this module imports numba and compiles (or loads from the disk cache
of :mod:`rrt_pin.compiled._cache`) every entry point below, each for one fixed
signature: float64 scalars, tuples and C-contiguous float64 arrays. Helpers
marked ``inline`` are inlined into their callers at numba's IR level and never
compiled on their own. The public, validated wrappers are in
:mod:`rrt_pin.compiled.dynamics`.

Layouts shared with the integrators:

* ``p``: the 15 physical parameters in ``rrt_pin.dynamics.kernel.PARAM_ORDER`` (SI units);
* a controller: ``kind`` 0 = no effort; 1 = eq. (31) of the chapter with its own
  parameters (another arm than the plant's); 2 = PD plus the plant's own G(q)
  (one kernel evaluation serves the dynamics and the compensation); 3 = eq. (31)
  with the plant's g, m2, m3, L2: its gravity terms are then exactly the plant's
  G(q) (the chapter's eq. (15)), so the dynamics fold them like kind 2, while the
  efforts reported at the output times are eq. (31) as printed. ``c`` = (kp1,
  kp2, kp3, kd1, kd2, kd3, q1f, q2f, q3f, *p_law) with p_law the 15 parameters
  the law was built with (eq. (31) reads g, m2, m3 and L2 from them).

The hot path, :func:`closed_loop`, takes ``p`` and ``c`` as tuples: calls
between separately compiled numba functions are not inlined by LLVM, and an
array argument costs two atomic reference-count updates per call, more than
the dynamics themselves; tuples are passed by value. The adaptive integrators'
stage loop uses :data:`closed_loop_inline`, the same function inlined at
numba's IR level (inlined at every call site, it doubled the compilation).

Numba's "numpy" error model is used: a division by zero gives inf or nan, which
the callers detect (no exception inside machine code). No fast-math: the
results must agree with Pinocchio to round-off, and nan must stay nan.
"""

from __future__ import annotations

import math

import numpy as np
from numba import float64, int64, types

from rrt_pin.compiled._jit import CACHE_PROBLEMS, ORIGINS, SIGNATURES, jit
from rrt_pin.dynamics import kernel
from rrt_pin.simulate.codes import (
    KIND_CHAPTER,
    KIND_CHAPTER_FOLDED,
    KIND_NONE,
    KIND_PD_PLANT_GRAVITY,
    NC,
    NP,
    SINCOS_FLOPS,  # noqa: F401  (re-exported: the flop count of vsincos, below)
)

__all__ = ["CACHE_PROBLEMS", "ORIGINS", "SIGNATURES", "jit"]

# Indices of the parameters eq. (31) needs, in kernel.PARAM_ORDER.
_L2 = kernel.PARAM_ORDER.index("L2")
_M2 = kernel.PARAM_ORDER.index("m2")
_M3 = kernel.PARAM_ORDER.index("m3")
_G = kernel.PARAM_ORDER.index("g")
_INF = math.inf

_f8 = float64
_vec = float64[::1]
_mat = float64[:, ::1]
_cube = float64[:, :, ::1]
# Inputs are typed read-only: writable arrays convert to them, read-only ones
# (e.g. a frozen Trajectory's) are accepted without a copy.
_rvec = types.Array(float64, 1, "C", readonly=True)
_rmat = types.Array(float64, 2, "C", readonly=True)
_PT = types.UniTuple(float64, NP)
_CT = types.UniTuple(float64, NC)

#: The generated kernel, unchanged (inlined into every caller).
terms = jit(None, inline=True)(kernel.terms)

# Vectorizable sine and cosine: Cephes' sin.c (S. L. Moshier), reduction by π/4 in
# three parts and degree-13/14 polynomials, with no call and no branch, so that a
# loop over samples vectorizes (libm's sin/cos are calls, which do not). Absolute
# error <= 2.3e-16 for |x| < SINCOS_LIMIT (tests/test_compiled.py checks it against
# numpy); callers use libm beyond.
SINCOS_LIMIT = 1e8
_FOPI = 1.27323954473516268615  # 4/π
_DP1 = 7.85398125648498535156e-1  # π/4 = DP1 + DP2 + DP3, DP1·j and DP2·j exact
_DP2 = 3.77489470793079817668e-8
_DP3 = 2.69515142907905952645e-15
_S = (
    1.58962301576546568060e-10, -2.50507477628578072866e-8, 2.75573136213857245213e-6,
    -1.98412698295895385996e-4, 8.33333333332211858878e-3, -1.66666666666666307295e-1,
)  # fmt: skip
_C = (
    -1.13585365213876817300e-11, 2.08757008419747316778e-9, -2.75573141792967388112e-7,
    2.48015872888517045348e-5, -1.38888888888730564116e-3, 4.16666666666665929218e-2,
)  # fmt: skip


@jit(None, inline=True)
def _octant(x):
    """(j, sin-polynomial, cos-polynomial) of |x| reduced to [-π/4, π/4], j the even octant."""
    ax = abs(x)
    j = np.int64(ax * _FOPI)
    j += j & 1
    y = float(j)
    z = ((ax - y * _DP1) - y * _DP2) - y * _DP3
    zz = z * z
    hs = ((((_S[0] * zz + _S[1]) * zz + _S[2]) * zz + _S[3]) * zz + _S[4]) * zz + _S[5]
    hc = ((((_C[0] * zz + _C[1]) * zz + _C[2]) * zz + _C[3]) * zz + _C[4]) * zz + _C[5]
    ps = z + z * zz * hs
    pc = 1.0 - 0.5 * zz + zz * zz * hc
    return j & 7, ps, pc


@jit(None, inline=True)
def vsin(x):
    """sin(x) for |x| < SINCOS_LIMIT (vectorizable)."""
    j, ps, pc = _octant(x)
    v = pc if j & 2 else ps
    v = -v if j & 4 else v
    return -v if x < 0.0 else v


@jit(None, inline=True)
def vcos(x):
    """cos(x) for |x| < SINCOS_LIMIT (vectorizable)."""
    j, ps, pc = _octant(x)
    v = ps if j & 2 else pc
    return -v if (j + 2) & 4 else v


@jit(None, inline=True)
def vsincos(x):
    """(sin x, cos x) for |x| < SINCOS_LIMIT, one shared reduction (vectorizable)."""
    j, ps, pc = _octant(x)
    s = pc if j & 2 else ps
    s = -s if j & 4 else s
    c = ps if j & 2 else pc
    c = -c if (j + 2) & 4 else c
    return (-s if x < 0.0 else s), c


@jit(None, inline=True)
def sincos(x):
    """(sin x, cos x): vsincos for |x| < SINCOS_LIMIT, else libm (also for inf and nan)."""
    if abs(x) < SINCOS_LIMIT:
        return vsincos(x)
    return math.sin(x), math.cos(x)


#: Samples a block of inverse_batch: its q1 and q2 are scanned first, then the block
#: takes the vectorized or the libm sine and cosine.
_BLOCK = 256


#: The generated inverse and forward dynamics (hand-factored, cos q2 and sin q2 as inputs).
inverse_terms = jit(None, inline=True)(kernel.inverse_terms)
inverse_constants = jit(None, inline=True)(kernel.inverse_constants)
forward_terms = jit(None, inline=True)(kernel.forward_terms)


@jit(None, inline=True)
def kernel_terms(q1, q2, q3, qd1, qd2, qd3, p):
    """(M11, M12, M13, M22, M23, M33, c1, c2, c3, G1, G2, G3) with parameters ``p``."""
    return terms(
        q1, q2, q3, qd1, qd2, qd3,
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], p[12],
        p[13], p[14],
    )  # fmt: skip


@jit(None, inline=True)
def as_tuple_p(p):
    """The 15 physical parameters as a tuple."""
    return (
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], p[12],
        p[13], p[14],
    )  # fmt: skip


@jit(None, inline=True)
def as_tuple_c(c):
    """The 24 controller parameters as a tuple."""
    return (
        c[0], c[1], c[2], c[3], c[4], c[5], c[6], c[7], c[8], c[9], c[10], c[11], c[12],
        c[13], c[14], c[15], c[16], c[17], c[18], c[19], c[20], c[21], c[22], c[23],
    )  # fmt: skip


@jit(None, inline=True)
def ldl_solve(m11, m12, m13, m22, m23, m33, b1, b2, b3):
    """Solve M x = b for a symmetric 3×3 M by LDLᵀ (closed form, no pivoting).

    Returns:
        (x1, x2, x3, bad): ``bad`` is 0 when M is positive definite and well
        conditioned (every pivot d_i > 1e-13 · Σ|M_jj|, all finite), else
        1 + the index of the first failing pivot (x is then meaningless).
    """
    tiny = 1e-13 * (abs(m11) + abs(m22) + abs(m33))  # nan if any entry is nan
    d1 = m11
    if not (tiny < d1 < _INF):
        return 0.0, 0.0, 0.0, 1
    r1 = 1.0 / d1
    l21 = m12 * r1
    l31 = m13 * r1
    d2 = m22 - l21 * m12
    if not (tiny < d2 < _INF):
        return 0.0, 0.0, 0.0, 2
    r2 = 1.0 / d2
    l32 = (m23 - l31 * m12) * r2
    d3 = m33 - l31 * m13 - l32 * l32 * d2
    if not (tiny < d3 < _INF):
        return 0.0, 0.0, 0.0, 3
    z2 = b2 - l21 * b1
    z3 = b3 - l31 * b1 - l32 * z2
    x3 = z3 / d3
    x2 = z2 * r2 - l32 * x3
    x1 = b1 * r1 - l21 * x2 - l31 * x3
    return x1, x2, x3, 0


@jit(None, inline=True)
def eq31(c, q1, q2, q3, qd1, qd2, qd3, s2, c2):
    """Eq. (31) of the chapter (T01x [N·m], T12y [N·m], F23z [N]) given sin q2 and cos q2.

    ``c`` as ``control``'s: the gravity terms read g, m2, m3 and L2 from the law's parameters.
    """
    u1 = -c[3] * qd1 - c[0] * (q1 - c[6])
    u2 = -c[4] * qd2 - c[1] * (q2 - c[7])
    u3 = -c[5] * qd3 - c[2] * (q3 - c[8])
    g = c[9 + _G]
    m2 = c[9 + _M2]
    m3 = c[9 + _M3]
    L2 = c[9 + _L2]
    return u1, u2 + g * m2 * L2 * c2 + g * m3 * c2 * (L2 + q3), u3 + g * m3 * s2


@jit(None, inline=True)
def control(kind, c, q1, q2, q3, qd1, qd2, qd3, G1, G2, G3):
    """Joint efforts (T01x [N·m], T12y [N·m], F23z [N]) of controller ``kind``.

    (G1, G2, G3) is the plant's gravity vector at q, used by
    ``KIND_PD_PLANT_GRAVITY`` and ``KIND_CHAPTER_FOLDED`` (other kinds ignore it).
    """
    if kind == KIND_NONE:
        return 0.0, 0.0, 0.0
    if kind == KIND_CHAPTER:
        # Eq. (31): the gravity compensation written out with the chapter's symbols.
        s2, c2 = sincos(q2)
        return eq31(c, q1, q2, q3, qd1, qd2, qd3, s2, c2)
    u1 = -c[3] * qd1 - c[0] * (q1 - c[6])
    u2 = -c[4] * qd2 - c[1] * (q2 - c[7])
    u3 = -c[5] * qd3 - c[2] * (q3 - c[8])
    if kind == KIND_PD_PLANT_GRAVITY or kind == KIND_CHAPTER_FOLDED:
        return u1 + G1, u2 + G2, u3 + G3
    return math.nan, math.nan, math.nan  # not a kind of this module: fail loudly


@jit(None, inline=True)
def effort(kind, c, p, q1, q2, q3, qd1, qd2, qd3):
    """The efforts the controller reports at one state (eq. (31) as printed for kinds 1 and 3)."""
    if kind == KIND_PD_PLANT_GRAVITY:
        r = kernel_terms(q1, q2, q3, 0.0, 0.0, 0.0, p)
        return control(kind, c, q1, q2, q3, qd1, qd2, qd3, r[9], r[10], r[11])
    if kind == KIND_CHAPTER_FOLDED:
        return control(KIND_CHAPTER, c, q1, q2, q3, qd1, qd2, qd3, 0.0, 0.0, 0.0)
    return control(kind, c, q1, q2, q3, qd1, qd2, qd3, 0.0, 0.0, 0.0)


@jit(None, inline=True)
def control_sc(kind, c, q1, q2, q3, qd1, qd2, qd3, s2, c2, G2, G3):
    """``control(kind, c, q, q̇, 0.0, G2, G3)`` given (s2, c2) = ``sincos(q2)``, by selects.

    The same operations as ``control`` for every kind (the same bits), all of them
    computed and the kind's chosen: no call and no branch, so that a loop over
    variants of different kinds vectorizes (:mod:`rrt_pin.compiled._jit_batch`).
    """
    u1 = -c[3] * qd1 - c[0] * (q1 - c[6])
    u2 = -c[4] * qd2 - c[1] * (q2 - c[7])
    u3 = -c[5] * qd3 - c[2] * (q3 - c[8])
    e1, e2, e3 = eq31(c, q1, q2, q3, qd1, qd2, qd3, s2, c2)
    law = kind == KIND_CHAPTER
    plant = kind == KIND_PD_PLANT_GRAVITY or kind == KIND_CHAPTER_FOLDED
    other = math.nan if kind != KIND_NONE else 0.0  # an unknown kind fails loudly
    v1 = e1 if law else (u1 + 0.0 if plant else other)
    v2 = e2 if law else (u2 + G2 if plant else other)
    v3 = e3 if law else (u3 + G3 if plant else other)
    return v1, v2, v3


@jit(None, inline=True)
def accelerations(kind, c, k, q1, q2, q3, qd1, qd2, qd3, s2, c2):
    """``closed_loop`` given (s2, c2) = ``sincos(q2)`` and k = ``inverse_constants(*p)``.

    No call and no branch (selects): the body of the variants' loop of
    :mod:`rrt_pin.compiled._jit_batch`, and of ``closed_loop`` (one definition).
    """
    k0, k1, k2, k3, k4, k5, k6, k7, k8, k9 = k
    M11, M22, n1, n2, n3, G2, G3 = forward_terms(
        c2, s2, q3, qd1, qd2, qd3, k0, k1, k2, k3, k4, k5, k6, k7, k8, k9
    )
    u1, u2, u3 = control_sc(kind, c, q1, q2, q3, qd1, qd2, qd3, s2, c2, G2, G3)
    M33 = k0  # m3
    tiny = 1e-13 * (abs(M11) + abs(M22) + abs(M33))  # nan if any entry is nan
    bad = 3 if not (tiny < M33 < _INF) else 0
    bad = 2 if not (tiny < M22 < _INF) else bad
    bad = 1 if not (tiny < M11 < _INF) else bad
    a1 = (u1 - n1) / M11 if bad == 0 else 0.0
    a2 = (u2 - n2 - G2) / M22 if bad == 0 else 0.0
    a3 = (u3 - n3 - G3) / M33 if bad == 0 else 0.0
    return a1, a2, a3, u1, u2, u3, bad


@jit(
    types.Tuple((_f8, _f8, _f8, _f8, _f8, _f8, int64))(
        int64, _CT, _PT, _f8, _f8, _f8, _f8, _f8, _f8
    )
)
def closed_loop(kind, c, p, q1, q2, q3, qd1, qd2, qd3):
    """(q̈1, q̈2, q̈3, τ1, τ2, τ3, bad): forward dynamics under controller ``kind``.

    q̈ [rad/s², m/s²] solves M(q)·q̈ = τ − c(q, q̇) − G(q) with τ = the
    controller's efforts [N·m, N·m, N]. M is diagonal (the generated
    ``forward_terms``: M12 = M13 = M23 = 0 proved when generated), so q̈ is
    three divisions; ``bad`` is 0, or 1 + the index of the first diagonal
    entry that is not > 1e-13·trace and finite (as ldl_solve's pivots; q̈ is
    then 0). One evaluation serves the dynamics and, for kinds 2 and 3, the gravity
    compensation. Sine and cosine are one inlined vsincos (no libm call)
    unless |q2| >= SINCOS_LIMIT.
    """
    s2, c2 = sincos(q2)
    k = inverse_constants(
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], p[12],
        p[13], p[14],
    )  # fmt: skip
    return accelerations(kind, c, k, q1, q2, q3, qd1, qd2, qd3, s2, c2)


#: closed_loop inlined at numba's IR level into its caller: the integrators' hot
#: stage loops use it (LLVM then hoists the parameter combinations out of the loop
#: and passes nothing by value); other call sites call closed_loop, compiled once.
closed_loop_inline = jit(None, inline=True)(closed_loop.py_func)


@jit(None, inline=True)
def poison(a, i):
    """0.0 if row ``i`` of the (N, 3) array ``a`` is finite, else nan (no branch: vectorizes)."""
    return 0.0 * a[i, 0] + 0.0 * a[i, 1] + 0.0 * a[i, 2]


# The batch functions check their inputs as they read them, for free: they
# return the sum of 0·x over every input x, which is 0.0 when all are finite and
# nan otherwise (the caller then locates the value). A branch per row instead
# would cost more than the dynamics.
@jit(float64(_rmat, _rvec, _cube))
def mass_matrix_batch(q, p, out):
    """M(q) [kg·m², kg·m, kg] of every row of q (N, 3) into out (N, 3, 3)."""
    check = 0.0
    for i in range(q.shape[0]):
        check += poison(q, i)
        r = kernel_terms(q[i, 0], q[i, 1], q[i, 2], 0.0, 0.0, 0.0, p)
        out[i, 0, 0] = r[0]
        out[i, 0, 1] = r[1]
        out[i, 0, 2] = r[2]
        out[i, 1, 0] = r[1]
        out[i, 1, 1] = r[3]
        out[i, 1, 2] = r[4]
        out[i, 2, 0] = r[2]
        out[i, 2, 1] = r[4]
        out[i, 2, 2] = r[5]
    return check


@jit(float64(_rmat, _rmat, _rvec, int64, _mat))
def bias_batch(q, qd, p, which, out):
    """Per row [N·m, N·m, N]: which = 0 c + G (nonlinear effects), 1 c (Coriolis), 2 G."""
    check = 0.0
    for i in range(q.shape[0]):
        check += poison(q, i) + poison(qd, i)
        r = kernel_terms(q[i, 0], q[i, 1], q[i, 2], qd[i, 0], qd[i, 1], qd[i, 2], p)
        for k in range(3):
            if which == 0:
                out[i, k] = r[6 + k] + r[9 + k]
            elif which == 1:
                out[i, k] = r[6 + k]
            else:
                out[i, k] = r[9 + k]
    return check


@jit(float64(_rmat, _rmat, _rmat, _rvec, _mat))
def inverse_batch(q, qd, qdd, p, out):
    """τ = M(q) q̈ + c(q, q̇) + G(q) [N·m, N·m, N] of every row into out (N, 3).

    Per block of rows, q1 and q2 are scanned, then the generated
    ``inverse_terms`` runs over the block with the vectorizable sine and cosine
    (one reduction for both), several samples per instruction (blocks holding
    some |q2| >= SINCOS_LIMIT, or a non-finite q2, use libm). The returned
    check is nan if an input or an output is not finite: q1, which τ does not
    depend on, is tested as it is copied; every other input reaches an
    output, so a non-finite one makes τ non-finite, and one comparison of
    τ1 + τ2 + τ3 a sample, OR-ed into a flag, finds it (a false alarm when
    the sum alone overflows costs only the caller's search).
    """
    k = inverse_constants(
        p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7], p[8], p[9], p[10], p[11], p[12],
        p[13], p[14],
    )  # fmt: skip
    k0, k1, k2, k3, k4, k5, k6, k7, k8, k9 = k
    n = q.shape[0]
    bad = False
    for start in range(0, n, _BLOCK):
        m = min(_BLOCK, n - start)
        # The block's rows as flat views, indexed from 0 (so indexed, the loops
        # below vectorize; as 2-D arrays, or from ``start``, they do not).
        qf = q[start : start + m].reshape(-1)
        qdf = qd[start : start + m].reshape(-1)
        qddf = qdd[start : start + m].reshape(-1)
        of = out[start : start + m].reshape(-1)
        small = 0
        finite1 = 0
        for j in range(m):
            small += abs(qf[3 * j + 1]) < SINCOS_LIMIT
            finite1 += abs(qf[3 * j]) < _INF
        bad |= finite1 != m
        if small == m:
            for j in range(m):
                i = 3 * j
                s2, c2 = vsincos(qf[i + 1])
                t1, t2, t3 = inverse_terms(
                    c2, s2, qf[i + 2], qdf[i], qdf[i + 1], qdf[i + 2], qddf[i], qddf[i + 1],
                    qddf[i + 2], k0, k1, k2, k3, k4, k5, k6, k7, k8, k9,
                )  # fmt: skip
                of[i] = t1
                of[i + 1] = t2
                of[i + 2] = t3
                bad |= not (abs(t1 + t2 + t3) < _INF)
        else:
            for j in range(m):
                i = 3 * j
                x = qf[i + 1]
                t1, t2, t3 = inverse_terms(
                    math.cos(x), math.sin(x), qf[i + 2], qdf[i], qdf[i + 1], qdf[i + 2],
                    qddf[i], qddf[i + 1], qddf[i + 2], k0, k1, k2, k3, k4, k5, k6, k7, k8, k9,
                )  # fmt: skip
                of[i] = t1
                of[i + 1] = t2
                of[i + 2] = t3
                bad |= not (abs(t1 + t2 + t3) < _INF)
    return math.nan if bad else 0.0


@jit(types.Tuple((float64, int64))(_rmat, _rmat, _rmat, _rvec, _mat))
def forward_batch(q, qd, tau, p, out):
    """q̈ [rad/s², m/s²] of every row into out (N, 3).

    Returns (check, row): ``check`` as the other batch functions; ``row`` -1,
    or the first row whose mass matrix is singular or ill-conditioned.
    """
    check = 0.0
    for i in range(q.shape[0]):
        check += poison(q, i) + poison(qd, i) + poison(tau, i)
        r = kernel_terms(q[i, 0], q[i, 1], q[i, 2], qd[i, 0], qd[i, 1], qd[i, 2], p)
        a1, a2, a3, bad = ldl_solve(
            r[0], r[1], r[2], r[3], r[4], r[5],
            tau[i, 0] - r[6] - r[9], tau[i, 1] - r[7] - r[10], tau[i, 2] - r[8] - r[11],
        )  # fmt: skip
        if bad != 0 and math.isfinite(check):
            return check, i
        out[i, 0] = a1
        out[i, 1] = a2
        out[i, 2] = a3
    return check, -1
