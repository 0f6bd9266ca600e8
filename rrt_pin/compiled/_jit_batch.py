"""Machine-code batches: many variants, the adaptive ones side by side in lanes.

A batch's variants are the rows of y0, p, kind and cvec. :func:`integrate_fixed`
runs a fixed-step method over them one after the other (``integrate`` of
:mod:`rrt_pin.compiled._jit_integrators`). :func:`integrate_lanes` runs RK45 or
DOP853: ``adaptive`` integrates one variant at a time, each stage of a step waits
for the one before, and one variant's right-hand side (a sine and a cosine, the
closed-form dynamics, three divisions) is far too short to fill a core. Here up
to ``lanes`` variants advance together, one step attempt each per round: the
stages' combinations, right-hand sides and dense-output coefficients are loops
over the lanes that LLVM vectorizes (several variants per instruction); the
step-size control, the dense output and the end of a variant are per lane. A
lane whose variant ends takes the next one.

Each lane does exactly the operations of ``adaptive`` for its variant, in the
same order: the same steps, statuses and bits (tests/test_compiled_lanes.py
compares them with single runs). The right-hand side is ``accelerations`` of
:mod:`rrt_pin.compiled._jit_dynamics`, the body of ``closed_loop`` itself; a lane
whose q2 is not below ``SINCOS_LIMIT`` is evaluated again by ``closed_loop``
(libm's sine and cosine), as ``sincos`` would.

What is written for variant b (``keep``, a ``KEEP_*`` code):

* KEEP_TRAJECTORIES: out_y[b] (T, 6) and out_tau[b] (T, 3) at every output time;
* KEEP_FINAL: out_y[b, 0] and out_tau[b, 0] at the last output time only. The
  adaptive methods then skip the dense output (and its extra stages) and report
  the last step's end, which the full run's interpolant reproduces to round-off;
  the fixed-step ones fill a scratch run and keep its last row;
* KEEP_METRICS: the same, and out_m[b] (METRIC_WIDTH,): the metrics of the
  variant's samples at every output time (target qf[b], settling band ``band``).

``info[b]`` receives (status, coordinate, n_evals, n_steps, n_rejected, n_out) and
``t_reached[b]`` the time reached [s]. Both functions release the GIL: threads may
run one batch at once, taking its variants from one counter (:func:`_take`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import float64, int64, types
from numba.core import cgutils
from numba.extending import intrinsic

from rrt_pin.compiled._jit import borrow, jit, keep_alive, wide_vectors
from rrt_pin.compiled._jit_dynamics import (
    SINCOS_LIMIT,
    accelerations,
    as_tuple_c,
    as_tuple_p,
    closed_loop,
    inverse_constants,
    vsincos,
)
from rrt_pin.compiled._jit_integrators import (
    D8_C,
    D8_D,
    D8_E3,
    D8_E5,
    DENSE_PAD,
    MAX_FACTOR,
    MIN_FACTOR,
    RK45_C,
    RK45_E,
    RK45_P,
    SAFETY,
    N,
    _with_efforts,
    dense_dop853_rows,
    dense_rk45_rows,
    fill_efforts_rows,
    first_step,
    integrate,
    samples_until,
    tableau,
)
from rrt_pin.compiled._jit_metrics import as_rows, variant_metrics
from rrt_pin.simulate.codes import (
    KEEP_FINAL,
    KEEP_METRICS,
    KEEP_TRAJECTORIES,
    NC,
    STATUS_EFFORT_NONFINITE,
    STATUS_MAX_STEPS,
    STATUS_OK,
    STATUS_SINGULAR_MASS,
    STATUS_STEP_UNDERFLOW,
)

__all__ = ["LANES", "integrate_fixed", "integrate_lanes"]

#: Variants a thread integrates side by side (adaptive methods). 32 fill the vector
#: units several times over and spread each round's fixed costs (a loop's setup and
#: its run-time overlap checks, per stage) over more variants: faster than 16 keeping
#: final states or metrics (whose scratch runs, 9 × T values a lane, then spill from L2
#: to L3); ``scripts/bench/compiled.py --only lanes`` measures each count.
LANES = 32

_vec = float64[::1]
_mat = float64[:, ::1]
_cube = float64[:, :, ::1]
_rvec = types.Array(float64, 1, "C", readonly=True)
_rmat = types.Array(float64, 2, "C", readonly=True)
_rivec = types.Array(int64, 1, "C", readonly=True)
_ivec = int64[::1]


def _item(context, builder, signature, args):
    """A pointer to counter[i] (the arguments of the intrinsics below: counter, i)."""
    array = context.make_array(signature.args[0])(context, builder, args[0])
    return cgutils.get_item_pointer(context, builder, signature.args[0], array, [args[1]])


@intrinsic
def _load(typingctx, counter, i):
    """counter[i], read anew at every call (an atomic load: never kept from a previous one)."""
    sig = int64(counter, i)

    def codegen(context, builder, signature, args):
        return builder.load_atomic(_item(context, builder, signature, args), "acquire", 8)

    return sig, codegen


@intrinsic
def _swap(typingctx, counter, i, old, new):
    """counter[i] = new if it still holds old, atomically; whether it did."""
    sig = types.boolean(counter, i, old, new)

    def codegen(context, builder, signature, args):
        ptr = _item(context, builder, signature, args)
        pair = builder.cmpxchg(ptr, args[2], args[3], "acq_rel", "acquire")
        return builder.extract_value(pair, 1)

    return sig, codegen


@jit(None, inline=True)
def _take(counter, B):
    """The next variant of a shared batch: b < B, or B when all are taken, -1 when none is ready.

    ``counter``: [next variant, variants laid out]. Every thread's call over a batch
    takes its variants from it, one at a time, as its lanes fall free: no slices, no
    thread idle while another still has variants to start (the same bits: each
    variant's run is its own). The caller lays the variants out as the threads run
    and raises counter[1] after each part (or sets counter[0] = B to stop them).
    """
    while True:
        b = _load(counter, 0)
        if b >= B:
            return B
        if b >= _load(counter, 1):
            return -1
        if _swap(counter, 0, b, b + 1):
            return b


# The lanes' arrays are laid out (…, N, L), lanes last, and the loops below run over
# the flat index m = i·L + lane of a (N, L) block: one loop a row of coefficients,
# which LLVM vectorizes once (a loop over lanes inside a loop over the 6 components
# is unrolled into 6 vectorized copies, and compiling them took most of a minute).


@jit(None, inline=True)
def _combine(Yf, Kf, A, s, H, acc, out, M):
    """Write Y + H · Σ_{j<s} A[s, j] K[j] into ``out``, the flat (N·L) block (``combine``'s order)."""
    for m in range(M):
        acc[m] = 0.0
    for j in range(s):
        aj = A[s, j]
        if aj != 0.0:
            for m in range(M):
                acc[m] += aj * Kf[j, m]
    for m in range(M):
        out[m] = Yf[m] + acc[m] * H[m]


@jit(None, inline=True)
def _errors(Yf, Ynf, Kf, H, AT, rtol, dop853, n_stages, E, E3, M):
    """Every lane's error estimate divided by its scale, into E (and E3), ``adaptive``'s order.

    DOP853: E = Σ K·E5 / scale, E3 = Σ K·E3 / scale; RK45: E = Σ K·E · h / scale; the
    scale is atol + max(|y|, |y_new|)·rtol.
    """
    for m in range(M):
        E[m] = 0.0
        E3[m] = 0.0
    if dop853:
        for j in range(n_stages + 1):
            e5j = D8_E5[j]
            e3j = D8_E3[j]
            for m in range(M):
                E[m] += Kf[j, m] * e5j
                E3[m] += Kf[j, m] * e3j
        for m in range(M):
            scale = AT[m] + max(abs(Yf[m]), abs(Ynf[m])) * rtol
            E[m] = E[m] / scale
            E3[m] = E3[m] / scale
    else:
        for j in range(n_stages + 1):
            ej = RK45_E[j]
            for m in range(M):
                E[m] += Kf[j, m] * ej
        for m in range(M):
            scale = AT[m] + max(abs(Yf[m]), abs(Ynf[m])) * rtol
            E[m] = E[m] * H[m] / scale


@jit(None, inline=True)
def _dense_coefficients(Yf, Ynf, Kf, H, dop853, n_stages, FLf, M):
    """Every lane's dense-output coefficients FLf (7, N·L) of its step (``adaptive``'s order).

    DOP853: F0..F2 from the step's ends, F3..F6 from its 16 stages; RK45: the four
    columns of K·P. H holds each lane's step h at every component of the lane.
    """
    if dop853:
        for m in range(M):
            dy = Ynf[m] - Yf[m]
            FLf[0, m] = dy
            FLf[1, m] = H[m] * Kf[0, m] - dy
            FLf[2, m] = 2.0 * dy - H[m] * (Kf[n_stages, m] + Kf[0, m])
        for r in range(4):
            for m in range(M):
                FLf[3 + r, m] = 0.0
            for j in range(n_stages + 4):  # the 16 stages (a run-time count: not unrolled)
                drj = D8_D[r, j]
                if drj != 0.0:
                    for m in range(M):
                        FLf[3 + r, m] += drj * Kf[j, m]
            for m in range(M):
                FLf[3 + r, m] *= H[m]
    else:
        for r in range(4):
            for m in range(M):
                FLf[r, m] = 0.0
            for j in range(n_stages + 1):
                pjr = RK45_P[j, r]
                if pjr != 0.0:
                    for m in range(M):
                        FLf[r, m] += Kf[j, m] * pjr


@jit(None, inline=True)
def _dense_rows(dop853, F, y, t_eval, t, h, start, end, rows, xs):
    """One lane's dense output at t_eval[start:end] into its rows (``dense_*_rows``)."""
    if dop853:
        dense_dop853_rows(F, y, t_eval, t, h, start, end, rows, xs)
    else:
        dense_rk45_rows(F, y, t_eval, t, h, start, end, rows, xs)


@jit(None, inline=True)
def _lane_c(CL, ln):
    """Lane ln's controller parameters as a tuple (read in place: no view, no reference count)."""
    return (
        CL[0, ln], CL[1, ln], CL[2, ln], CL[3, ln], CL[4, ln], CL[5, ln], CL[6, ln], CL[7, ln],
        CL[8, ln], CL[9, ln], CL[10, ln], CL[11, ln], CL[12, ln], CL[13, ln], CL[14, ln], CL[15, ln],
        CL[16, ln], CL[17, ln], CL[18, ln], CL[19, ln], CL[20, ln], CL[21, ln], CL[22, ln], CL[23, ln],
    )  # fmt: skip


@jit(None, inline=True)
def _lane_rhs(X, KC, CL, PL, kinds, K, s, bad, n):
    """ẏ of the states X[:, ln] into K[s, :, ln] and the singular pivot into bad[ln], lanes ln < n.

    The loop over lanes has no call and no branch (it vectorizes); lanes whose q2
    is not below SINCOS_LIMIT are done again by ``closed_loop`` (libm's sine and cosine).
    """
    for ln in range(n):
        q1, q2, q3 = X[0, ln], X[1, ln], X[2, ln]
        qd1, qd2, qd3 = X[3, ln], X[4, ln], X[5, ln]
        s2, c2 = vsincos(q2 if abs(q2) < SINCOS_LIMIT else 0.0)
        k = (KC[0, ln], KC[1, ln], KC[2, ln], KC[3, ln], KC[4, ln], KC[5, ln], KC[6, ln],
             KC[7, ln], KC[8, ln], KC[9, ln])  # fmt: skip
        a1, a2, a3, _, _, _, b = accelerations(
            kinds[ln], _lane_c(CL, ln), k, q1, q2, q3, qd1, qd2, qd3, s2, c2
        )
        K[s, 0, ln] = qd1
        K[s, 1, ln] = qd2
        K[s, 2, ln] = qd3
        K[s, 3, ln] = a1
        K[s, 4, ln] = a2
        K[s, 5, ln] = a3
        bad[ln] = b
    for ln in range(n):
        if not abs(X[1, ln]) < SINCOS_LIMIT:
            pt = (PL[0, ln], PL[1, ln], PL[2, ln], PL[3, ln], PL[4, ln], PL[5, ln], PL[6, ln],
                  PL[7, ln], PL[8, ln], PL[9, ln], PL[10, ln], PL[11, ln], PL[12, ln],
                  PL[13, ln], PL[14, ln])  # fmt: skip
            a1, a2, a3, _, _, _, b = closed_loop(
                kinds[ln], _lane_c(CL, ln), pt, X[0, ln], X[1, ln], X[2, ln], X[3, ln],
                X[4, ln], X[5, ln],
            )  # fmt: skip
            K[s, 3, ln] = a1
            K[s, 4, ln] = a2
            K[s, 5, ln] = a3
            bad[ln] = b


@jit(None, inline=True)
def _record(row, r):
    """row[:] = r[:6]: a run's (status, coordinate, n_evals, n_steps, n_rejected, n_out)."""
    row[0] = r[0]
    row[1] = r[1]
    row[2] = r[2]
    row[3] = r[3]
    row[4] = r[4]
    row[5] = r[5]


@jit(
    types.void(
        int64, int64, types.Tuple((int64, int64, int64, int64, int64, int64, float64)), int64,
        _rvec, _rmat, _rivec, _rmat, _rmat, float64, _cube, _cube, _mat, _cube, int64[:, ::1],
        _vec,
    )
)  # fmt: skip
def _finish(b, ln, r, keep, t_eval, p, kind, cvec, qf, band, out_y, out_tau, out_m, rows, info,
            t_reached):  # fmt: skip
    """Variant b's run ended with ``r``: its efforts, kept values and info.

    Compiled on its own (a variant ends at one of five places). Trajectories
    are copied from the lane's rows; metrics come from its rows (efforts added).
    """
    wide_vectors()
    T = t_eval.shape[0]
    if keep == KEEP_METRICS:
        if r[0] == STATUS_OK:
            bad = fill_efforts_rows(kind[b], cvec[b], p[b], rows[ln], r[5])
            if bad >= 0:
                r = (STATUS_EFFORT_NONFINITE, bad, r[2], r[3], r[4], r[5], t_eval[bad // 3])
        if r[0] == STATUS_OK:
            lr = rows[ln]
            for i in range(N):
                out_y[b, 0, i] = lr[i, T - 1]
            for k in range(3):
                out_tau[b, 0, k] = lr[6 + k, T - 1]
            variant_metrics(t_eval, lr, qf[b], band, out_m[b])
    else:
        if keep == KEEP_TRAJECTORIES:  # the rows the dense output filled, as (T, 6)
            oy = out_y[b]
            lr = rows[ln]
            for m in range(r[5]):
                for i in range(N):
                    oy[m, i] = lr[i, m]
        r = _with_efforts(r, t_eval, kind[b], cvec[b], p[b], out_y[b], out_tau[b])
    _record(info[b], r)
    t_reached[b] = r[6]


@jit(
    types.void(
        int64, _rmat, _rvec, _rvec, float64, float64, int64, _rmat, _rivec, _rmat, int64,
        _rmat, float64, _cube, _cube, _mat, int64[:, ::1], _vec, int64, _ivec,
    )
)  # fmt: skip
def integrate_lanes(
    method, y0, t_eval, atol, rtol, max_step, max_steps, p, kind, cvec, keep, qf, band,
    out_y, out_tau, out_m, info, t_reached, lanes, counter,
):  # fmt: skip
    """RK45 or DOP853 (``method``) over every variant b, up to ``lanes`` at once.

    The arguments are ``adaptive``'s, a row per variant, and the outputs of the
    module's docstring (needs len(t_eval) >= 2). The variants are taken from
    ``counter`` (:func:`_take`; [0, B] for a batch of its own, shared by the
    threads that run one batch together). The dense output goes to a scratch
    run by rows (9, T) a lane (states, then efforts for the metrics); trajectories
    are copied from it when a variant ends.
    """
    wide_vectors()
    B = y0.shape[0]
    if B == 0:
        return
    L = max(1, min(lanes, B))
    T = t_eval.shape[0]
    dense = keep != KEEP_FINAL  # the states at every output time, into rows (6+, T) a lane
    dop853, n_stages, exponent, order, A = tableau(method)
    t_start = t_eval[0]
    t_bound = t_eval[T - 1]
    interval = t_bound - t_start

    # The arguments and the scratch below are used through borrowed views (no reference
    # counting in the loops; see rrt_pin.compiled._jit.borrow): the caller holds the
    # arguments, and keep_alive at the end holds the eight scratch arrays.
    y0, t_eval, atol = borrow(y0), borrow(t_eval), borrow(atol)
    p, kind, cvec = borrow(p), borrow(kind), borrow(cvec)
    qf, out_y, out_tau, out_m = borrow(qf), borrow(out_y), borrow(out_tau), borrow(out_m)
    info, t_reached, counter = borrow(info), borrow(t_reached), borrow(counter)

    # The lanes: variant, time, step and counters of each; states and stages by lane (last axis).
    own_lf = np.zeros((5, L))
    lf = borrow(own_lf)
    t, h, h_abs, t_new, min_step = lf[0], lf[1], lf[2], lf[3], lf[4]
    own_li = np.zeros((10, L), np.int64)
    li = borrow(own_li)
    var, n_evals, n_steps, n_rejected, i_out = li[0], li[1], li[2], li[3], li[4]
    limiting, fail_s, fail_k, bad, kinds = li[5], li[6], li[7], li[8], li[9]
    # fail_s: stage of the first singular mass matrix, or 0; fail_k: its pivot
    var[:] = -1
    own_lb = np.zeros((4, L), np.bool_)
    # fresh: a new step starts (clamp the step size); go: the lane attempts a step this
    # round; need: the lane's accepted step covers output times
    lb = borrow(own_lb)
    rejected, fresh, go, need = lb[0], lb[1], lb[2], lb[3]
    M = N * L  # a flat (N, L) block
    own_flat = np.zeros((5, M))
    # H: h of each lane at each of its components; AT: atol of each component at each
    # lane; E: every lane's scaled error estimate (DOP853: its 5th-order part), E3: the 3rd
    flat = borrow(own_flat)
    acc, H, AT, E, E3 = flat[0], flat[1], flat[2], flat[3], flat[4]
    for m in range(M):
        AT[m] = atol[m // L]
    own_states = np.zeros((3 + 16 + 7, N, L))  # Y, Yn, Yt, the 16 stages K, coefficients FL
    states = borrow(own_states)
    Y, Yn, Yt, K, FL = states[0], states[1], states[2], states[3:19], states[19:26]
    Yf = Y.reshape(M)
    Ynf = Yn.reshape(M)
    Ytf = Yt.reshape(M)
    Kf = K.reshape((16, M))
    FLf = FL.reshape((7, M))  # the dense output's coefficients, by lane
    own_lanes = np.zeros((25 + NC, L))  # each lane's inverse_constants, parameters, controller
    lanes_p = borrow(own_lanes)
    KC, PL, CL = lanes_p[0:10], lanes_p[10:25], lanes_p[25:]
    # rows: a lane's run, (9, T + DENSE_PAD): see dense_dop853_rows; xs: finite from the start
    own_rows = np.empty((L, 9, T + DENSE_PAD if dense else 0))
    rows = borrow(own_rows)
    own_xs = np.zeros(T + DENSE_PAD if dense else 0)
    xs = borrow(own_xs)
    own_small = np.empty((5, N))
    small = borrow(own_small)
    y, f, ytmp, err, scale = small[0], small[1], small[2], small[3], small[4]
    taken = False  # the counter passed B: no variant left to start

    while True:
        # 1. Fill idle lanes with the next variants, then set up each lane's attempt.
        active = 0
        for ln in range(L):
            while True:
                if var[ln] < 0:
                    if taken:
                        break
                    b = _take(counter, B)
                    if b < 0:  # none laid out yet: the lane waits a round
                        break
                    if b >= B:
                        taken = True
                        break
                    # Start variant b: f(t0, y0), then SciPy's select_initial_step.
                    pt = as_tuple_p(p[b])
                    ct = as_tuple_c(cvec[b])
                    kd = kind[b]
                    for i in range(N):
                        y[i] = y0[b, i]
                    status, k, ne, h_first = first_step(
                        y, t_start, pt, ct, kd, atol, rtol, order, interval, max_step, f, ytmp,
                        err, scale,
                    )  # fmt: skip
                    if status != STATUS_OK:  # h_first: the failure time
                        r = (status, k, ne, 0, 0, 0, h_first)
                        _finish(b, ln, r, keep, t_eval, p, kind, cvec, qf, band, out_y, out_tau,
                                out_m, rows, info, t_reached)  # fmt: skip
                        continue
                    var[ln] = b
                    t[ln] = t_start
                    h_abs[ln] = h_first
                    n_evals[ln] = ne
                    n_steps[ln] = 0
                    n_rejected[ln] = 0
                    i_out[ln] = 0
                    limiting[ln] = 0
                    fresh[ln] = True
                    k9 = inverse_constants(
                        pt[0], pt[1], pt[2], pt[3], pt[4], pt[5], pt[6], pt[7], pt[8], pt[9],
                        pt[10], pt[11], pt[12], pt[13], pt[14],
                    )  # fmt: skip
                    for i in range(10):
                        KC[i, ln] = k9[i]
                    for i in range(15):
                        PL[i, ln] = p[b, i]
                    for i in range(NC):
                        CL[i, ln] = cvec[b, i]
                    kinds[ln] = kd
                    for i in range(N):
                        Y[i, ln] = y[i]
                        K[0, i, ln] = f[i]
                # A step attempt of the lane's variant, or its end.
                b = var[ln]
                tl = t[ln]
                if fresh[ln]:
                    min_step[ln] = 10.0 * abs(np.nextafter(tl, np.inf) - tl)
                    if h_abs[ln] > max_step:
                        h_abs[ln] = max_step
                    elif h_abs[ln] < min_step[ln]:
                        h_abs[ln] = min_step[ln]
                    rejected[ln] = False
                    fresh[ln] = False
                status = STATUS_OK
                if h_abs[ln] < min_step[ln]:
                    status = STATUS_STEP_UNDERFLOW
                elif n_steps[ln] + n_rejected[ln] >= max_steps:
                    status = STATUS_MAX_STEPS
                if status != STATUS_OK:
                    r = (status, limiting[ln], n_evals[ln], n_steps[ln], n_rejected[ln],
                         i_out[ln], tl)  # fmt: skip
                    _finish(b, ln, r, keep, t_eval, p, kind, cvec, qf, band, out_y, out_tau,
                            out_m, rows, info, t_reached)  # fmt: skip
                    var[ln] = -1
                    continue
                tn = tl + h_abs[ln]
                if tn - t_bound > 0.0:
                    tn = t_bound
                t_new[ln] = tn
                h[ln] = tn - tl
                for i in range(N):
                    H[i * L + ln] = h[ln]
                h_abs[ln] = abs(h[ln])
                break
            go[ln] = var[ln] >= 0
            active += go[ln]
        if active == 0:
            if taken:
                break
            continue  # the variants left are being laid out: wait for them

        # 2. The stages of every lane's attempt (idle lanes compute on stale values),
        # 3. each lane's error estimate and step-size control (``adaptive``'s, per lane),
        # 4. DOP853's extra stages when an accepted step covers output times: one
        # stage loop for both (each copy of the lanes' loops costs seconds of compilation).
        for ln in range(L):
            fail_s[ln] = 0
        any_dense = False
        for phase in range(2):
            if phase == 0:
                first, last = 1, n_stages
            elif any_dense and dop853:
                first, last = n_stages + 1, 15
            else:
                break
            for s in range(first, last + 1):
                target = Yn if s == n_stages else Yt
                _combine(Yf, Kf, A, s, H, acc, Ynf if s == n_stages else Ytf, M)
                _lane_rhs(target, KC, CL, PL, kinds, K, s, bad, L)
                for ln in range(L):
                    if (go[ln] if phase == 0 else need[ln]) and bad[ln] != 0 and fail_s[ln] == 0:
                        fail_s[ln] = s
                        fail_k[ln] = bad[ln] - 1
            if phase == 1:
                break
            _errors(Yf, Ynf, Kf, H, AT, rtol, dop853, n_stages, E, E3, M)
            for ln in range(L):
                need[ln] = False
                if not go[ln]:
                    continue
                b = var[ln]
                if fail_s[ln] != 0:
                    s = fail_s[ln]
                    r = (
                        STATUS_SINGULAR_MASS, fail_k[ln], n_evals[ln] + s, n_steps[ln], n_rejected[ln],
                        i_out[ln], t[ln] + h[ln] * (D8_C[s] if dop853 else RK45_C[min(s, 5)]),
                    )  # fmt: skip
                    _finish(b, ln, r, keep, t_eval, p, kind, cvec, qf, band, out_y, out_tau, out_m,
                            rows, info, t_reached)  # fmt: skip
                    var[ln] = -1
                    go[ln] = False
                    continue
                n_evals[ln] += n_stages
                if dop853:
                    e5 = 0.0
                    e3 = 0.0
                    for i in range(N):
                        a5 = E[i * L + ln]
                        a3 = E3[i * L + ln]
                        e5 += a5 * a5
                        e3 += a3 * a3
                    if e5 == 0.0 and e3 == 0.0:
                        error_norm = 0.0
                    else:
                        error_norm = abs(h[ln]) * e5 / math.sqrt((e5 + 0.01 * e3) * N)
                else:
                    e = 0.0
                    for i in range(N):
                        a = E[i * L + ln]
                        e += a * a
                    error_norm = math.sqrt(e / N)
                k = -1
                for i in range(N):
                    if not math.isfinite(Yn[i, ln]):
                        k = i
                        break
                if k < 0:
                    for i in range(N):
                        if not math.isfinite(K[n_stages, i, ln]):
                            k = i
                            break
                if k >= 0 or not math.isfinite(error_norm):
                    # Overflow or nan: a smaller step may help; SciPy shrinks by MIN_FACTOR too.
                    if k < 0:
                        for s in range(n_stages):
                            for i in range(N):
                                if not math.isfinite(K[s, i, ln]):
                                    k = i
                                    break
                            if k >= 0:
                                break
                    limiting[ln] = max(k, 0)
                    h_abs[ln] *= MIN_FACTOR
                    rejected[ln] = True
                    n_rejected[ln] += 1
                    go[ln] = False
                    continue
                worst = 0.0
                for i in range(N):
                    if abs(E[i * L + ln]) > worst:
                        worst = abs(E[i * L + ln])
                        limiting[ln] = i
                if error_norm < 1.0:
                    if error_norm == 0.0:
                        factor = MAX_FACTOR
                    else:
                        factor = min(MAX_FACTOR, SAFETY * error_norm**exponent)
                    if rejected[ln]:
                        factor = min(1.0, factor)
                    h_abs[ln] *= factor
                    n_steps[ln] += 1
                    if dense and i_out[ln] < T and t_eval[i_out[ln]] <= t_new[ln]:
                        need[ln] = True
                        any_dense = True
                else:
                    h_abs[ln] *= max(MIN_FACTOR, SAFETY * error_norm**exponent)
                    rejected[ln] = True
                    n_rejected[ln] += 1
                    go[ln] = False  # rejected: the lane tries again next round

        # 5. Dense output and the end of each accepted step.
        if any_dense:
            _dense_coefficients(Yf, Ynf, Kf, H, dop853, n_stages, FLf, M)
        for ln in range(L):
            if not go[ln]:
                continue
            b = var[ln]
            hl = h[ln]
            tl = t[ln]
            if need[ln]:
                if fail_s[ln] != 0:
                    s = fail_s[ln]
                    r = (STATUS_SINGULAR_MASS, fail_k[ln], n_evals[ln], n_steps[ln], n_rejected[ln],
                         i_out[ln], tl + D8_C[s] * hl)  # fmt: skip
                    _finish(b, ln, r, keep, t_eval, p, kind, cvec, qf, band, out_y, out_tau,
                            out_m, rows, info, t_reached)  # fmt: skip
                    var[ln] = -1
                    continue
                if dop853:
                    n_evals[ln] += 16 - (n_stages + 1)
                start = i_out[ln]
                end = samples_until(t_eval, start, t_new[ln])
                _dense_rows(
                    dop853, FL[:, :, ln], Y[:, ln], t_eval, tl, hl, start, end, rows[ln], xs
                )
                i_out[ln] = end
            tl = t_new[ln]
            t[ln] = tl
            for i in range(N):
                Y[i, ln] = Yn[i, ln]
                K[0, i, ln] = K[n_stages, i, ln]
            fresh[ln] = True
            if tl - t_bound >= 0.0:
                if not dense:
                    for i in range(N):
                        out_y[b, 0, i] = Y[i, ln]
                    i_out[ln] = 1
                r = (STATUS_OK, -1, n_evals[ln], n_steps[ln], n_rejected[ln], i_out[ln], tl)
                _finish(b, ln, r, keep, t_eval, p, kind, cvec, qf, band, out_y, out_tau, out_m,
                        rows, info, t_reached)  # fmt: skip
                var[ln] = -1
    keep_alive(
        (own_lf, own_li, own_lb, own_flat, own_states, own_lanes, own_rows, own_xs, own_small)
    )


@jit(
    types.void(
        int64, _rmat, _rvec, float64, int64, _rmat, _rivec, _rmat, int64, _rmat, float64,
        _cube, _cube, _mat, int64[:, ::1], _vec, _ivec,
    )
)  # fmt: skip
def integrate_fixed(
    method, y0, t_eval, dt, max_steps, p, kind, cvec, keep, qf, band, out_y, out_tau, out_m,
    info, t_reached, counter,
):  # fmt: skip
    """A fixed-step method over the variants b taken from ``counter`` (see :func:`_take`), in turn.

    The outputs of ``integrate_lanes``.

    KEEP_FINAL and KEEP_METRICS fill a scratch run (T, 6) and keep its last row (and,
    for metrics, the metrics of its samples).
    """
    T = t_eval.shape[0]
    scratch = 0 if keep == KEEP_TRAJECTORIES else T
    sy = np.empty((scratch, N))
    st = np.empty((scratch, 3))
    rows = np.empty((9, T if keep == KEEP_METRICS else 0))  # the run by rows, for its metrics
    atol = np.zeros(N)
    B = y0.shape[0]
    while True:
        b = _take(counter, B)
        if b >= B:
            break
        if b < 0:  # being laid out: wait
            continue
        r = integrate(
            method, y0[b], t_eval, dt, atol, 0.0, math.inf, max_steps, p[b], kind[b], cvec[b],
            out_y[b] if keep == KEEP_TRAJECTORIES else sy,
            out_tau[b] if keep == KEEP_TRAJECTORIES else st,
        )  # fmt: skip
        if keep != KEEP_TRAJECTORIES and r[0] == STATUS_OK:
            for i in range(N):
                out_y[b, 0, i] = sy[T - 1, i]
            for k in range(3):
                out_tau[b, 0, k] = st[T - 1, k]
            if keep == KEEP_METRICS:
                as_rows(sy, st, rows, T)
                variant_metrics(t_eval, rows, qf[b], band, out_m[b])
        _record(info[b], r)
        t_reached[b] = r[6]
