"""The lanes of any robot's batches: adaptive variants side by side, one vector lane each.

Appended by :mod:`rrt_pin.compiled.robot_code` to the module it makes from
:mod:`rrt_pin.compiled._robot_template` (from the line ``# --- lanes ---`` on), with
``free_lanes``: the generated forward dynamics without gravity of ``L`` states at once
under efforts given in rows, inside one loop over the lanes (no call, no branch: the
polynomial sine and cosine of :mod:`rrt_pin.compiled.rnea_vector`), which LLVM runs
several lanes an instruction, and ``gravity_lanes``. Every evaluation of a batch, its
first steps too, goes through these: a batch's first use compiles one copy of the
forward dynamics (and the scalar G(q) of the metrics), not the single run's.

``run_lanes`` integrates a batch's variants with RK45 or DOP853 as ``run_many`` does
(SciPy's steps, error norms, step-size control and dense output, each variant with its
own step size): every lane attempts a step at once; each accepts or rejects its own;
a lane whose variant ends takes the next. A lane's arithmetic never depends on the
other lanes, so the results do not depend on the lane count, the threads or the chunks.
"""

import math

import numpy as np


def jit(f):  # the module's header defines numba's
    return f


jit_inline = jit  # and this one (numba's, inline="always")


def phys_sincos(w):  # generated: the sines and cosines of the physical kernels' work array
    raise NotImplementedError


def gravity_lanes(w):  # generated: G(q) of LANE_COUNT states, in place in w
    raise NotImplementedError


def free_lanes(w):  # generated: ẏ without gravity of LANE_COUNT states, efforts in rows n…
    raise NotImplementedError


LANE_COUNT = PHYS_ROWS = GRAVITY_LANES_OUT = FREE_LANES_OUT = 0
metrics_of_pd = samples_until = clip = losses = free_lanes
SAFETY = MIN_FACTOR = MAX_FACTOR = FRICTION_VELOCITY = 0.0
D8_NS = D8_A = D8_C = D8_E3 = D8_E5 = D8_D = RK45_AB = RK45_C = RK45_E = RK45_P = None
LAW_PD_GRAVITY = METHOD_DOP853 = KEEP_FINAL = KEEP_METRICS = KEEP_TRAJECTORIES = 0
STATUS_OK = STATUS_STEP_UNDERFLOW = STATUS_MAX_STEPS = STATUS_EFFORT_NONFINITE = 0
STATUS_NONFINITE = 0
METHOD_DOP853_RKC = N_STIFF = RKC_MAX_STAGES = RKC_RHO_EVERY = 0
STIFF_H_RHO = D8_STABLE_H_RHO = HAND_BACK = 0.0
rkc_stages = rkc_coefficients = free_lanes  # _robot_rkc.py's
# --- lanes ---


if LANE_COUNT not in (0, 8):  # pragma: no cover - the loops below are written for 8 lanes
    raise RuntimeError(f"the lanes are written for 8, not {LANE_COUNT}")


@jit_inline
def combine_lanes(Y, K, A, s, h, w):
    """w[i·L + l] = Y[i, l] + (Σ_{j<s} A[s, j] K[j, i, l]) · h[l] for every lane (combine's order).

    The 8 lanes' sums are 8 locals (in registers: no store and reload a term).
    """
    for i in range(Y.shape[0]):
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
        for j in range(s):
            aj = A[s, j]
            if aj != 0.0:
                k = K[j, i]
                a0 += aj * k[0]
                a1 += aj * k[1]
                a2 += aj * k[2]
                a3 += aj * k[3]
                a4 += aj * k[4]
                a5 += aj * k[5]
                a6 += aj * k[6]
                a7 += aj * k[7]
        y = Y[i]
        r = i * 8
        w[r] = y[0] + a0 * h[0]
        w[r + 1] = y[1] + a1 * h[1]
        w[r + 2] = y[2] + a2 * h[2]
        w[r + 3] = y[3] + a3 * h[3]
        w[r + 4] = y[4] + a4 * h[4]
        w[r + 5] = y[5] + a5 * h[5]
        w[r + 6] = y[6] + a6 * h[6]
        w[r + 7] = y[7] + a7 * h[7]


@jit
def error_lanes(dop853, n_stages, K, Y, Ynew, h, atol, rtol, ERR, e5s, e3s, acc3):
    """Each lane's scaled error components (ERR) and sums of squares (e5s, e3s), side by side.

    The operations, in order, of ``adaptive``'s error norm for one run: a lane's bits
    are a single run's. ``acc3`` (LANE_COUNT,): scratch.
    """
    n = Y.shape[0]
    L = LANE_COUNT
    E = D8_E5 if dop853 else RK45_E
    for lane in range(L):
        e5s[lane] = 0.0
        e3s[lane] = 0.0
    for i in range(n):
        a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
        b0 = b1 = b2 = b3 = b4 = b5 = b6 = b7 = 0.0
        for j in range(n_stages + 1):
            k = K[j, i]
            ej = E[j]
            a0 += k[0] * ej
            a1 += k[1] * ej
            a2 += k[2] * ej
            a3 += k[3] * ej
            a4 += k[4] * ej
            a5 += k[5] * ej
            a6 += k[6] * ej
            a7 += k[7] * ej
            if dop853:
                ej = D8_E3[j]
                b0 += k[0] * ej
                b1 += k[1] * ej
                b2 += k[2] * ej
                b3 += k[3] * ej
                b4 += k[4] * ej
                b5 += k[5] * ej
                b6 += k[6] * ej
                b7 += k[7] * ej
        e = ERR[i]
        e[0], e[1], e[2], e[3], e[4], e[5], e[6], e[7] = a0, a1, a2, a3, a4, a5, a6, a7
        ai = atol[i]
        y, yn = Y[i], Ynew[i]
        if dop853:
            acc3[0], acc3[1], acc3[2], acc3[3] = b0, b1, b2, b3
            acc3[4], acc3[5], acc3[6], acc3[7] = b4, b5, b6, b7
            for lane in range(L):
                sc = ai + max(abs(y[lane]), abs(yn[lane])) * rtol
                a5 = e[lane] / sc
                a3 = acc3[lane] / sc
                e3s[lane] += a3 * a3
                e[lane] = a5
                e5s[lane] += a5 * a5
        else:
            for lane in range(L):
                sc = ai + max(abs(y[lane]), abs(yn[lane])) * rtol
                a5 = e[lane] * h[lane] / sc
                e[lane] = a5
                e5s[lane] += a5 * a5


