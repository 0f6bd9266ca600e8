"""Machine-code integrators over the compiled RRT dynamics: whole runs, no Python per step.

The state is y = (q1, q2, q3, q̇1, q̇2, q̇3) [rad, rad, m, rad/s, rad/s, m/s];
the right-hand side is ẏ = (q̇, M⁻¹(τ − c − G)) with τ from the compiled
controller (see :mod:`rrt_pin.compiled._jit_dynamics` for the layouts of the
parameter vector ``p`` and of the controller ``kind``/``c``).

Adaptive methods replicate SciPy's ``solve_ivp`` step by step: the same
initial-step selection, error norms, step-size controller (safety 0.9, factors
0.2…10) and dense output at ``t_eval`` (DOP853: the 7th-order interpolant with
three extra stages; RK45: Shampine's quartic). With the same right-hand side
they take the same steps as SciPy, up to round-off.

Fixed-step methods step from sample to sample of ``t_eval``, each interval cut
into ``ceil(Δt / dt)`` equal substeps (one substep when ``dt <= 0``).

Every run returns a status instead of raising (machine code cannot raise a
Python exception cheaply): see the ``STATUS_*`` codes of :mod:`rrt_pin.simulate.codes`.
"""

from __future__ import annotations

import math

import numpy as np
from numba import float64, int64, types

from rrt_pin.compiled import _dop853_coefficients as dop
from rrt_pin.compiled._jit_dynamics import (
    SINCOS_LIMIT,
    as_tuple_c,
    as_tuple_p,
    closed_loop,
    closed_loop_inline,
    effort,
    eq31,
    jit,
    vsincos,
)
from rrt_pin.simulate.codes import (
    FIXED_STEP_FROM,
    KIND_CHAPTER,
    KIND_CHAPTER_FOLDED,
    METHOD_DOP853,
    METHOD_RK4,
    METHOD_SYMPLECTIC_EULER,
    STATUS_EFFORT_NONFINITE,
    STATUS_MAX_STEPS,
    STATUS_NO_CONVERGENCE,
    STATUS_NONFINITE,
    STATUS_OK,
    STATUS_SINGULAR_MASS,
    STATUS_STEP_UNDERFLOW,
)

__all__ = ["integrate"]


#: Verlet's fixed-point iterations stop at this relative change (as rrt_pin.simulate.integrators) …
VERLET_TOL = 1e-14
#: … or fail after this many iterations.
VERLET_MAX_ITER = 50


SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
N = 6

