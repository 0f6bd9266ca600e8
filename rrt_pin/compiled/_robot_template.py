"""The integrators of any robot, in machine code: the template its generated module is made from.

:mod:`rrt_pin.compiled.robot_code` writes one module a robot: a header (imports,
``jit``), the robot's generated one-sample functions (``forward``, ``gravity``,
``mass_matrix``, ``bias``: :mod:`rrt_pin.dynamics.forward_source`), then this file
from the line ``# --- template ---`` on. Above that line, stubs stand in for them,
so that this file reads (and lints) as Python; it is never imported to run.

The state is y = (q, q̇), n = 2·nv entries [rad or m, rad/s or m/s] (continuous
joints: their angle). The right-hand side is ẏ = (q̇, q̈) with q̈ the generated
forward dynamics under τ of the run's law (``LAW_*`` of :mod:`rrt_pin.simulate.codes`):

* ``LAW_NONE``: τ = 0 (passive motion);
* ``LAW_PD_GRAVITY``: τ = −kd·q̇ − kp·(q − qf) + G(q), ``c`` = (kp, kd, qf);
* ``LAW_TRACKING``: computed torque along a sampled motion, τ = M(q)·(q̈r + kd·(q̇r − q̇)
  + kp·(qr − q)) + b(q, q̇), (qr, q̇r, q̈r) interpolated linearly in the reference
  (``rt`` (K,) [s], ``rv`` (K, 3·nv)) and held outside it, ``c`` = (kp, kd);
* ``LAW_OPEN_LOOP``: τ(t) interpolated linearly in ``rt``, ``rv`` (K, nv), held outside.

The adaptive methods are SciPy's ``solve_ivp`` RK45 and DOP853 step for step (the same
initial step, error norms, step-size control and dense output, as the chapter arm's
:mod:`rrt_pin.compiled._jit_integrators`); the fixed-step ones are the formulas of
:mod:`rrt_pin.simulate.integrators`. A run returns a status (``STATUS_*`` of
:mod:`rrt_pin.simulate.codes`), never raises.
"""

import math

import numpy as np

from rrt_pin.compiled import _dop853_coefficients as dop


def jit(f):  # the module's header defines numba's
    return f


jit_inline = jit


def forward(y, tau, out):  # generated: q̈ = M(q)⁻¹(τ − b(q, q̇)) into out[nv:]
    raise NotImplementedError


def rhs_pd(y, c, out):  # generated: ẏ under PD (c = kp, kd, qf) without gravity
    raise NotImplementedError


def forward_free(y, tau, out):  # generated: q̈ without gravity under tau, into out[nv:]
    raise NotImplementedError


def rhs_phys(y, c, P, out):  # generated: ẏ under PD + G with the physical model applied
    raise NotImplementedError


def gravity(y, out):  # generated: G(q)
    raise NotImplementedError


def mass_matrix(y, out):  # generated: M(q) (nv, nv)
    raise NotImplementedError


def bias(y, out):  # generated: b(q, q̇)
    raise NotImplementedError


LAW_NONE, LAW_PD_GRAVITY, LAW_TRACKING, LAW_OPEN_LOOP = 0, 1, 2, 3
FRICTION_VELOCITY = 1e-3
KEEP_TRAJECTORIES, KEEP_FINAL, KEEP_METRICS = 0, 1, 2
METHOD_DOP853, METHOD_RK4, METHOD_SYMPLECTIC_EULER, FIXED_STEP_FROM = 1, 11, 10, 10
METHOD_DOP853_RKC = 5
N_STIFF = 15
STIFF_H_RHO = 3.25
STATUS_OK, STATUS_NONFINITE, STATUS_STEP_UNDERFLOW = 0, 1, 2
STATUS_MAX_STEPS, STATUS_NO_CONVERGENCE, STATUS_EFFORT_NONFINITE = 4, 5, 6
# --- template ---

SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0
VERLET_TOL = 1e-14
VERLET_MAX_ITER = 50