@jit
def dense_lanes(dop853, n_stages, K, Y, Ynew, h, F):
    """Every lane's dense-output coefficients F (7, n, L) of its last step (SciPy's)."""
    n = Y.shape[0]
    L = LANE_COUNT
    if dop853:
        for i in range(n):
            for lane in range(L):
                dy = Ynew[i, lane] - Y[i, lane]
                F[0, i, lane] = dy
                F[1, i, lane] = h[lane] * K[0, i, lane] - dy
                F[2, i, lane] = 2.0 * dy - h[lane] * (K[n_stages, i, lane] + K[0, i, lane])
    rows = 4
    for r in range(rows):
        for i in range(n):
            a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
            for j in range(16 if dop853 else n_stages + 1):
                c = D8_D[r, j] if dop853 else RK45_P[j, r]
                if c != 0.0:
                    k = K[j, i]
                    if dop853:  # drj · K (SciPy's order), else K · p
                        a0 += c * k[0]
                        a1 += c * k[1]
                        a2 += c * k[2]
                        a3 += c * k[3]
                        a4 += c * k[4]
                        a5 += c * k[5]
                        a6 += c * k[6]
                        a7 += c * k[7]
                    else:
                        a0 += k[0] * c
                        a1 += k[1] * c
                        a2 += k[2] * c
                        a3 += k[3] * c
                        a4 += k[4] * c
                        a5 += k[5] * c
                        a6 += k[6] * c
                        a7 += k[7] * c
            if dop853:
                f = F[3 + r, i]
                f[0], f[1], f[2], f[3] = a0 * h[0], a1 * h[1], a2 * h[2], a3 * h[3]
                f[4], f[5], f[6], f[7] = a4 * h[4], a5 * h[5], a6 * h[6], a7 * h[7]
            else:
                f = F[r, i]
                f[0], f[1], f[2], f[3], f[4], f[5], f[6], f[7] = a0, a1, a2, a3, a4, a5, a6, a7


@jit
def stage_lanes(phys, Y, K, A, s, h, wf, CL, P, fold, okay):
    """Stage s of every lane: its state into the work rows, ẏ into K[s]; the state's rows.

    ``free_lanes``, the forward dynamics without gravity, under the PD efforts (the law's
    G(q) and the robot's cancel); with a physical model (phys[0] != 0) G(q) by
    ``gravity_lanes``, the PD-plus-G efforts saturated at the effort limits, less G,
    plus damping, friction and the compliant position limits (``passive``'s terms).
    With s = 0 (and any h), ẏ at the states Y into K[0]. ``wf``: the kernels' work
    array (rows of L values: the states from row 0, the efforts from row n, G(q) from
    GRAVITY_LANES_OUT, ẏ from FREE_LANES_OUT); ``fold`` (LANE_COUNT,) booleans and
    ``okay`` (LANE_COUNT,) integers: scratch.
    """
    n = Y.shape[0]
    L = LANE_COUNT
    Ks = K[s]
    combine_lanes(Y, K, A, s, h, wf)
    eval_lanes(phys, n, wf, CL, P, fold, okay)
    out = FREE_LANES_OUT * L
    for i in range(n):
        for lane in range(L):
            Ks[i, lane] = wf[out + i * L + lane]


@jit_inline
def eval_lanes(phys, n, wf, CL, P, fold, okay):
    """ẏ of the states in wf's rows 0 … n − 1 into its rows from FREE_LANES_OUT (stage_lanes's)."""
    nv = n // 2
    L = LANE_COUNT
    phys_sincos(wf)  # once for G and the forward dynamics
    # The PD efforts go into rows n… first (the forward dynamics' efforts, completed below).
    if phys[0] == 0:
        for k in range(nv):
            for lane in range(L):
                q = wf[k * L + lane]
                wf[(n + k) * L + lane] = -CL[nv + k, lane] * wf[(nv + k) * L + lane] - CL[
                    k, lane
                ] * (q - CL[2 * nv + k, lane])
    else:
        physical_efforts(nv, wf, CL, P, fold, okay)
    free_lanes(wf)


@jit
def physical_efforts(nv, wf, CL, P, fold, okay):
    """The efforts of stage_lanes under the physical model, into wf's rows n… (see there)."""
    n = 2 * nv
    g0 = GRAVITY_LANES_OUT * LANE_COUNT
    L = LANE_COUNT
    # A lane is folded where no joint's PD effort exceeds its room (P[11]: the effort limit
    # less a bound of |G|) and no joint is past a limit: clip(PD + G) − G is PD there, to
    # rounding, and G(q) is computed only if some lane is not (each lane's numbers depend
    # on its own state alone, not on its neighbours).
    for lane in range(L):
        okay[lane] = 0
    for k in range(nv):
        room, lo, hi = P[11, k], P[0, k], P[1, k]
        for lane in range(L):
            q = wf[k * L + lane]
            pd = -CL[nv + k, lane] * wf[(nv + k) * L + lane] - CL[k, lane] * (
                q - CL[2 * nv + k, lane]
            )
            wf[(n + k) * L + lane] = pd
            okay[lane] += (abs(pd) <= room) & (lo <= q) & (q <= hi)
    folded = 0
    for lane in range(L):
        fold[lane] = okay[lane] == nv
        folded += fold[lane]
    if folded == L:  # within the limits: no limit's push, t = pd (the general case's bits)
        for k in range(nv):
            d, fr = P[3, k], P[4, k]
            if fr != 0.0:
                for lane in range(L):
                    v = wf[(nv + k) * L + lane]
                    wf[(n + k) * L + lane] += -d * v - fr * math.tanh(v / FRICTION_VELOCITY)
            else:
                for lane in range(L):
                    wf[(n + k) * L + lane] += -d * wf[(nv + k) * L + lane]
        return
    gravity_lanes(wf)
    for k in range(nv):
        lo, hi, e, d, fr, kk, bb = P[0, k], P[1, k], P[2, k], P[3, k], P[4, k], P[5, k], P[6, k]
        if fr != 0.0:
            for lane in range(L):
                q = wf[k * L + lane]
                v = wf[(nv + k) * L + lane]
                pd = wf[(n + k) * L + lane]
                if fold[lane]:
                    t = pd
                else:
                    g = wf[g0 + k * L + lane]
                    t = clip(pd + g, e) - g
                wf[(n + k) * L + lane] = t + losses(q, v, lo, hi, d, fr, kk, bb)
            continue
        # no friction: ``losses`` and ``clip`` without a call or a jump, lane by lane alike
        for lane in range(L):
            q = wf[k * L + lane]
            v = wf[(nv + k) * L + lane]
            pd = wf[(n + k) * L + lane]
            g = wf[g0 + k * L + lane]
            u = pd + g
            u = e if u > e else (-e if u < -e else u)
            t = pd if fold[lane] else u - g
            f = -d * v
            below = max(0.0, kk * (lo - q) - bb * v)
            above = min(0.0, kk * (hi - q) - bb * v)
            f = f + below if q < lo else (f + above if q > hi else f)
            wf[(n + k) * L + lane] = t + f