# RK45 (Dormand–Prince 5(4)), as in scipy.integrate._ivp.rk.RK45.
RK45_C = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1])
RK45_A = np.array(
    [
        [0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656],
    ]
)
RK45_B = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
#: RK45_A with B as its last row: the stage loop computes y_new as a 7th "stage".
RK45_AB = np.vstack([np.hstack([RK45_A, np.zeros((6, 1))]), RK45_B])
RK45_E = np.array([-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
RK45_P = np.array(
    [
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [
            0,
            127303824393 / 49829197408,
            -318862633887 / 49829197408,
            701980252875 / 199316789632,
        ],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ]
)

# DOP853, as in scipy.integrate._ivp.rk.DOP853 (row 12 of A is B; rows 13-15 are
# the extra stages of the dense output).
D8_NS = dop.N_STAGES
D8_A = np.ascontiguousarray(dop.A)
D8_C = np.ascontiguousarray(dop.C)
D8_E3 = np.ascontiguousarray(dop.E3)
D8_E5 = np.ascontiguousarray(dop.E5)
D8_D = np.ascontiguousarray(dop.D)

_vec = float64[::1]
_mat = float64[:, ::1]
_rvec = types.Array(float64, 1, "C", readonly=True)  # inputs: read-only accepted, no copy
_rmat = types.Array(float64, 2, "C", readonly=True)
_rivec = types.Array(int64, 1, "C", readonly=True)
_RESULT = types.Tuple((int64, int64, int64, int64, int64, int64, float64))
# RK4's stages evaluate f at y + RK4_C[s]·h·k_{s-1}.
RK4_C = np.array([0.0, 0.5, 0.5, 1.0])


@jit(None, inline=True)
def rhs(y, p, c, kind, out):
    """ẏ of the closed loop into ``out`` (6,); returns 0 or 1 + the singular pivot.

    ``p`` and ``c`` are tuples (see ``closed_loop``).
    """
    a1, a2, a3, _, _, _, bad = closed_loop(kind, c, p, y[0], y[1], y[2], y[3], y[4], y[5])
    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    out[3] = a1
    out[4] = a2
    out[5] = a3
    return bad


@jit(None, inline=True)
def rhs_inline(y, p, c, kind, out):
    """``rhs`` with the dynamics inlined: for the adaptive methods' stage loops."""
    a1, a2, a3, _, _, _, bad = closed_loop_inline(kind, c, p, y[0], y[1], y[2], y[3], y[4], y[5])
    out[0] = y[3]
    out[1] = y[4]
    out[2] = y[5]
    out[3] = a1
    out[4] = a2
    out[5] = a3
    return bad


@jit(None, inline=True)
def first_nonfinite(v):
    """Index of the first non-finite entry of ``v``, or -1."""
    for i in range(v.shape[0]):
        if not math.isfinite(v[i]):
            return i
    return -1


@jit(None, inline=True)
def rms_scaled(v, scale):
    """RMS norm of v / scale (SciPy's ``norm``)."""
    s = 0.0
    for i in range(v.shape[0]):
        x = v[i] / scale[i]
        s += x * x
    return math.sqrt(s / v.shape[0])


_ry2 = types.Array(float64, 2, "A", readonly=True)
_wy2 = types.Array(float64, 2, "A")


@jit(types.boolean(int64, _rvec, _rvec, _ry2, _wy2, int64))
def efforts_at(kind, cvec, p, y, tau, n):
    """``effort`` at the first ``n`` states y (n, 6+) into tau (n, 3): any controller kind.

    Whether one is not finite (|τ1 + τ2 + τ3| < inf fails). Compiled once (any
    layout: rows of a run, transposed rows of a scratch run) for the callers' loops
    that are not eq. (31)'s vectorized one.
    """
    bad = False
    for i in range(n):
        u1, u2, u3 = effort(kind, cvec, p, y[i, 0], y[i, 1], y[i, 2], y[i, 3], y[i, 4], y[i, 5])
        tau[i, 0] = u1
        tau[i, 1] = u2
        tau[i, 2] = u3
        bad |= not (abs(u1 + u2 + u3) < math.inf)
    return bad


@jit(int64(int64, _rvec, _rvec, _mat, _mat, int64))
def fill_efforts(kind, cvec, p, out_y, out_tau, n):
    """The controller's efforts at the first ``n`` output states, into out_tau.

    Returns -1, or 3·i + k of the first non-finite effort (row i, effort k). Eq. (31)
    (kinds 1 and 3), when every |q2| is below SINCOS_LIMIT, runs as one loop over
    flat views with the branch-free sine and cosine and the law's constants in
    registers, which vectorizes; finiteness is one flag OR-ed per sample (from
    |τ1 + τ2 + τ3| < inf, a false alarm when only the sum overflows costs the search).
    """
    bad = False
    chapter = kind == KIND_CHAPTER or kind == KIND_CHAPTER_FOLDED
    if chapter:
        for i in range(n):
            chapter &= abs(out_y[i, 1]) < SINCOS_LIMIT
    if chapter:
        c = as_tuple_c(cvec)
        yf = out_y.reshape(-1)
        tf = out_tau.reshape(-1)
        for j in range(n):
            i = 6 * j
            s2, c2 = vsincos(yf[i + 1])
            u1, u2, u3 = eq31(
                c, yf[i], yf[i + 1], yf[i + 2], yf[i + 3], yf[i + 4], yf[i + 5], s2, c2
            )
            tf[3 * j] = u1
            tf[3 * j + 1] = u2
            tf[3 * j + 2] = u3
            bad |= not (abs(u1 + u2 + u3) < math.inf)
    else:
        bad = efforts_at(kind, cvec, p, out_y, out_tau, n)
    if not bad:
        return -1
    for i in range(n):
        for k in range(3):
            if not math.isfinite(out_tau[i, k]):
                return 3 * i + k
    return -1  # only the sum overflowed


@jit(None, inline=True)
def fill_efforts_rows(kind, cvec, p, rows, n):
    """``fill_efforts`` by rows: states rows[0:6], efforts into rows[6:9] (9, T), samples < n.

    The same arithmetic per sample (the same bits); every row is contiguous, so
    eq. (31)'s loop vectorizes with plain vector loads and stores.
    """
    q1, q2, q3, qd1, qd2, qd3 = rows[0], rows[1], rows[2], rows[3], rows[4], rows[5]
    t1, t2, t3 = rows[6], rows[7], rows[8]
    bad = False
    chapter = kind == KIND_CHAPTER or kind == KIND_CHAPTER_FOLDED
    if chapter:
        for i in range(n):
            chapter &= abs(q2[i]) < SINCOS_LIMIT
    if chapter:
        c = as_tuple_c(cvec)
        for i in range(n):
            s2, c2 = vsincos(q2[i])
            u1, u2, u3 = eq31(c, q1[i], q2[i], q3[i], qd1[i], qd2[i], qd3[i], s2, c2)
            t1[i] = u1
            t2[i] = u2
            t3[i] = u3
            bad |= not (abs(u1 + u2 + u3) < math.inf)
    else:
        bad = efforts_at(kind, cvec, p, rows[0:6].T, rows[6:9].T, n)
    if not bad:
        return -1
    for i in range(n):
        for k in range(3):
            if not math.isfinite(rows[6 + k, i]):
                return 3 * i + k
    return -1


@jit(None, inline=True)
def combine(y, K, A, s, h, out):
    """Write y + h · Σ_{j<s} A[s, j] K[j] into ``out`` (SciPy's order: the sum, then · h)."""
    a0 = a1 = a2 = a3 = a4 = a5 = 0.0
    for j in range(s):
        aj = A[s, j]
        if aj != 0.0:
            a0 += aj * K[j, 0]
            a1 += aj * K[j, 1]
            a2 += aj * K[j, 2]
            a3 += aj * K[j, 3]
            a4 += aj * K[j, 4]
            a5 += aj * K[j, 5]
    out[0] = y[0] + a0 * h
    out[1] = y[1] + a1 * h
    out[2] = y[2] + a2 * h
    out[3] = y[3] + a3 * h
    out[4] = y[4] + a4 * h
    out[5] = y[5] + a5 * h


@jit(None, inline=True)
def dense_dop853(F, y, t_eval, t, h, start, end, out_y):
    """SciPy's Dop853DenseOutput at t_eval[start:end] into out_y: nested in x and 1 − x.

    The step's coefficients F (7, 6) and y are read into scalars once (the stores to
    out_y could alias them), and the samples, independent of each other, form a
    counted loop over views indexed from 0, which LLVM vectorizes (from ``start``,
    with indices it cannot prove non-negative, it does not).
    """
    y0, y1, y2, y3, y4, y5 = y[0], y[1], y[2], y[3], y[4], y[5]
    a0, a1, a2, a3, a4, a5 = F[0, 0], F[0, 1], F[0, 2], F[0, 3], F[0, 4], F[0, 5]
    b0, b1, b2, b3, b4, b5 = F[1, 0], F[1, 1], F[1, 2], F[1, 3], F[1, 4], F[1, 5]
    c0, c1, c2, c3, c4, c5 = F[2, 0], F[2, 1], F[2, 2], F[2, 3], F[2, 4], F[2, 5]
    d0, d1, d2, d3, d4, d5 = F[3, 0], F[3, 1], F[3, 2], F[3, 3], F[3, 4], F[3, 5]
    e0, e1, e2, e3, e4, e5 = F[4, 0], F[4, 1], F[4, 2], F[4, 3], F[4, 4], F[4, 5]
    f0, f1, f2, f3, f4, f5 = F[5, 0], F[5, 1], F[5, 2], F[5, 3], F[5, 4], F[5, 5]
    g0, g1, g2, g3, g4, g5 = F[6, 0], F[6, 1], F[6, 2], F[6, 3], F[6, 4], F[6, 5]
    of = out_y[start:end].reshape(-1)  # views indexed from 0: the loop vectorizes
    te = t_eval[start:end]
    for m in range(te.shape[0]):
        x = (te[m] - t) / h
        w = 1.0 - x
        j = 6 * m
        # (((((((0 + F6)·x + F5)·w + F4)·x + F3)·w + F2)·x + F1)·w + F0)·x + y, as SciPy's loop
        of[j + 0] = ((((((g0 * x + f0) * w + e0) * x + d0) * w + c0) * x + b0) * w + a0) * x + y0
        of[j + 1] = ((((((g1 * x + f1) * w + e1) * x + d1) * w + c1) * x + b1) * w + a1) * x + y1
        of[j + 2] = ((((((g2 * x + f2) * w + e2) * x + d2) * w + c2) * x + b2) * w + a2) * x + y2
        of[j + 3] = ((((((g3 * x + f3) * w + e3) * x + d3) * w + c3) * x + b3) * w + a3) * x + y3
        of[j + 4] = ((((((g4 * x + f4) * w + e4) * x + d4) * w + c4) * x + b4) * w + a4) * x + y4
        of[j + 5] = ((((((g5 * x + f5) * w + e5) * x + d5) * w + c5) * x + b5) * w + a5) * x + y5


@jit(None, inline=True)
def dense_rk45(F, y, t_eval, t, h, start, end, out_y):
    """SciPy's RkDenseOutput at t_eval[start:end] into out_y: y_old + h · Q · (x, x², x³, x⁴)."""
    for j in range(start, end):
        x = (t_eval[j] - t) / h
        x2 = x * x
        x3 = x2 * x
        x4 = x3 * x
        for i in range(N):
            out_y[j, i] = h * (F[0, i] * x + F[1, i] * x2 + F[2, i] * x3 + F[3, i] * x4) + y[i]


@jit(None, inline=True)
def samples_until(t_eval, start, t):
    """The first index >= start whose time is after ``t``, or len(t_eval): the samples a step covers.

    A binary search without branches on the comparisons (``t_eval`` increases): a
    step covers tens of samples, and a scan paid a load and a compare for each (in
    the lanes' loop, also reloads of pointers spilled to the stack).
    """
    lo = start
    n = t_eval.shape[0] - start
    while n > 0:
        half = n // 2
        mid = lo + half
        before = t_eval[mid] <= t
        lo = mid + 1 if before else lo
        n = n - half - 1 if before else half
    return lo


@jit(None, inline=True)
def _step_fractions(t_eval, t, h, start, end, xs):
    """xs[m] = (t_eval[start + m] − t) / h, the samples' fractions of the step (views from 0)."""
    te = t_eval[start:end]
    for m in range(te.shape[0]):
        xs[m] = (te[m] - t) / h


#: Samples :func:`dense_dop853_rows` rounds a step's samples up to (a vector of 8
#: doubles): its rows and fraction scratch need this many columns beyond the last.
DENSE_PAD = 8


@jit(None, inline=True)
def dense_dop853_rows(F, y, t_eval, t, h, start, end, rows, xs):
    """``dense_dop853`` into rows (6, ≥ T + DENSE_PAD): component i of sample m at rows[i, m].

    The same operations in the same order (the same bits); the fractions x are
    divided once into the scratch ``xs`` (≥ end − start + DENSE_PAD, finite), and each
    component's samples are contiguous, so every loop vectorizes without gathers or
    scatters. A step covers a few dozen samples: their count is rounded up to a
    multiple of DENSE_PAD, so that the loops have no scalar remainder (a large
    share of their time at a few dozen samples); the samples past ``end`` take stale fractions, and are written
    again by the steps that cover them (or lie past T).
    """
    _step_fractions(t_eval, t, h, start, end, xs)
    n = (end - start + DENSE_PAD - 1) // DENSE_PAD * DENSE_PAD
    for i in range(N):
        a, b, c, d = F[0, i], F[1, i], F[2, i], F[3, i]
        e, f, g, yi = F[4, i], F[5, i], F[6, i], y[i]
        row = rows[i, start : start + n]
        for m in range(n):
            x = xs[m]
            w = 1.0 - x
            row[m] = ((((((g * x + f) * w + e) * x + d) * w + c) * x + b) * w + a) * x + yi


@jit(None, inline=True)
def dense_rk45_rows(F, y, t_eval, t, h, start, end, rows, xs):
    """``dense_rk45`` into rows (6, ≥ T): component i of sample m at rows[i, m] (the same bits)."""
    _step_fractions(t_eval, t, h, start, end, xs)
    for i in range(N):
        a, b, c, d, yi = F[0, i], F[1, i], F[2, i], F[3, i], y[i]
        row = rows[i, start:end]
        for m in range(row.shape[0]):
            x = xs[m]
            x2 = x * x
            x3 = x2 * x
            x4 = x3 * x
            row[m] = h * (a * x + b * x2 + c * x3 + d * x4) + yi


@jit(None, inline=True)
def tableau(method):
    """(dop853, stages, step-size exponent, order, A with B as its last row) of RK45 or DOP853."""
    if method == METHOD_DOP853:
        return True, D8_NS, -1.0 / 8.0, 7.0, D8_A
    return False, 6, -1.0 / 5.0, 4.0, RK45_AB


@jit(None, inline=True)
def first_step(y, t, p, c, kind, atol, rtol, order, interval, max_step, f, ytmp, err, scale):
    """f(t, y) into ``f``, then SciPy's ``select_initial_step`` (one more evaluation).

    Returns:
        (status, coordinate, n_evals, h): STATUS_OK and the first step size, or a
        singular mass matrix or a non-finite derivative, its coordinate and the time
        of the failing evaluation [s] in place of h. ``ytmp``, ``err``, ``scale`` are scratch.
    """
    h0 = 0.0
    n_evals = 0
    for stage in range(2):
        bad = rhs(ytmp if stage else y, p, c, kind, err if stage else f)
        n_evals += 1
        if bad != 0:
            return STATUS_SINGULAR_MASS, bad - 1, n_evals, t + h0
        k = first_nonfinite(err if stage else f)
        if k >= 0:
            return STATUS_NONFINITE, k, n_evals, t + h0
        if stage == 0:
            for i in range(N):
                scale[i] = atol[i] + abs(y[i]) * rtol
            d0 = rms_scaled(y, scale)
            d1 = rms_scaled(f, scale)
            if d0 < 1e-5 or d1 < 1e-5:
                h0 = 1e-6
            else:
                h0 = 0.01 * d0 / d1
            h0 = min(h0, interval)
            for i in range(N):
                ytmp[i] = y[i] + h0 * f[i]
    for i in range(N):
        err[i] = err[i] - f[i]
    d2 = rms_scaled(err, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
    return STATUS_OK, -1, n_evals, min(100.0 * h0, h1, interval, max_step)


@jit(_RESULT(int64, _rvec, _rvec, _rvec, float64, float64, int64, _rvec, int64, _rvec, _mat))
def adaptive(method, y0, t_eval, atol, rtol, max_step, max_steps, p_arr, kind, c_arr, out_y):
    """RK45 (method 0) or DOP853 (method 1) with SciPy's error control; see ``integrate``.

    One run (a batch's variants run side by side in :mod:`rrt_pin.compiled._jit_batch`,
    whose lanes do these operations): out_y (T, 6) gets the state at every t_eval
    (needs len(t_eval) >= 2).
    """
    p = as_tuple_p(p_arr)
    c = as_tuple_c(c_arr)
    dop853, n_stages, exponent, order, A = tableau(method)
    n_out = t_eval.shape[0]
    K = np.empty((16, N))
    F = np.empty((7, N))
    y = y0.copy()
    y_new = np.empty(N)
    ytmp = np.empty(N)
    f = np.empty(N)
    err = np.empty(N)
    err3 = np.empty(N)
    scale = np.empty(N)
    t = t_eval[0]
    t_bound = t_eval[n_out - 1]
    interval = t_bound - t
    n_evals = 0
    n_steps = 0
    n_rejected = 0
    i_out = 0

    status, k, n_evals, h_abs = first_step(y, t, p, c, kind, atol, rtol, order, interval,
                                           max_step, f, ytmp, err, scale)  # fmt: skip
    if status != STATUS_OK:
        return status, k, n_evals, 0, 0, 0, h_abs  # h_abs: the failure time

    limiting = 0
    while True:
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h_abs > max_step:
            h_abs = max_step
        elif h_abs < min_step:
            h_abs = min_step
        accepted = False
        rejected = False
        h = 0.0
        t_new = t
        while not accepted:
            if h_abs < min_step:
                return STATUS_STEP_UNDERFLOW, limiting, n_evals, n_steps, n_rejected, i_out, t
            if n_steps + n_rejected >= max_steps:
                return STATUS_MAX_STEPS, limiting, n_evals, n_steps, n_rejected, i_out, t
            t_new = t + h_abs
            if t_new - t_bound > 0.0:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)

            for i in range(N):
                K[0, i] = f[i]
            # Stages 1 … n_stages - 1, then y_new (row n_stages of A is B) and f(y_new).
            for s in range(1, n_stages + 1):
                target = y_new if s == n_stages else ytmp
                combine(y, K, A, s, h, target)
                bad = rhs_inline(target, p, c, kind, K[s])
                if bad != 0:
                    return (
                        STATUS_SINGULAR_MASS, bad - 1, n_evals + s, n_steps, n_rejected, i_out,
                        t + h * (D8_C[s] if dop853 else RK45_C[min(s, 5)]),
                    )  # fmt: skip
            n_evals += n_stages

            for i in range(N):
                scale[i] = atol[i] + max(abs(y[i]), abs(y_new[i])) * rtol
            if dop853:
                for i in range(N):
                    err[i] = 0.0
                    err3[i] = 0.0
                for j in range(n_stages + 1):
                    e5j = D8_E5[j]
                    e3j = D8_E3[j]
                    for i in range(N):
                        err[i] += K[j, i] * e5j
                        err3[i] += K[j, i] * e3j
                e5 = 0.0
                e3 = 0.0
                for i in range(N):
                    a5 = err[i] / scale[i]
                    a3 = err3[i] / scale[i]
                    err[i] = a5
                    e5 += a5 * a5
                    e3 += a3 * a3
                if e5 == 0.0 and e3 == 0.0:
                    error_norm = 0.0
                else:
                    error_norm = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * N)
            else:
                for i in range(N):
                    err[i] = 0.0
                for j in range(n_stages + 1):
                    ej = RK45_E[j]
                    for i in range(N):
                        err[i] += K[j, i] * ej
                e = 0.0
                for i in range(N):
                    a = err[i] * h / scale[i]
                    err[i] = a
                    e += a * a
                error_norm = math.sqrt(e / N)
            k = first_nonfinite(y_new)
            if k < 0:
                k = first_nonfinite(K[n_stages])
            if k >= 0 or not math.isfinite(error_norm):
                # Overflow or nan: a smaller step may help; SciPy shrinks by MIN_FACTOR too.
                if k < 0:
                    for s in range(n_stages):
                        k = first_nonfinite(K[s])
                        if k >= 0:
                            break
                limiting = max(k, 0)
                h_abs *= MIN_FACTOR
                rejected = True
                n_rejected += 1
                continue
            worst = 0.0
            for i in range(N):
                if abs(err[i]) > worst:
                    worst = abs(err[i])
                    limiting = i
            if error_norm < 1.0:
                if error_norm == 0.0:
                    factor = MAX_FACTOR
                else:
                    factor = min(MAX_FACTOR, SAFETY * error_norm**exponent)
                if rejected:
                    factor = min(1.0, factor)
                h_abs *= factor
                accepted = True
            else:
                h_abs *= max(MIN_FACTOR, SAFETY * error_norm**exponent)
                rejected = True
                n_rejected += 1
        n_steps += 1

        # Dense output at the t_eval points of (t, t_new] (t_eval[0] in the first step).
        if i_out < n_out and t_eval[i_out] <= t_new:
            if dop853:
                for s in range(n_stages + 1, 16):
                    combine(y, K, D8_A, s, h, ytmp)
                    bad = rhs_inline(ytmp, p, c, kind, K[s])
                    if bad != 0:
                        return (
                            STATUS_SINGULAR_MASS, bad - 1, n_evals, n_steps, n_rejected, i_out,
                            t + D8_C[s] * h,
                        )  # fmt: skip
                n_evals += 16 - (n_stages + 1)
                for i in range(N):
                    dy = y_new[i] - y[i]
                    F[0, i] = dy
                    F[1, i] = h * K[0, i] - dy
                    F[2, i] = 2.0 * dy - h * (K[n_stages, i] + K[0, i])
                for r in range(4):
                    for i in range(N):
                        F[3 + r, i] = 0.0
                    for j in range(16):
                        drj = D8_D[r, j]
                        if drj != 0.0:
                            for i in range(N):
                                F[3 + r, i] += drj * K[j, i]
                    for i in range(N):
                        F[3 + r, i] *= h
            else:
                for r in range(4):
                    for i in range(N):
                        F[r, i] = 0.0
                    for j in range(n_stages + 1):
                        pjr = RK45_P[j, r]
                        if pjr != 0.0:
                            for i in range(N):
                                F[r, i] += K[j, i] * pjr
            end = samples_until(t_eval, i_out, t_new)
            if dop853:
                dense_dop853(F, y, t_eval, t, h, i_out, end, out_y)
            else:
                dense_rk45(F, y, t_eval, t, h, i_out, end, out_y)
            i_out = end

        t = t_new
        for i in range(N):
            y[i] = y_new[i]
            f[i] = K[n_stages, i]
        if t - t_bound >= 0.0:
            return STATUS_OK, -1, n_evals, n_steps, n_rejected, i_out, t


@jit(_RESULT(int64, _rvec, _rvec, float64, int64, _rvec, int64, _rvec, _mat))
def fixed(method, y0, t_eval, dt, max_steps, p_arr, kind, c_arr, out_y):
    """Symplectic Euler (10), RK4 (11) or velocity Verlet (12); see ``integrate``.

    The same formulas as :mod:`rrt_pin.simulate.integrators`:

    * symplectic (semi-implicit) Euler: q̇₁ = q̇₀ + h·a(q₀, q̇₀); q₁ = q₀ + h·q̇₁;
    * classic RK4 on (q, q̇);
    * velocity Verlet: q̇½ = q̇₀ + h/2·a₀; q₁ = q₀ + h·q̇½; q̇₁ = q̇½ + h/2·a(q₁, q̇₁),
      the implicit half kick solved by fixed-point iteration (relative change
      <= VERLET_TOL, at most VERLET_MAX_ITER evaluations); its last evaluation
      is reused as the next step's a₀.
    """
    p = as_tuple_p(p_arr)
    c = as_tuple_c(c_arr)
    n_out = t_eval.shape[0]
    y = y0.copy()
    k = np.empty((4, N))
    ytmp = np.empty(N)
    acc = np.empty(N)
    n_evals = 0
    n_steps = 0
    have_a = False
    for i in range(N):
        out_y[0, i] = y[i]
    for n in range(1, n_out):
        ta = t_eval[n - 1]
        span = t_eval[n] - ta
        m = 1
        if dt > 0.0:
            m = max(1, int(math.ceil(span / dt * (1.0 - 1e-12))))
        h = span / m
        for sub in range(m):
            t = ta + sub * h
            if n_steps >= max_steps:
                return STATUS_MAX_STEPS, 0, n_evals, n_steps, 0, n, t
            if method == METHOD_RK4:
                for s in range(4):
                    if s == 0:
                        for i in range(N):
                            ytmp[i] = y[i]
                    else:
                        ch = RK4_C[s] * h
                        for i in range(N):
                            ytmp[i] = y[i] + ch * k[s - 1, i]
                    bad = rhs(ytmp, p, c, kind, k[s])
                    n_evals += 1
                    if bad != 0:
                        return STATUS_SINGULAR_MASS, bad - 1, n_evals, n_steps, 0, n, t
                for i in range(N):
                    y[i] += h / 6.0 * (k[0, i] + 2.0 * k[1, i] + 2.0 * k[2, i] + k[3, i])
            elif method == METHOD_SYMPLECTIC_EULER:
                bad = rhs(y, p, c, kind, acc)
                n_evals += 1
                if bad != 0:
                    return STATUS_SINGULAR_MASS, bad - 1, n_evals, n_steps, 0, n, t
                for i in range(3):
                    y[3 + i] += h * acc[3 + i]
                    y[i] += h * y[3 + i]
            else:
                # acc[3:] holds a₀; ytmp = (q₁, q̇₁ iterate); y[3:] becomes q̇½.
                for it in range(VERLET_MAX_ITER + 1):
                    if it == 0 and have_a:
                        for i in range(3):
                            y[3 + i] += 0.5 * h * acc[3 + i]
                            ytmp[i] = y[i] + h * y[3 + i]
                            ytmp[3 + i] = y[3 + i]
                        continue
                    bad = rhs(ytmp if it > 0 else y, p, c, kind, acc)
                    n_evals += 1
                    if bad != 0:
                        return STATUS_SINGULAR_MASS, bad - 1, n_evals, n_steps, 0, n, t + h
                    if it == 0:
                        for i in range(3):
                            y[3 + i] += 0.5 * h * acc[3 + i]
                            ytmp[i] = y[i] + h * y[3 + i]
                            ytmp[3 + i] = y[3 + i]
                        have_a = True
                        continue
                    change = 0.0
                    vmax = 0.0
                    for i in range(3):
                        v_new = y[3 + i] + 0.5 * h * acc[3 + i]
                        change = max(change, abs(v_new - ytmp[3 + i]))
                        ytmp[3 + i] = v_new
                        vmax = max(vmax, abs(v_new))
                    if change <= VERLET_TOL * (1.0 + vmax):
                        break
                    if not math.isfinite(change) or it == VERLET_MAX_ITER:
                        worst = 0
                        for i in range(3):
                            if not abs(ytmp[3 + i] - y[3 + i]) <= abs(
                                ytmp[3 + worst] - y[3 + worst]
                            ):
                                worst = i
                        return STATUS_NO_CONVERGENCE, 3 + worst, n_evals, n_steps, 0, n, t + h
                for i in range(N):
                    y[i] = ytmp[i]
            n_steps += 1
            bad_k = first_nonfinite(y)
            if bad_k >= 0:
                return STATUS_NONFINITE, bad_k, n_evals, n_steps, 0, n, t + h
        for i in range(N):
            out_y[n, i] = y[i]
    return STATUS_OK, -1, n_evals, n_steps, 0, n_out, t_eval[n_out - 1]


@jit(None, inline=True)
def _with_efforts(r, t_eval, kind, cvec, p, out_y, out_tau):
    """``r`` after the efforts at its n_out rows: STATUS_EFFORT_NONFINITE if one is not finite."""
    bad = fill_efforts(kind, cvec, p, out_y, out_tau, r[5])
    if bad < 0 or r[0] != STATUS_OK:
        return r
    row = bad // 3
    when = t_eval[row] if out_y.shape[0] == t_eval.shape[0] else t_eval[t_eval.shape[0] - 1]
    return STATUS_EFFORT_NONFINITE, bad, r[2], r[3], r[4], r[5], when


@jit(
    _RESULT(
        int64,
        _rvec,
        _rvec,
        float64,
        _rvec,
        float64,
        float64,
        int64,
        _rvec,
        int64,
        _rvec,
        _mat,
        _mat,
    )
)
def integrate(
    method, y0, t_eval, dt, atol, rtol, max_step, max_steps, p, kind, cvec, out_y, out_tau
):
    """Integrate one run from (t_eval[0], y0) and fill out_y (N, 6) and out_tau (N, 3).

    Args:
        method: a ``METHOD_*`` code of :mod:`rrt_pin.simulate.codes`.
        y0: initial state (6,).
        t_eval: strictly increasing output times (N,) [s]; the run starts at t_eval[0].
        dt: fixed-step methods' largest step [s] (<= 0: one step per interval).
        atol: absolute tolerances (6,) (adaptive methods).
        rtol: relative tolerance (adaptive methods).
        max_step: largest step of the adaptive methods [s].
        max_steps: step budget (accepted plus rejected steps).
        p: physical parameters (15,).
        kind: controller kind.
        cvec: controller parameters.
        out_y: output states (N, 6).
        out_tau: output efforts (N, 3).

    Returns:
        (status, coordinate, n_evals, n_steps, n_rejected, n_out, t): ``t`` is the
        time reached, or the failure time when the status is not STATUS_OK [s]; n_out the number
        of output rows filled.
    """
    if method < FIXED_STEP_FROM:
        r = adaptive(method, y0, t_eval, atol, rtol, max_step, max_steps, p, kind, cvec, out_y)
    else:
        r = fixed(method, y0, t_eval, dt, max_steps, p, kind, cvec, out_y)
    return _with_efforts(r, t_eval, kind, cvec, p, out_y, out_tau)