RK45_C = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1, 1])
RK45_AB = np.array(
    [
        [0, 0, 0, 0, 0, 0, 0],
        [1 / 5, 0, 0, 0, 0, 0, 0],
        [3 / 40, 9 / 40, 0, 0, 0, 0, 0],
        [44 / 45, -56 / 15, 32 / 9, 0, 0, 0, 0],
        [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729, 0, 0, 0],
        [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656, 0, 0],
        [35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84, 0],
    ]
)
RK45_E = np.array([-71 / 57600, 0, 71 / 16695, -71 / 1920, 17253 / 339200, -22 / 525, 1 / 40])
RK45_P = np.array(
    [
        [1, -8048581381 / 2820520608, 8663915743 / 2820520608, -12715105075 / 11282082432],
        [0, 0, 0, 0],
        [0, 131558114200 / 32700410799, -68118460800 / 10900136933, 87487479700 / 32700410799],
        [0, -1754552775 / 470086768, 14199869525 / 1410260304, -10690763975 / 1880347072],
        [0, 127303824393 / 49829197408, -318862633887 / 49829197408, 701980252875 / 199316789632],
        [0, -282668133 / 205662961, 2019193451 / 616988883, -1453857185 / 822651844],
        [0, 40617522 / 29380423, -110615467 / 29380423, 69997945 / 29380423],
    ]
)
RK4_C = np.array([0.0, 0.5, 0.5, 1.0])
D8_NS = dop.N_STAGES
D8_A = np.ascontiguousarray(dop.A)
D8_C = np.ascontiguousarray(dop.C)
D8_E3 = np.ascontiguousarray(dop.E3)
D8_E5 = np.ascontiguousarray(dop.E5)
D8_D = np.ascontiguousarray(dop.D)


@jit
def interp_at(rt, rv, t, col0, count, out):
    """Columns col0 … col0+count of ``rv`` at time ``t``, linear in ``rt``, held outside (np.interp)."""
    last = rt.shape[0] - 1
    if t <= rt[0] or last == 0:
        for k in range(count):
            out[k] = rv[0, col0 + k]
        return
    if t >= rt[last]:
        for k in range(count):
            out[k] = rv[last, col0 + k]
        return
    lo, hi = 0, last
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if rt[mid] <= t:
            lo = mid
        else:
            hi = mid
    dt = rt[hi] - rt[lo]
    for k in range(count):
        slope = (rv[hi, col0 + k] - rv[lo, col0 + k]) / dt
        out[k] = slope * (t - rt[lo]) + rv[lo, col0 + k]


@jit
def pd(y, c, tau):
    """τ = −kd·q̇ − kp·(q − qf) at the state y, ``c`` = (kp, kd, qf)."""
    nv = tau.shape[0]
    for k in range(nv):
        tau[k] = -c[nv + k] * y[nv + k] - c[k] * (y[k] - c[2 * nv + k])


@jit
def efforts_pd_law(t, y, law, c, rt, rv, tau, work, m):
    """``efforts`` of PD plus this robot's gravity.

    The lanes' one law: their copies of the functions that ask for a law's efforts call
    this one, and compile no other law's.
    """
    nv = tau.shape[0]
    gravity(y, work)
    pd(y, c, tau)
    for k in range(nv):
        tau[k] = tau[k] + work[k]


@jit
def efforts(t, y, law, c, rt, rv, tau, work, m):
    """τ of the law at (t, y) into ``tau`` (nv,); ``work`` (3·nv,) and ``m`` (nv, nv) scratch."""
    nv = tau.shape[0]
    if law == LAW_PD_GRAVITY:
        efforts_pd_law(t, y, law, c, rt, rv, tau, work, m)
    elif law == LAW_TRACKING:
        interp_at(rt, rv, t, 0, 3 * nv, work)
        for k in range(nv):
            work[2 * nv + k] = (
                work[2 * nv + k] + c[nv + k] * (work[nv + k] - y[nv + k]) + c[k] * (work[k] - y[k])
            )
        mass_matrix(y, m)
        bias(y, tau)
        for i in range(nv):
            s = 0.0
            for j in range(nv):
                s += m[i, j] * work[2 * nv + j]
            tau[i] += s
    elif law == LAW_OPEN_LOOP:
        interp_at(rt, rv, t, 0, nv, tau)
    else:
        for k in range(nv):
            tau[k] = 0.0


@jit_inline
def clip(t, e):
    """``t`` clipped to [−e, e] (NaN stays NaN)."""
    if t > e:
        return e
    if t < -e:
        return -e
    return t


@jit
def saturate(tau, P):
    """The law's efforts ``tau`` clipped at the effort limits P[2]."""
    for k in range(tau.shape[0]):
        tau[k] = clip(tau[k], P[2, k])


@jit_inline
def losses(q, v, lower, upper, damping, friction, stiffness, limit_damping):
    """One joint's damping, friction and compliant position-limit efforts at (q, q̇).

    The terms of :func:`rrt_pin.robot.limits.applied_efforts` beyond the saturated law.
    """
    f = -damping * v
    if friction != 0.0:
        f -= friction * math.tanh(v / FRICTION_VELOCITY)
    if q < lower:
        f += max(0.0, stiffness * (lower - q) - limit_damping * v)
    elif q > upper:
        f += min(0.0, stiffness * (upper - q) - limit_damping * v)
    return f