@jit
def first_steps(phys, Y, start, F0, F1, Ytmp, hz, atol, rtol, order, interval, max_step,
                work, out):  # fmt: skip
    """SciPy's ``select_initial_step`` of the lanes whose ``start`` >= 0, side by side.

    Y (n, L): the lanes' states (those starting: their initial states); ẏ there into F0
    (1, n, L), then at Y + h0·ẏ into F1; ``work`` stage_lanes's arrays after its h.
    Returns nothing; ``out`` (4, L) per lane: status, coordinate, evaluations, and the
    step (or the time of the failure) [s], as ``first_step``'s.
    """
    n = Y.shape[0]
    L = LANE_COUNT
    wf, CL, P, fold, okay = work
    s0 = start.shape[0] - L  # 0, not a literal: stage_lanes is compiled once
    stage_lanes(phys, Y, F0, D8_A, s0, hz, wf, CL, P, fold, okay)
    for lane in range(L):
        for i in range(n):
            Ytmp[i, lane] = Y[i, lane]
        if start[lane] < 0:
            continue
        out[0, lane] = STATUS_OK
        k = -1
        for i in range(n):
            if not math.isfinite(F0[0, i, lane]):
                k = i
                break
        if k >= 0:
            out[0, lane], out[1, lane], out[2, lane], out[3, lane] = STATUS_NONFINITE, k, 1, 0.0
            continue
        d0 = 0.0
        d1 = 0.0
        for i in range(n):
            sc = atol[i] + abs(Y[i, lane]) * rtol
            x = Y[i, lane] / sc
            d0 += x * x
            x = F0[0, i, lane] / sc
            d1 += x * x
        d0 = math.sqrt(d0 / n)
        d1 = math.sqrt(d1 / n)
        if d0 < 1e-5 or d1 < 1e-5:
            h0 = 1e-6
        else:
            h0 = 0.01 * d0 / d1
        h0 = min(h0, interval)
        for i in range(n):
            Ytmp[i, lane] = Y[i, lane] + h0 * F0[0, i, lane]
        out[1, lane] = d1
        out[3, lane] = h0
    stage_lanes(phys, Ytmp, F1, D8_A, s0, hz, wf, CL, P, fold, okay)
    for lane in range(L):
        if start[lane] < 0 or out[0, lane] != STATUS_OK:
            continue
        d1, h0 = out[1, lane], out[3, lane]
        k = -1
        for i in range(n):
            if not math.isfinite(F1[0, i, lane]):
                k = i
                break
        if k >= 0:
            out[0, lane], out[1, lane], out[2, lane], out[3, lane] = STATUS_NONFINITE, k, 2, h0
            continue
        d2 = 0.0
        for i in range(n):
            x = (F1[0, i, lane] - F0[0, i, lane]) / (atol[i] + abs(Y[i, lane]) * rtol)
            d2 += x * x
        d2 = math.sqrt(d2 / n) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
        out[1, lane], out[2, lane], out[3, lane] = -1, 2, min(100.0 * h0, h1, interval, max_step)


#: The rows of the lanes' RKC state (``ri``: integers, ``rf``: floats), one column a lane.
RI_PC, RI_J, RI_S, RI_SINCE, RI_IT, RI_LIMIT, RI_PENDING, RI_BACK = range(8)
RI_ROWS = 8
RF_H, RF_TNEW, RF_RHO, RF_RAW, RF_DZ, RF_W0, RF_W1 = range(7)
RF_ROWS = 7
#: What a lane in RKC's tail does next: decide its step, estimate ρ, a stage, ẏ at the
#: step's end, or nothing until the next round (done, failed, or handed back).
PC_DECIDE, PC_RHO, PC_STAGE, PC_END, PC_IDLE = 0, 1, 2, 3, 4


@jit_inline
def rkc_prepare(lane_b, mode, finished, ri, rf, Y, K, V, Z, Yold, Yolder, cheb, t, h_abs,
                attempts, evals, info, t_reached, t_eval, max_step, max_steps, wf, asks):  # fmt: skip
    """Each lane in RKC's tail (mode 1): the state it needs ẏ at, into wf's rows 0 … n − 1.

    ``rkc_tail``'s decisions, in its order, where a lane is at a step's start: a
    non-finite error's check (after its new ρ), the hand-back test of the step just
    accepted (after its new ρ, if due), ρ not finite (hand back), the step budget, the
    smallest step; then the step's stages and first state (``rkc_step``'s arithmetic:
    Yolder the stage before, Yold the last). A lane that hands back waits for the next
    round (mode 2); one that fails is recorded and let go. ``asks`` (L,): 1 where the
    lane wants ẏ. Returns whether some lane does.
    """
    n = Y.shape[0]
    L = LANE_COUNT
    T = t_eval.shape[0]
    t_bound = t_eval[T - 1]
    wanted = False
    for lane in range(L):
        asks[lane] = 0
        b = lane_b[lane]
        if b < 0 or mode[lane] != 1 or finished[lane] or ri[RI_PC, lane] == PC_IDLE:
            continue
        if ri[RI_PC, lane] == PC_DECIDE:
            tl = t[lane]
            min_step = 10.0 * abs(np.nextafter(tl, np.inf) - tl)
            status = STATUS_OK
            coordinate = 0
            if ri[RI_PENDING, lane] != 0:
                ri[RI_PENDING, lane] = 0
                if not h_abs[lane] >= min_step:
                    status, coordinate = STATUS_NONFINITE, ri[RI_LIMIT, lane]
            rho = rf[RF_RHO, lane]
            if status == STATUS_OK and ri[RI_BACK, lane] != 0:
                ri[RI_BACK, lane] = 0
                h_stable = D8_STABLE_H_RHO / rho
                s_next, h_next = rkc_stages(min(h_abs[lane], max_step), rho)
                if (s_next + 1) * h_stable > HAND_BACK * 12.0 * h_next:
                    h_abs[lane] = min(h_abs[lane], h_stable)
                    mode[lane] = 2
                    ri[RI_PC, lane] = PC_IDLE
                    continue
            if status == STATUS_OK:
                if not math.isfinite(rho):
                    mode[lane] = 2
                    ri[RI_PC, lane] = PC_IDLE
                    continue
                if attempts[lane] >= max_steps:
                    status = STATUS_MAX_STEPS
                elif min(h_abs[lane], max_step) < min_step:
                    status = STATUS_STEP_UNDERFLOW
            if status != STATUS_OK:
                info[b, 0] = status
                info[b, 1] = coordinate
                info[b, 2] = evals[lane]
                t_reached[b] = tl
                lane_b[lane] = -1
                ri[RI_PC, lane] = PC_IDLE
                continue
            s, h = rkc_stages(min(h_abs[lane], max_step), rho)
            t_new = tl + h
            if t_new - t_bound > 0.0:
                t_new = t_bound
            h = t_new - tl
            rf[RF_H, lane] = h
            rf[RF_TNEW, lane] = t_new
            ri[RI_S, lane] = s
            # rkc_step's coefficients and first stage (the lane's own)
            w0, w1 = rkc_coefficients(s, cheb[lane])
            rf[RF_W0, lane] = w0
            rf[RF_W1, lane] = w1
            mu1 = cheb[lane, 3, 1] * w1
            for i in range(n):
                Yolder[i, lane] = Y[i, lane]
                Yold[i, lane] = Y[i, lane] + mu1 * h * K[0, i, lane]
            ri[RI_J, lane] = 2
            ri[RI_PC, lane] = PC_STAGE
        if ri[RI_PC, lane] == PC_RHO:
            if ri[RI_IT, lane] < 0:  # rkc_rho's start
                ynorm = 0.0
                vnorm = 0.0
                for i in range(n):
                    ynorm += Y[i, lane] * Y[i, lane]
                    vnorm += V[i, lane] * V[i, lane]
                ynorm = math.sqrt(ynorm)
                vnorm = math.sqrt(vnorm)
                dz = math.sqrt(2.220446049250313e-16) * max(ynorm, 1e-3)
                if not vnorm > 0.0:
                    for i in range(n):
                        V[i, lane] = 1.0
                    vnorm = math.sqrt(n)
                for i in range(n):
                    Z[i, lane] = Y[i, lane] + V[i, lane] * (dz / vnorm)
                rf[RF_DZ, lane] = dz
                rf[RF_RAW, lane] = 0.0
                ri[RI_IT, lane] = 0
            asks[lane] = 1
        else:  # a stage, or the step's end: ẏ at Yold
            asks[lane] = 2
        wanted = True
    for lane in range(L):  # the states asked for (the other lanes' rows left as they are)
        a = asks[lane]
        if a == 1:
            for i in range(n):
                wf[i * L + lane] = Z[i, lane]
        elif a == 2:
            for i in range(n):
                wf[i * L + lane] = Yold[i, lane]
    return wanted


@jit_inline
def rkc_consume(lane_b, mode, finished, ri, rf, Y, K, V, Z, Yold, Yolder, FN, cheb, t, h_abs,
                evals, attempts, i_out, t_eval, atol, rtol, keep, out_y, scratch, wf, asks, c,
                G):  # fmt: skip
    """Each lane that asked ẏ of ``rkc_prepare`` takes it from wf's rows (FREE_LANES_OUT …).

    A step of ρ's power iteration (``rkc_rho``'s), of a stage (``rkc_step``'s
    recurrence), or the step's end: its error, rejected (then a new ρ) or accepted (its
    outputs, the new state, the next step; a new ρ every RKC_RHO_EVERY steps; the
    hand-back test at the next decision), as ``rkc_tail``'s. The sums over the
    coordinates run lane by lane side by side, each lane's in rkc_tail's order.
    ``c`` (9, L), ``G`` (4, n): scratch.
    """
    n = Y.shape[0]
    L = LANE_COUNT
    T = t_eval.shape[0]
    t_bound = t_eval[T - 1]
    out = FREE_LANES_OUT * L
    # Per lane: its kind of evaluation (1 ρ, 2 stage, 3 end) and a stage's coefficients.
    kind = c[0]
    sums = False
    stages = False
    for lane in range(L):
        kind[lane] = 0.0
        if asks[lane] == 0:
            continue
        pc = ri[RI_PC, lane]
        kind[lane] = 1.0 if pc == PC_RHO else (2.0 if pc == PC_STAGE else 3.0)
        sums = sums or pc != PC_STAGE
        stages = stages or pc == PC_STAGE
        c[4, lane] = rf[RF_H, lane]
        if pc == PC_STAGE:
            j = ri[RI_J, lane]
            Tc, bc = cheb[lane, 0], cheb[lane, 3]
            w0, w1 = rf[RF_W0, lane], rf[RF_W1, lane]
            mu = 2.0 * bc[j] * w0 / bc[j - 1]
            nu = -bc[j] / bc[j - 2]
            mut = 2.0 * bc[j] * w1 / bc[j - 1]
            gt = -(1.0 - bc[j - 1] * Tc[j - 1]) * mut
            c[1, lane] = 1.0 - mu - nu
            c[2, lane] = mu
            c[3, lane] = nu
            c[4, lane] = rf[RF_H, lane]
            c[5, lane] = mut
            c[6, lane] = gt
    # Sums over the coordinates, in rkc_tail's order: the step's error Σ a² (its end) and
    # |f(z) − f(y)|² (ρ); ẏ at the step's end kept in FN.
    accE = c[7]
    accR = c[8]
    Hh = c[4]
    for lane in range(L if sums else 0):
        k = kind[lane]
        if k == 1.0:
            e = 0.0
            for i in range(n):
                d = wf[out + i * L + lane] - K[0, i, lane]
                e += d * d
            accR[lane] = e
        elif k == 3.0:
            e = 0.0
            h = Hh[lane]
            for i in range(n):
                f = wf[out + i * L + lane]
                k0 = K[0, i, lane]
                y = Y[i, lane]
                yn = Yold[i, lane]
                FN[i, lane] = f
                est = 0.8 * (y - yn) + 0.4 * h * (k0 + f)
                a = est / (atol[i] + max(abs(y), abs(yn)) * rtol)
                e += a * a
            accE[lane] = e
    for lane in range(L):
        k = kind[lane]
        if k == 2.0:
            j = ri[RI_J, lane]
            if j == ri[RI_S, lane]:
                ri[RI_PC, lane] = PC_END
            ri[RI_J, lane] = j + 1
        elif k == 1.0:
            it = ri[RI_IT, lane]
            evals[lane] += 1
            dnorm = math.sqrt(accR[lane])
            dz = rf[RF_DZ, lane]
            before = rf[RF_RAW, lane]
            rho = dnorm / dz
            rf[RF_RAW, lane] = rho
            if not math.isfinite(rho):
                rf[RF_RHO, lane] = rho
                ri[RI_PC, lane] = PC_DECIDE
                continue
            if dnorm == 0.0 or (it > 1 and abs(rho - before) <= 0.01 * max(rho, before)):
                done = True
            else:
                for i in range(n):
                    Z[i, lane] = Y[i, lane] + (wf[out + i * L + lane] - K[0, i, lane]) * (
                        dz / dnorm
                    )
                ri[RI_IT, lane] = it + 1
                done = it + 1 == 20
            if done:  # v = z − y (z as it is: moved on after the twentieth)
                for i in range(n):
                    V[i, lane] = Z[i, lane] - Y[i, lane]
                rf[RF_RHO, lane] = 1.2 * rho
                ri[RI_PC, lane] = PC_DECIDE
        elif k == 3.0:
            b = lane_b[lane]
            h = rf[RF_H, lane]
            tl = t[lane]
            t_new = rf[RF_TNEW, lane]
            evals[lane] += ri[RI_S, lane]
            attempts[lane] += 1
            err = math.sqrt(accE[lane] / n)
            if not math.isfinite(err) or err > 1.0:
                if math.isfinite(err):
                    h_abs[lane] = h * max(0.1, 0.8 * err ** (-1.0 / 3.0))
                else:
                    h_abs[lane] = h * MIN_FACTOR
                    worst = 0.0
                    limiting = 0
                    for i in range(n):  # the first coordinate of the largest |a| (or NaN)
                        yn = Yold[i, lane]
                        est = 0.8 * (Y[i, lane] - yn) + 0.4 * h * (K[0, i, lane] + FN[i, lane])
                        a = est / (atol[i] + max(abs(Y[i, lane]), abs(yn)) * rtol)
                        if not abs(a) <= worst:
                            worst = abs(a)
                            limiting = i
                    ri[RI_PENDING, lane] = 1
                    ri[RI_LIMIT, lane] = limiting
                ri[RI_SINCE, lane] = 0
                ri[RI_IT, lane] = -1
                ri[RI_PC, lane] = PC_RHO
                continue
            m = i_out[lane]
            if keep != KEEP_FINAL and m < T and t_eval[m] <= t_new:
                ys = out_y[b] if keep == KEEP_TRAJECTORIES else scratch[lane]
                for i in range(n):  # the lane's columns, contiguous for the outputs' loop
                    G[0, i] = Y[i, lane]
                    G[1, i] = K[0, i, lane]
                    G[2, i] = Yold[i, lane]
                    G[3, i] = FN[i, lane]
                while m < T and t_eval[m] <= t_new:
                    x = (t_eval[m] - tl) / h
                    x2 = x * x
                    x3 = x2 * x
                    h00 = 2.0 * x3 - 3.0 * x2 + 1.0
                    c10 = (x3 - 2.0 * x2 + x) * h
                    h01 = 3.0 * x2 - 2.0 * x3
                    c11 = (x3 - x2) * h
                    for i in range(n):  # rkc_tail's h00·y + h10·h·f + h01·y₁ + h11·h·f₁
                        ys[m, i] = h00 * G[0, i] + c10 * G[1, i] + h01 * G[2, i] + c11 * G[3, i]
                    m += 1
                i_out[lane] = m
            for i in range(n):
                Y[i, lane] = Yold[i, lane]
                K[0, i, lane] = FN[i, lane]
            t[lane] = t_new
            factor = 10.0 if err == 0.0 else min(10.0, max(0.1, 0.8 * err ** (-1.0 / 3.0)))
            h_abs[lane] = h * factor
            if t_new - t_bound >= 0.0:
                finished[lane] = True
                ri[RI_PC, lane] = PC_IDLE
            else:
                ri[RI_BACK, lane] = 1
                ri[RI_SINCE, lane] += 1
                if ri[RI_SINCE, lane] == RKC_RHO_EVERY:
                    ri[RI_SINCE, lane] = 0
                    ri[RI_IT, lane] = -1
                    ri[RI_PC, lane] = PC_RHO
                else:
                    ri[RI_PC, lane] = PC_DECIDE
    # The stages' recurrence (rkc_step's expression), every lane side by side: a lane not
    # at a stage computes with stale coefficients into rows it no longer reads (its end
    # was taken above; a new step sets both rows afresh). The 8 lanes written out (as
    # combine_lanes's), so that LLVM runs them a vector at a time.
    if stages:
        cc1 = c[1]
        cc2 = c[2]
        cc3 = c[3]
        cc4 = c[4]
        cc5 = c[5]
        cc6 = c[6]
        a0, b0, d0, e0, g0, m0 = cc1[0], cc2[0], cc3[0], cc4[0], cc5[0], cc6[0]
        a1, b1, d1, e1, g1, m1 = cc1[1], cc2[1], cc3[1], cc4[1], cc5[1], cc6[1]
        a2, b2, d2, e2, g2, m2 = cc1[2], cc2[2], cc3[2], cc4[2], cc5[2], cc6[2]
        a3, b3, d3, e3, g3, m3 = cc1[3], cc2[3], cc3[3], cc4[3], cc5[3], cc6[3]
        a4, b4, d4, e4, g4, m4 = cc1[4], cc2[4], cc3[4], cc4[4], cc5[4], cc6[4]
        a5, b5, d5, e5, g5, m5 = cc1[5], cc2[5], cc3[5], cc4[5], cc5[5], cc6[5]
        a6, b6, d6, e6, g6, m6 = cc1[6], cc2[6], cc3[6], cc4[6], cc5[6], cc6[6]
        a7, b7, d7, e7, g7, m7 = cc1[7], cc2[7], cc3[7], cc4[7], cc5[7], cc6[7]
        for i in range(n):
            r = out + i * L
            y, yo, yy, k0 = Y[i], Yold[i], Yolder[i], K[0, i]
            v0 = a0 * y[0] + b0 * yo[0] + d0 * yy[0] + e0 * (g0 * wf[r + 0] + m0 * k0[0])
            v1 = a1 * y[1] + b1 * yo[1] + d1 * yy[1] + e1 * (g1 * wf[r + 1] + m1 * k0[1])
            v2 = a2 * y[2] + b2 * yo[2] + d2 * yy[2] + e2 * (g2 * wf[r + 2] + m2 * k0[2])
            v3 = a3 * y[3] + b3 * yo[3] + d3 * yy[3] + e3 * (g3 * wf[r + 3] + m3 * k0[3])
            v4 = a4 * y[4] + b4 * yo[4] + d4 * yy[4] + e4 * (g4 * wf[r + 4] + m4 * k0[4])
            v5 = a5 * y[5] + b5 * yo[5] + d5 * yy[5] + e5 * (g5 * wf[r + 5] + m5 * k0[5])
            v6 = a6 * y[6] + b6 * yo[6] + d6 * yy[6] + e6 * (g6 * wf[r + 6] + m6 * k0[6])
            v7 = a7 * y[7] + b7 * yo[7] + d7 * yy[7] + e7 * (g7 * wf[r + 7] + m7 * k0[7])
            yy[0] = yo[0]
            yy[1] = yo[1]
            yy[2] = yo[2]
            yy[3] = yo[3]
            yy[4] = yo[4]
            yy[5] = yo[5]
            yy[6] = yo[6]
            yy[7] = yo[7]
            yo[0] = v0
            yo[1] = v1
            yo[2] = v2
            yo[3] = v3
            yo[4] = v4
            yo[5] = v5
            yo[6] = v6
            yo[7] = v7