@jit
def passive(y, P, k):
    """Joint k's :func:`losses` at the state y (P as ``Physical.as_array``)."""
    nv = P.shape[1]
    return losses(y[k], y[nv + k], P[0, k], P[1, k], P[3, k], P[4, k], P[5, k], P[6, k])


@jit
def rhs_pd_law(t, y, law, c, rt, rv, out, ws):
    """``rhs`` under PD plus this robot's gravity (the lanes' one law, as ``efforts_pd_law``).

    With no physical model applied (``ws[4][0] == 0``), q̈ is the forward dynamics
    without gravity under the PD efforts alone (the law's G(q) and the robot's cancel
    exactly); else M⁻¹(τ − b) = the forward dynamics without gravity under τ − G, G
    needed for the saturation only (generated with it, the sines and cosines shared).
    """
    tau, work, m, P, phys = ws
    if phys[0] == 0:
        rhs_pd(y, c, out)
    else:
        rhs_phys(y, c, P, out)


@jit
def rhs(t, y, law, c, rt, rv, out, ws):
    """ẏ = (q̇, q̈) of the closed loop at (t, y) into ``out``.

    Under PD plus gravity with no physical model applied (``ws[4][0] == 0``), q̈ is the
    forward dynamics without gravity under the PD efforts alone (the law's G(q) and the
    robot's cancel exactly). Else the joints get the law's efforts saturated at the effort
    limits plus damping, friction and the compliant position limits (P = ws[3]).
    """
    tau, work, m, P, phys = ws
    if law == LAW_PD_GRAVITY:
        rhs_pd_law(t, y, law, c, rt, rv, out, ws)
    else:
        nv = tau.shape[0]
        for k in range(nv):
            out[k] = y[nv + k]
        efforts(t, y, law, c, rt, rv, tau, work, m)
        if phys[0] != 0:
            saturate(tau, P)
            for k in range(nv):
                tau[k] = tau[k] + passive(y, P, k)
        forward(y, tau, out)


@jit
def first_nonfinite(v):
    """Index of the first non-finite entry of ``v``, or -1."""
    for i in range(v.shape[0]):
        if not math.isfinite(v[i]):
            return i
    return -1


@jit
def rms_scaled(v, scale):
    """RMS norm of v / scale (SciPy's ``norm``)."""
    s = 0.0
    for i in range(v.shape[0]):
        x = v[i] / scale[i]
        s += x * x
    return math.sqrt(s / v.shape[0])


@jit
def combine(y, K, A, s, h, out):
    """Out = y + (Σ_{j<s} A[s, j] K[j]) · h (SciPy's order: the sum, then · h)."""
    for i in range(y.shape[0]):
        a = 0.0
        for j in range(s):
            aj = A[s, j]
            if aj != 0.0:
                a += aj * K[j, i]
        out[i] = y[i] + a * h


@jit
def samples_until(t_eval, start, t):
    """The first index >= start whose time is after ``t``, or len(t_eval)."""
    lo = start
    n = t_eval.shape[0] - start
    while n > 0:
        half = n // 2
        mid = lo + half
        if t_eval[mid] <= t:
            lo = mid + 1
            n = n - half - 1
        else:
            n = half
    return lo


@jit
def first_step(
    t, y, law, c, rt, rv, atol, rtol, order, interval, max_step, f, ytmp, err, scale, ws
):
    """f(t, y) into ``f``, then SciPy's ``select_initial_step``: (status, coordinate, evals, h)."""
    tau, work, m, P, phys = ws
    n = y.shape[0]
    rhs(t, y, law, c, rt, rv, f, ws)
    k = first_nonfinite(f)
    if k >= 0:
        return STATUS_NONFINITE, k, 1, t
    for i in range(n):
        scale[i] = atol[i] + abs(y[i]) * rtol
    d0 = rms_scaled(y, scale)
    d1 = rms_scaled(f, scale)
    if d0 < 1e-5 or d1 < 1e-5:
        h0 = 1e-6
    else:
        h0 = 0.01 * d0 / d1
    h0 = min(h0, interval)
    for i in range(n):
        ytmp[i] = y[i] + h0 * f[i]
    rhs(t + h0, ytmp, law, c, rt, rv, err, ws)
    k = first_nonfinite(err)
    if k >= 0:
        return STATUS_NONFINITE, k, 2, t + h0
    for i in range(n):
        err[i] = err[i] - f[i]
    d2 = rms_scaled(err, scale) / h0
    if d1 <= 1e-15 and d2 <= 1e-15:
        h1 = max(1e-6, h0 * 1e-3)
    else:
        h1 = (0.01 / max(d1, d2)) ** (1.0 / (order + 1.0))
    return STATUS_OK, -1, 2, min(100.0 * h0, h1, interval, max_step)