@jit
def accept_lanes(dop853, n_stages, exponent, lane_b, dop_lane, accepted, rejected, evals,
                 attempts, h, h_abs, e5s, e3s, ERR, Ynew, K, limiting, dense, i_out, t_eval,
                 t_next):  # fmt: skip
    """Each DOP853 (or RK45) lane's step from its error norm: accepted, or rejected.

    SciPy's rules (a smaller step after a rejection). Returns whether some accepted lane
    has outputs in its step.
    """
    n = Ynew.shape[0]
    L = LANE_COUNT
    T = t_eval.shape[0]
    any_dense = False
    for lane in range(L):
        accepted[lane] = False
        b = lane_b[lane]
        if b < 0 or not dop_lane[lane]:
            continue
        evals[lane] += n_stages
        attempts[lane] += 1
        hl = h[lane]
        e5 = e5s[lane]
        e3 = e3s[lane]
        if dop853:
            if e5 == 0.0 and e3 == 0.0:
                error_norm = 0.0
            else:
                error_norm = abs(hl) * e5 / math.sqrt((e5 + 0.01 * e3) * n)
        else:
            error_norm = math.sqrt(e5 / n)
        k = -1
        for i in range(n):
            if not (math.isfinite(Ynew[i, lane]) and math.isfinite(K[n_stages, i, lane])):
                k = i
                break
        if k >= 0 or not math.isfinite(error_norm):
            if k < 0:
                for s in range(n_stages):
                    for i in range(n):
                        if not math.isfinite(K[s, i, lane]):
                            k = i
                            break
                    if k >= 0:
                        break
            limiting[lane] = max(k, 0)
            h_abs[lane] *= MIN_FACTOR
            rejected[lane] = True
            continue
        worst = 0.0
        for i in range(n):
            if abs(ERR[i, lane]) > worst:
                worst = abs(ERR[i, lane])
                limiting[lane] = i
        if error_norm < 1.0:
            if error_norm == 0.0:
                factor = MAX_FACTOR
            else:
                factor = min(MAX_FACTOR, SAFETY * error_norm**exponent)
            if rejected[lane]:
                factor = min(1.0, factor)
            h_abs[lane] *= factor
            accepted[lane] = True
            rejected[lane] = False
            if dense and i_out[lane] < T and t_eval[i_out[lane]] <= t_next[lane]:
                any_dense = True
        else:
            h_abs[lane] *= max(MIN_FACTOR, SAFETY * error_norm**exponent)
            rejected[lane] = True
    return any_dense