@jit
def adaptive(method, y0, t_eval, atol, rtol, max_step, max_steps, law, c, rt, rv, dense, out_y, ws):
    """RK45 (0), DOP853 (1) or DOP853-RKC from (t_eval[0], y0) with SciPy's error control.

    ``dense``: the state at every t_eval into out_y (T, n); else only the final one
    into out_y[0] (the same steps). Returns (status, coordinate, evals, rows, t).
    DOP853-RKC is DOP853 handing over to ``rkc_tail`` after N_STIFF steps in a row at
    the edge of its stability (h·ρ̂ > STIFF_H_RHO, from the step's last two stages at
    t + h), and on again where RKC hands back: in the copy ``adaptive_rkc`` (and its PD
    copy), which calls ``rkc_tail``; here a stub stands for it, so that the entries of
    DOP853 and RK45 compile none of RKC's code.
    """
    n = y0.shape[0]
    handover = method == METHOD_DOP853_RKC
    dop853 = method == METHOD_DOP853 or handover
    if dop853:
        n_stages, exponent, order, A, Cs = D8_NS, -1.0 / 8.0, 7.0, D8_A, D8_C
    else:
        n_stages, exponent, order, A, Cs = 6, -1.0 / 5.0, 4.0, RK45_AB, RK45_C
    tau, work, m, P, phys = ws
    n_out = t_eval.shape[0]
    K = np.empty((16, n))
    F = np.empty((7, n))
    y = y0.copy()
    y_new = np.empty(n)
    ytmp = np.empty(n)
    f = np.empty(n)
    err = np.empty(n)
    scale = np.empty(n)
    t = t_eval[0]
    t_bound = t_eval[n_out - 1]
    i_out = 0
    status, k, n_evals, h_abs = first_step(
        t, y, law, c, rt, rv, atol, rtol, order, t_bound - t, max_step, f, ytmp, err, scale, ws
    )
    if status != STATUS_OK:
        return status, k, n_evals, 0, h_abs
    n_steps = 0
    n_rejected = 0
    limiting = 0
    streak = 0
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
                return STATUS_STEP_UNDERFLOW, limiting, n_evals, i_out, t
            if n_steps + n_rejected >= max_steps:
                return STATUS_MAX_STEPS, limiting, n_evals, i_out, t
            t_new = t + h_abs
            if t_new - t_bound > 0.0:
                t_new = t_bound
            h = t_new - t
            h_abs = abs(h)
            for i in range(n):
                K[0, i] = f[i]
            for s in range(1, n_stages + 1):
                target = y_new if s == n_stages else ytmp
                combine(y, K, A, s, h, target)
                rhs(t + Cs[s] * h, target, law, c, rt, rv, K[s], ws)
            n_evals += n_stages
            for i in range(n):
                scale[i] = atol[i] + max(abs(y[i]), abs(y_new[i])) * rtol
            if dop853:
                e5 = 0.0
                e3 = 0.0
                for i in range(n):
                    a5 = 0.0
                    a3 = 0.0
                    for j in range(n_stages + 1):
                        a5 += K[j, i] * D8_E5[j]
                        a3 += K[j, i] * D8_E3[j]
                    a5 = a5 / scale[i]
                    a3 = a3 / scale[i]
                    err[i] = a5
                    e5 += a5 * a5
                    e3 += a3 * a3
                if e5 == 0.0 and e3 == 0.0:
                    error_norm = 0.0
                else:
                    error_norm = abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)
            else:
                e = 0.0
                for i in range(n):
                    a = 0.0
                    for j in range(n_stages + 1):
                        a += K[j, i] * RK45_E[j]
                    a = a * h / scale[i]
                    err[i] = a
                    e += a * a
                error_norm = math.sqrt(e / n)
            k = first_nonfinite(y_new)
            if k < 0:
                k = first_nonfinite(K[n_stages])
            if k >= 0 or not math.isfinite(error_norm):
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
            for i in range(n):
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
        if handover:  # before the dense output's stages overwrite ytmp (stage 11's state)
            num = 0.0
            den = 0.0
            for i in range(n):
                a = K[n_stages, i] - K[n_stages - 1, i]
                b = y_new[i] - ytmp[i]
                num += a * a
                den += b * b
            stiff = den > 0.0 and h * h * num > STIFF_H_RHO * STIFF_H_RHO * den
            streak = streak + 1 if stiff else 0
        if dense and i_out < n_out and t_eval[i_out] <= t_new:
            if dop853:
                for s in range(n_stages + 1, 16):
                    combine(y, K, D8_A, s, h, ytmp)
                    rhs(t + D8_C[s] * h, ytmp, law, c, rt, rv, K[s], ws)
                n_evals += 16 - (n_stages + 1)
                for i in range(n):
                    dy = y_new[i] - y[i]
                    F[0, i] = dy
                    F[1, i] = h * K[0, i] - dy
                    F[2, i] = 2.0 * dy - h * (K[n_stages, i] + K[0, i])
                for r in range(4):
                    for i in range(n):
                        s5 = 0.0
                        for j in range(16):
                            drj = D8_D[r, j]
                            if drj != 0.0:
                                s5 += drj * K[j, i]
                        F[3 + r, i] = s5 * h
            else:
                for r in range(4):
                    for i in range(n):
                        s4 = 0.0
                        for j in range(n_stages + 1):
                            pjr = RK45_P[j, r]
                            if pjr != 0.0:
                                s4 += K[j, i] * pjr
                        F[r, i] = s4
            end = samples_until(t_eval, i_out, t_new)
            for j in range(i_out, end):
                x = (t_eval[j] - t) / h
                if dop853:
                    w = 1.0 - x
                    for i in range(n):
                        out_y[j, i] = (
                            (
                                (
                                    ((((F[6, i] * x + F[5, i]) * w + F[4, i]) * x + F[3, i]) * w)
                                    + F[2, i]
                                )
                                * x
                                + F[1, i]
                            )
                            * w
                            + F[0, i]
                        ) * x + y[i]
                else:
                    x2 = x * x
                    x3 = x2 * x
                    x4 = x3 * x
                    for i in range(n):
                        out_y[j, i] = (
                            h * (F[0, i] * x + F[1, i] * x2 + F[2, i] * x3 + F[3, i] * x4) + y[i]
                        )
            i_out = end
        t = t_new
        for i in range(n):
            y[i] = y_new[i]
            f[i] = K[n_stages, i]
        done = t - t_bound >= 0.0
        if handover and streak >= N_STIFF and not done:
            status, k, evals, steps, i_out, t, h_abs, done = no_rkc_tail(
                t, y, f, h_abs, t_eval, i_out, atol, rtol, max_step,
                max_steps - n_steps - n_rejected, law, c, rt, rv, dense, out_y, ws,
            )  # fmt: skip
            n_evals += evals
            n_steps += steps
            streak = 0
            if status != STATUS_OK:
                return status, k, n_evals, i_out, t
        if done:
            if not dense:
                for i in range(n):
                    out_y[0, i] = y[i]
                i_out = 1
            return STATUS_OK, -1, n_evals, i_out, t


@jit
def no_rkc_tail(t, y, f, h_abs, t_eval, i_out, atol, rtol, max_step, budget, law, c, rt, rv,
                dense, out_y, ws):  # fmt: skip
    """``adaptive``'s stand-in for ``rkc_tail`` (never called: DOP853-RKC runs ``adaptive_rkc``)."""
    return STATUS_OK, -1, 0, 0, i_out, t, h_abs, False


@jit
def no_fixed(method, y0, t_eval, dt, max_steps, law, c, rt, rv, dense, out_y, ws):
    """Stands for ``fixed`` in the entries of the adaptive methods (never called there).

    ``run_adaptive``, ``run_adams``, ``run_bdf`` …: their first use compiles no fixed-step
    integrator.
    """
    return STATUS_MAX_STEPS, 0, 0, 0, t_eval[0]


@jit
def fixed(method, y0, t_eval, dt, max_steps, law, c, rt, rv, dense, out_y, ws):
    """Symplectic Euler (10), RK4 (11) or velocity Verlet (12), landing on every t_eval.

    The formulas of :mod:`rrt_pin.simulate.integrators` (Verlet's implicit half kick by
    fixed-point iteration, its last evaluation reused as the next step's a₀). ``dense``
    as :func:`adaptive`'s. Returns (status, coordinate, evals, rows, t).
    """
    n = y0.shape[0]
    nv = n // 2
    tau, work, m, P, phys = ws
    n_out = t_eval.shape[0]
    y = y0.copy()
    k = np.empty((4, n))
    ytmp = np.empty(n)
    acc = np.empty(n)
    n_evals = 0
    n_steps = 0
    have_a = False
    if dense:
        for i in range(n):
            out_y[0, i] = y[i]
    for r in range(1, n_out):
        ta = t_eval[r - 1]
        span = t_eval[r] - ta
        steps = 1
        if dt > 0.0:
            steps = max(1, int(math.ceil(span / dt * (1.0 - 1e-12))))
        h = span / steps
        for sub in range(steps):
            t = ta + sub * h
            if n_steps >= max_steps:
                return STATUS_MAX_STEPS, 0, n_evals, r, t
            if method == METHOD_RK4:
                for s in range(4):
                    if s == 0:
                        for i in range(n):
                            ytmp[i] = y[i]
                    else:
                        ch = RK4_C[s] * h
                        for i in range(n):
                            ytmp[i] = y[i] + ch * k[s - 1, i]
                    rhs(t + RK4_C[s] * h, ytmp, law, c, rt, rv, k[s], ws)
                    n_evals += 1
                for i in range(n):
                    y[i] += h / 6.0 * (k[0, i] + 2.0 * k[1, i] + 2.0 * k[2, i] + k[3, i])
            elif method == METHOD_SYMPLECTIC_EULER:
                rhs(t, y, law, c, rt, rv, acc, ws)
                n_evals += 1
                for i in range(nv):
                    y[nv + i] += h * acc[nv + i]
                    y[i] += h * y[nv + i]
            else:
                for it in range(VERLET_MAX_ITER + 1):
                    if it == 0 and have_a:
                        for i in range(nv):
                            y[nv + i] += 0.5 * h * acc[nv + i]
                            ytmp[i] = y[i] + h * y[nv + i]
                            ytmp[nv + i] = y[nv + i]
                        continue
                    if it > 0:
                        rhs(t + h, ytmp, law, c, rt, rv, acc, ws)
                    else:
                        rhs(t, y, law, c, rt, rv, acc, ws)
                    n_evals += 1
                    if it == 0:
                        for i in range(nv):
                            y[nv + i] += 0.5 * h * acc[nv + i]
                            ytmp[i] = y[i] + h * y[nv + i]
                            ytmp[nv + i] = y[nv + i]
                        have_a = True
                        continue
                    change = 0.0
                    vmax = 0.0
                    for i in range(nv):
                        v_new = y[nv + i] + 0.5 * h * acc[nv + i]
                        change = max(change, abs(v_new - ytmp[nv + i]))
                        ytmp[nv + i] = v_new
                        vmax = max(vmax, abs(v_new))
                    if change <= VERLET_TOL * (1.0 + vmax):
                        break
                    if not math.isfinite(change) or it == VERLET_MAX_ITER:
                        worst = 0
                        for i in range(nv):
                            if not abs(ytmp[nv + i] - y[nv + i]) <= abs(
                                ytmp[nv + worst] - y[nv + worst]
                            ):
                                worst = i
                        return STATUS_NO_CONVERGENCE, nv + worst, n_evals, r, t + h
                for i in range(n):
                    y[i] = ytmp[i]
            n_steps += 1
            bad = first_nonfinite(y)
            if bad >= 0:
                return STATUS_NONFINITE, bad, n_evals, r, t + h
        if dense:
            for i in range(n):
                out_y[r, i] = y[i]
    if not dense:
        for i in range(n):
            out_y[0, i] = y[i]
    return STATUS_OK, -1, n_evals, n_out if dense else 1, t_eval[n_out - 1]