@jit
def no_rkc_prepare(lane_b, mode, finished, ri, rf, Y, K, V, Z, Yold, Yolder, cheb, t, h_abs,
                   attempts, evals, info, t_reached, t_eval, max_step, max_steps, wf, asks):  # fmt: skip
    """``run_lanes``'s stand-in for rkc_prepare: no lane is ever in RKC's tail there."""
    return False


@jit
def no_rkc_consume(lane_b, mode, finished, ri, rf, Y, K, V, Z, Yold, Yolder, FN, cheb, t,
                   h_abs, evals, attempts, i_out, t_eval, atol, rtol, keep, out_y, scratch, wf,
                   asks, c, G):  # fmt: skip
    """``run_lanes``'s stand-in for rkc_consume (never called)."""
    return


@jit
def efforts_lanes(ys, rows, c, taus, gw, P, phys):
    """PD plus G(q) at the first ``rows`` states ys (…, n) into taus, LANE_COUNT at a time.

    ``gw``: the work array of the physical kernels (``gravity_lanes``). Returns -1, or
    nv·i + k of the first non-finite effort.
    """
    n = ys.shape[1]
    nv = n // 2
    L = LANE_COUNT
    out = GRAVITY_LANES_OUT * L
    for start in range(0, rows, L):
        m = min(L, rows - start)
        for i in range(n):
            for j in range(L):
                gw[i * L + j] = ys[start + min(j, m - 1), i]
        phys_sincos(gw)
        gravity_lanes(gw)
        for j in range(m):
            y = ys[start + j]
            for k in range(nv):
                pd = -c[nv + k] * y[nv + k] - c[k] * (y[k] - c[2 * nv + k])
                t = pd + gw[out + k * L + j]
                if phys[0] != 0:
                    t = clip(t, P[2, k])
                taus[start + j, k] = t
    for i in range(rows):
        for k in range(nv):
            if not math.isfinite(taus[i, k]):
                return nv * i + k
    return -1


@jit
def efforts_at_lanes(t_eval, rows, law, c, rt, rv, ys, taus, ws):
    """``efforts_at`` under PD plus gravity (single runs' copies), by ``efforts_lanes``.

    G(q) of LANE_COUNT samples a call instead of one: the same bits as the template's
    ``efforts_at`` with ``efforts_pd_law`` (the lanes' rows equal single runs'), about a
    quarter of its time at a run's outputs. ``ws``: the run's workspace (P, phys).
    """
    P, phys = ws[3], ws[4]
    gw = np.zeros(PHYS_ROWS * LANE_COUNT)
    return efforts_lanes(ys, rows, c, taus, gw, P, phys)