@jit
def efforts_at(t_eval, rows, law, c, rt, rv, ys, taus, ws):
    """The law's efforts at the first ``rows`` states ys (…, n) into taus (…, nv).

    ``t_eval`` gives each row's time (its last entry when ys holds the final state
    only). Returns -1, or nv·i + k of the first non-finite effort.
    """
    tau, work, m, P, phys = ws
    nv = taus.shape[1]
    last = t_eval.shape[0] - 1
    for i in range(rows):
        t = t_eval[i] if ys.shape[0] == t_eval.shape[0] else t_eval[last]
        efforts(t, ys[i], law, c, rt, rv, taus[i], work, m)
        if phys[0] != 0:
            saturate(taus[i], P)
        for k in range(nv):
            if not math.isfinite(taus[i, k]):
                return nv * i + k
    return -1


@jit
def metrics_of(t_eval, ys, taus, qf, band, row, law, c, rt, rv, ws):
    """The metrics row of one run sampled at every t_eval (see rrt_pin.simulate.metrics).

    ``row`` (8·nv + 1): |q(tf) − qf|, settling time (NaN: not settled), peak |τ| and
    its time, max |q(t) − q(t0)|, then ∫ Σ|τ·q̇| dt (trapezoidal) [J], then the
    ``limits`` group: the largest distance past the stated position limits (0 inside)
    and the time the law's demand exceeded the stated effort limit [s], trapezoidal
    over the samples, then the peak demanded |effort| [N·m or N], as
    ``rrt_pin.simulate.crossings`` measures them. ``taus`` are the
    efforts applied (saturated when the model applies effort limits); where one is at
    its limit, the law's demand is computed again at that sample (``law``, ``c``,
    ``rt``, ``rv`` its law, ``ws`` the run's workspace: P's rows 8–10 hold the stated
    lower, upper and effort limits).
    """
    T = t_eval.shape[0]
    nv = taus.shape[1]
    demand, work, m, P, phys = ws
    depth = 5 * nv + 1
    saturated = 6 * nv + 1
    peak = 7 * nv + 1
    # Every metric is a running max, a last or first index, or a sum in the samples'
    # order, so any order of the passes gives the same bits: joint by joint where no
    # sample's demand is computed again, else one pass row after row.
    band_of = np.empty(nv)
    last = np.full(nv, -1, dtype=np.int64)
    when = np.zeros(nv, dtype=np.int64)
    over = np.zeros(nv)
    for k in range(nv):
        row[k] = abs(ys[T - 1, k] - qf[k])
        scale = abs(ys[0, k] - qf[k])
        if not scale > 0.0:
            scale = 0.0
            for i in range(T):
                scale = max(scale, abs(ys[i, k] - qf[k]))
        band_of[k] = band * scale
        row[2 * nv + k] = -1.0
        row[4 * nv + k] = 0.0
        row[depth + k] = 0.0
        row[saturated + k] = 0.0
        row[peak + k] = 0.0
    again_any = False  # a sample whose demand must be computed again (effort limits applied)
    i = 0
    while phys[0] != 0 and not again_any and i < T:
        for k in range(nv):
            again_any = again_any or abs(taus[i, k]) >= P[2, k]
        i += 1
    energy = 0.0
    before = 0.0
    if not again_any:  # column by column, each joint's metrics in registers
        for k in range(nv):
            qk, bk, y0 = qf[k], band_of[k], ys[0, k]
            lo, hi, limit = P[8, k], P[9, k], P[10, k]
            last_k, peak_k, when_k, exc_k, depth_k, demand_k, sat_k, over_k = (
                -1,
                -1.0,
                0,
                0.0,
                0.0,
                0.0,
                0.0,
                0.0,
            )
            for i in range(T):
                q = ys[i, k]
                if abs(q - qk) > bk:
                    last_k = i
                a = abs(taus[i, k])
                if a > peak_k:
                    peak_k = a
                    when_k = i
                exc_k = max(exc_k, abs(q - y0))
                if lo - q > depth_k:
                    depth_k = lo - q
                if q - hi > depth_k:
                    depth_k = q - hi
                if a > demand_k:
                    demand_k = a
                now = 1.0 if a > limit else 0.0
                if i > 0:
                    sat_k += 0.5 * (now + over_k) * (t_eval[i] - t_eval[i - 1])
                over_k = now
            last[k], when[k] = last_k, when_k
            row[2 * nv + k], row[4 * nv + k] = peak_k, exc_k
            row[depth + k], row[peak + k], row[saturated + k] = depth_k, demand_k, sat_k
        for i in range(T):
            p = 0.0
            for k in range(nv):
                p += abs(taus[i, k] * ys[i, nv + k])
            if i > 0:
                energy += 0.5 * (p + before) * (t_eval[i] - t_eval[i - 1])
            before = p
    else:
        for i in range(T):
            again = False
            if phys[0] != 0:
                for k in range(nv):
                    if abs(taus[i, k]) >= P[2, k]:
                        again = True
            if again:
                efforts(t_eval[i], ys[i], law, c, rt, rv, demand, work, m)
            dt = t_eval[i] - t_eval[i - 1] if i > 0 else 0.0
            p = 0.0
            for k in range(nv):
                q = ys[i, k]
                if abs(q - qf[k]) > band_of[k]:
                    last[k] = i
                a = abs(taus[i, k])
                if a > row[2 * nv + k]:
                    row[2 * nv + k] = a
                    when[k] = i
                row[4 * nv + k] = max(row[4 * nv + k], abs(q - ys[0, k]))
                worst = row[depth + k]
                if P[8, k] - q > worst:
                    worst = P[8, k] - q
                if q - P[9, k] > worst:
                    worst = q - P[9, k]
                row[depth + k] = worst
                d = abs(demand[k]) if again else a
                if d > row[peak + k]:
                    row[peak + k] = d
                now = 1.0 if d > P[10, k] else 0.0
                if i > 0:
                    row[saturated + k] += 0.5 * (now + over[k]) * dt
                over[k] = now
                p += abs(taus[i, k] * ys[i, nv + k])
            if i > 0:
                energy += 0.5 * (p + before) * dt
            before = p
    for k in range(nv):
        if last[k] == -1:
            row[nv + k] = t_eval[0]
        elif last[k] == T - 1:
            row[nv + k] = np.nan
        else:
            row[nv + k] = t_eval[last[k] + 1]
        row[3 * nv + k] = t_eval[when[k]]
    row[5 * nv] = energy


@jit
def run_many(
    method, Y0, t_eval, dt, atol, rtol, max_step, max_steps, laws, C, rt, rv, keep, band,
    out_y, out_tau, metrics, info, t_reached, first, stop, P, phys,
):  # fmt: skip
    """Variants ``first`` … ``stop`` − 1, one after the other, each with its own step control.

    Args:
        method: a ``METHOD_*`` code.
        Y0: initial states (B, n).
        t_eval: output times (T,) [s], shared.
        dt: fixed-step methods' longest step [s] (<= 0: one step an interval).
        atol: absolute tolerances (n,).
        rtol: relative tolerance.
        max_step: adaptive methods' longest step [s].
        max_steps: step budget of a variant.
        laws: each variant's ``LAW_*`` code (B,).
        C: their parameters (B, 3·nv).
        rt: reference times of a tracking or open-loop law (K,) [s], shared.
        rv: its values (K, 3·nv or nv).
        keep: ``KEEP_*``: out_y (B, T, n) and out_tau (B, T, nv) hold every output
            time, else the last only (B, 1, …).
        band: the settling band (share of |q0 − qf|).
        out_y: the states kept.
        out_tau: the efforts kept.
        metrics: (B, 5·nv + 1), with KEEP_METRICS (the target qf is a PD law's,
            C[b, 2·nv:3·nv]).
        info: (status, coordinate, evals) a variant (B, 3).
        t_reached: the time each reached, or failed at (B,) [s].
        first: the first variant.
        stop: one past the last.
        P: the physical model (12, nv): rows 0–7 as ``rrt_pin.robot.limits.Physical.as_array``,
            rows 8–10 the robot's stated lower, upper and effort limits (what the
            metrics measure against, applied or not), row 11 the room a PD effort has
            before PD plus G(q) saturates (the lanes' fold; −inf: never).
        phys: (1,) int: 1 to apply P's rows 0–7, 0 for the law alone.
    """
    n = Y0.shape[1]
    nv = n // 2
    T = t_eval.shape[0]
    ws = (np.empty(nv), np.empty(3 * nv), np.empty((nv, nv)), P, phys)
    dense = keep != KEEP_FINAL
    scratch_y = np.empty((T if keep == KEEP_METRICS else 1, n))
    scratch_tau = np.empty((T if keep == KEEP_METRICS else 1, nv))
    for b in range(first, stop):
        ys = out_y[b] if keep == KEEP_TRAJECTORIES else scratch_y
        if not dense:
            ys = out_y[b]
        if method < FIXED_STEP_FROM:
            r = adaptive(
                method, Y0[b], t_eval, atol, rtol, max_step, max_steps, laws[b], C[b], rt, rv,
                dense, ys, ws,
            )  # fmt: skip
        else:
            r = fixed(method, Y0[b], t_eval, dt, max_steps, laws[b], C[b], rt, rv, dense, ys, ws)
        status, coordinate, evals, rows, t = r
        taus = out_tau[b] if keep != KEEP_METRICS else scratch_tau
        bad = efforts_at(t_eval, rows, laws[b], C[b], rt, rv, ys, taus, ws)
        if keep == KEEP_METRICS:
            for i in range(n):
                out_y[b, 0, i] = ys[rows - 1, i] if rows > 0 else np.nan
            for k in range(nv):
                out_tau[b, 0, k] = taus[rows - 1, k] if rows > 0 else np.nan
            if status == STATUS_OK and bad < 0:
                metrics_of(
                    t_eval, ys, taus, C[b, 2 * nv : 3 * nv], band, metrics[b], laws[b], C[b],
                    rt, rv, ws,
                )  # fmt: skip
        if status == STATUS_OK and bad >= 0:
            status, coordinate = STATUS_EFFORT_NONFINITE, bad
            t = t_eval[bad // nv] if ys.shape[0] == T else t_eval[T - 1]
        info[b, 0] = status
        info[b, 1] = coordinate
        info[b, 2] = evals
        t_reached[b] = t