@jit
def run_lanes_rkc(
    method, Y0, t_eval, atol, rtol, max_step, max_steps, C, keep, band,
    out_y, out_tau, metrics, info, t_reached, first, stop, P, phys,
):  # fmt: skip
    """Variants ``first`` … ``stop`` − 1 under PD plus gravity, LANE_COUNT at a time in lanes.

    Arguments as ``run_many``'s (every law PD plus gravity; RK45 or DOP853; P and phys
    the physical model, applied when phys[0] != 0). The stages are evaluated in the
    work array of ``free_lanes``: states written into its first rows, the efforts into
    the next nv, ẏ read from its rows from FREE_LANES_OUT on.
    """
    L = LANE_COUNT
    n = Y0.shape[1]
    nv = n // 2
    T = t_eval.shape[0]
    t0 = t_eval[0]
    t_bound = t_eval[T - 1]
    handover = method == METHOD_DOP853_RKC
    dop853 = method == METHOD_DOP853 or handover
    if dop853:
        n_stages, exponent, order, A = D8_NS, -1.0 / 8.0, 7.0, D8_A
    else:
        n_stages, exponent, order, A = 6, -1.0 / 5.0, 4.0, RK45_AB
    dense = keep != KEEP_FINAL
    Y = np.zeros((n, L))
    Ynew = np.zeros((n, L))
    K = np.zeros((16, n, L))
    CL = np.zeros((3 * nv, L))
    h = np.zeros(L)
    t = np.zeros(L)
    t_next = np.zeros(L)
    h_abs = np.zeros(L)
    attempts = np.zeros(L, dtype=np.int64)
    evals = np.zeros(L, dtype=np.int64)
    i_out = np.zeros(L, dtype=np.int64)
    lane_b = np.full(L, -1, dtype=np.int64)
    rejected = np.zeros(L, dtype=np.bool_)
    accepted = np.zeros(L, dtype=np.bool_)
    limiting = np.zeros(L, dtype=np.int64)
    scratch = np.empty((L, T if keep == KEEP_METRICS else 1, n))
    taus = np.empty((T if keep == KEEP_METRICS else 1, nv))
    ws = (np.empty(nv), np.empty(3 * nv), np.empty((nv, nv)), P, phys)
    F = np.empty((8, n))
    FL = np.zeros((7, n, L))
    wf = np.zeros(PHYS_ROWS * L)
    fold = np.zeros(L, dtype=np.bool_)
    okay = np.zeros(L, dtype=np.int64)
    ERR = np.zeros((n, L))
    e5s = np.zeros(L)
    e3s = np.zeros(L)
    acc3 = np.zeros(L)
    start = np.full(L, -1, dtype=np.int64)
    F0 = np.zeros((1, n, L))
    F1 = np.zeros((1, n, L))
    Ytmp = np.zeros((n, L))
    hz = np.zeros(L)
    begun = np.zeros((4, L))
    work = (wf, CL, P, fold, okay)
    rt = np.zeros(1)
    rv = np.zeros((1, 1))
    # DOP853-RKC: each lane's mode (0 DOP853, 1 in RKC's tail, 2 handed back: DOP853
    # from the next round) and its RKC state (rkc_prepare's and rkc_consume's).
    mode = np.zeros(L, dtype=np.int64)
    streak = np.zeros(L, dtype=np.int64)
    dop_lane = np.zeros(L, dtype=np.bool_)
    finished = np.zeros(L, dtype=np.bool_)
    ri = np.zeros((RI_ROWS, L), dtype=np.int64)
    rf = np.zeros((RF_ROWS, L))
    V = np.zeros((n, L))
    Z = np.zeros((n, L))
    Yold = np.zeros((n, L))
    Yolder = np.zeros((n, L))
    FN = np.zeros((n, L))
    Ys11 = np.zeros((n, L))
    cheb = np.zeros((L, 4, RKC_MAX_STAGES + 1 if handover else 1))
    asks = np.zeros(L, dtype=np.int64)
    cw = np.zeros((9, L))
    G = np.zeros((4, n))
    next_b = first
    live = 0
    for lane in range(L):
        lane_b[lane] = -1
    while True:
        # Lanes without a variant take the next ones: their first steps side by side.
        while next_b < stop:
            starting = 0
            for lane in range(L):
                start[lane] = -1
                if lane_b[lane] < 0 and next_b < stop:
                    b = next_b
                    next_b += 1
                    start[lane] = b
                    starting += 1
                    for i in range(n):
                        Y[i, lane] = Y0[b, i]
                    for i in range(3 * nv):
                        CL[i, lane] = C[b, i]
            if starting == 0:
                break
            first_steps(phys, Y, start, F0, F1, Ytmp, hz, atol, rtol, order, t_bound - t0,
                        max_step, work, begun)  # fmt: skip
            for lane in range(L):
                b = start[lane]
                if b < 0:
                    continue
                status = int(begun[0, lane])
                if status != STATUS_OK:
                    info[b, 0] = status
                    info[b, 1] = int(begun[1, lane])
                    info[b, 2] = int(begun[2, lane])
                    t_reached[b] = t0 + begun[3, lane]
                    continue
                lane_b[lane] = b
                live += 1
                mode[lane] = 0
                streak[lane] = 0
                for i in range(n):
                    K[0, i, lane] = F0[0, i, lane]
                t[lane] = t0
                h_abs[lane] = begun[3, lane]
                evals[lane] = int(begun[2, lane])
                attempts[lane] = 0
                i_out[lane] = 0
                rejected[lane] = False
                limiting[lane] = 0
        if live == 0:
            return
        # Each lane's step: SciPy's bounds, then the stages of every lane at once.
        any_dop = False
        for lane in range(L):
            h[lane] = 0.0
            dop_lane[lane] = False
            accepted[lane] = False  # (accept_lanes's, where it runs this round)
            if mode[lane] == 2:  # handed back by RKC: DOP853 from this round
                mode[lane] = 0
                streak[lane] = 0
            b = lane_b[lane]
            if b < 0 or mode[lane] != 0:
                continue
            tl = t[lane]
            min_step = 10.0 * abs(np.nextafter(tl, np.inf) - tl)
            if h_abs[lane] > max_step:
                h_abs[lane] = max_step
            elif h_abs[lane] < min_step:
                if rejected[lane]:
                    info[b, 0] = STATUS_STEP_UNDERFLOW
                else:
                    h_abs[lane] = min_step
            if attempts[lane] >= max_steps:
                info[b, 0] = STATUS_MAX_STEPS
            if info[b, 0] != STATUS_OK:
                info[b, 1] = limiting[lane]
                info[b, 2] = evals[lane]
                t_reached[b] = tl
                lane_b[lane] = -1
                live -= 1
                continue
            t_new = tl + h_abs[lane]
            if t_new - t_bound > 0.0:
                t_new = t_bound
            h[lane] = t_new - tl
            h_abs[lane] = abs(h[lane])
            t_next[lane] = t_new
            any_dop = True
            dop_lane[lane] = True
        any_dense = False
        if handover:
            # One loop of evaluations: DOP853's stages 1 … 12 (then its error and its
            # lanes' acceptance, then the dense output's stages 13 … 15 where due), the
            # lanes in RKC's tail a step of theirs at each; with no lane in DOP853, up to
            # 16 of RKC's alone.
            last = n_stages if any_dop else 0
            s = 1
            while True:
                dop_stage = s <= last
                if dop_stage:
                    combine_lanes(Y, K, D8_A, s, h, wf)
                    if s == n_stages - 1:  # stage 11's state: the stiffness test's
                        for i in range(n):
                            for lane in range(L):
                                Ys11[i, lane] = wf[i * L + lane]
                wanted = rkc_prepare(lane_b, mode, finished, ri, rf, Y, K, V, Z, Yold, Yolder,
                                     cheb, t, h_abs, attempts, evals, info, t_reached, t_eval,
                                     max_step, max_steps, wf, asks)  # fmt: skip
                if (any_dop and not dop_stage) or (not any_dop and (not wanted or s > 16)):
                    break
                eval_lanes(phys, n, wf, CL, P, fold, okay)
                if dop_stage:
                    out = FREE_LANES_OUT * L
                    for i in range(n):
                        for lane in range(L):
                            K[s, i, lane] = wf[out + i * L + lane]
                if wanted:
                    rkc_consume(lane_b, mode, finished, ri, rf, Y, K, V, Z, Yold, Yolder, FN,
                                cheb, t, h_abs, evals, attempts, i_out, t_eval, atol, rtol, keep,
                                out_y, scratch, wf, asks, cw, G)  # fmt: skip
                if dop_stage and s == n_stages:
                    for i in range(n):  # the last stage's state
                        for lane in range(L):
                            Ynew[i, lane] = wf[i * L + lane]
                    error_lanes(dop853, n_stages, K, Y, Ynew, h, atol, rtol, ERR, e5s, e3s, acc3)
                    any_dense = accept_lanes(
                        dop853, n_stages, exponent, lane_b, dop_lane, accepted, rejected, evals,
                        attempts, h, h_abs, e5s, e3s, ERR, Ynew, K, limiting, dense, i_out,
                        t_eval, t_next,
                    )  # fmt: skip
                    if any_dense:
                        last = 15
                s += 1
        else:
            if any_dop:
                for s in range(1, n_stages + 1):
                    stage_lanes(phys, Y, K, A, s, h, wf, CL, P, fold, okay)
                for i in range(n):  # the last stage's state
                    for lane in range(L):
                        Ynew[i, lane] = wf[i * L + lane]
                # Each lane's error norm: accepted, or rejected with a smaller step.
                error_lanes(dop853, n_stages, K, Y, Ynew, h, atol, rtol, ERR, e5s, e3s, acc3)
            any_dense = accept_lanes(
                dop853, n_stages, exponent, lane_b, dop_lane, accepted, rejected, evals,
                attempts, h, h_abs, e5s, e3s, ERR, Ynew, K, limiting, dense, i_out, t_eval,
                t_next,
            )  # fmt: skip
            if any_dense and dop853:
                for s in range(n_stages + 1, 16):
                    stage_lanes(phys, Y, K, D8_A, s, h, wf, CL, P, fold, okay)
        if any_dense:
            dense_lanes(dop853, n_stages, K, Y, Ynew, h, FL)
        # Accepted lanes: dense output, then their new state; a finished one lets go.
        for lane in range(L):
            if not accepted[lane]:
                continue
            b = lane_b[lane]
            tl = t[lane]
            hl = h[lane]
            t_new = t_next[lane]
            if handover:  # DOP853's stiffness test (adaptive's, the same sums)
                num = 0.0
                den = 0.0
                for i in range(n):
                    a = K[n_stages, i, lane] - K[n_stages - 1, i, lane]
                    d = Ynew[i, lane] - Ys11[i, lane]
                    num += a * a
                    den += d * d
                stiff = den > 0.0 and hl * hl * num > STIFF_H_RHO * STIFF_H_RHO * den
                streak[lane] = streak[lane] + 1 if stiff else 0
            if dense and i_out[lane] < T and t_eval[i_out[lane]] <= t_new:
                ys = out_y[b] if keep == KEEP_TRAJECTORIES else scratch[lane]
                if dop853:
                    evals[lane] += 16 - (n_stages + 1)
                for r in range(7):
                    for i in range(n):
                        F[r, i] = FL[r, i, lane]
                for i in range(n):  # the lane's state, contiguous for the outputs' loop
                    F[7, i] = Y[i, lane]
                end = samples_until(t_eval, i_out[lane], t_new)
                for j in range(i_out[lane], end):
                    x = (t_eval[j] - tl) / hl
                    if dop853:
                        w = 1.0 - x
                        for i in range(n):
                            ys[j, i] = (
                                (
                                    (
                                        (
                                            (((F[6, i] * x + F[5, i]) * w + F[4, i]) * x + F[3, i])
                                            * w
                                        )
                                        + F[2, i]
                                    )
                                    * x
                                    + F[1, i]
                                )
                                * w
                                + F[0, i]
                            ) * x + F[7, i]
                    else:
                        x2 = x * x
                        x3 = x2 * x
                        x4 = x3 * x
                        for i in range(n):
                            ys[j, i] = (
                                hl * (F[0, i] * x + F[1, i] * x2 + F[2, i] * x3 + F[3, i] * x4)
                                + F[7, i]
                            )
                i_out[lane] = end
            for i in range(n):
                Y[i, lane] = Ynew[i, lane]
                K[0, i, lane] = K[n_stages, i, lane]
            t[lane] = t_new
            if t_new - t_bound >= 0.0:
                finished[lane] = True
            elif handover and streak[lane] >= N_STIFF:  # to RKC (rkc_tail's start)
                mode[lane] = 1
                streak[lane] = 0
                ri[RI_PC, lane] = PC_RHO
                ri[RI_IT, lane] = -1
                ri[RI_SINCE, lane] = ri[RI_BACK, lane] = ri[RI_PENDING, lane] = 0
                for i in range(n):
                    V[i, lane] = 1.0
        if handover:  # lanes RKC let go (failed) leave the count
            live = 0
            for lane in range(L):
                live += lane_b[lane] >= 0
        for lane in range(L):
            if not finished[lane]:
                continue
            finished[lane] = False
            b = lane_b[lane]
            t_new = t[lane]
            # The variant is done: its efforts (and metrics) at the samples kept.
            if keep == KEEP_FINAL:
                ys = out_y[b]
                for i in range(n):
                    ys[0, i] = Y[i, lane]
                rows = 1
            else:
                ys = out_y[b] if keep == KEEP_TRAJECTORIES else scratch[lane]
                rows = i_out[lane]
            tau_rows = out_tau[b] if keep != KEEP_METRICS else taus
            bad = efforts_lanes(ys, rows, C[b], tau_rows, wf, P, phys)
            status = STATUS_OK
            coordinate = -1
            when = t_new
            if bad >= 0:
                status = STATUS_EFFORT_NONFINITE
                coordinate = bad
                when = t_eval[bad // nv] if ys.shape[0] == T else t_eval[T - 1]
            if keep == KEEP_METRICS:
                for i in range(n):
                    out_y[b, 0, i] = ys[rows - 1, i]
                for i in range(nv):
                    out_tau[b, 0, i] = tau_rows[rows - 1, i]
                if status == STATUS_OK:
                    metrics_of_pd(
                        t_eval, ys, tau_rows, C[b, 2 * nv : 3 * nv], band, metrics[b],
                        LAW_PD_GRAVITY, C[b], rt, rv, ws,
                    )  # fmt: skip
            info[b, 0] = status
            info[b, 1] = coordinate
            info[b, 2] = evals[lane]
            t_reached[b] = when
            lane_b[lane] = -1
            live -= 1
