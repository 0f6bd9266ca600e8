"""Any robot's stiff tail: the Runge–Kutta–Chebyshev method DOP853 hands over to (``DOP853-RKC``).

Appended by :mod:`rrt_pin.compiled.robot_code` to the module it makes from
:mod:`rrt_pin.compiled._robot_template` (from the line ``# --- rkc ---`` on); above that
line, stubs stand in for the template's names it uses, so that this file reads (and
lints) as Python; it is never imported to run.

Why: a robot's closed loop that has settled is stiff for DOP853. Its steps are then
held at the edge of its stability region (|h·λ| ≈ 6 on the negative real axis), not by
the tolerance: on UR5's and Panda's PD scene 61–78 % of its evaluations
(``scripts/bench/stiff_tail.py``). The template's ``adaptive`` runs DOP853, and where
``DOP853-RKC`` is asked and N_STIFF steps in a row pass DOP853's own stiffness test
(Hairer's: h·ρ̂ > 3.25, ρ̂ = |f(y₁) − f(y₁₂)| / |y₁ − y₁₂| from the step's last stage)
it calls :func:`rkc_tail`.

:func:`rkc_tail` is RKC (Sommeijer, Shampine and Verwer, *J. Comput. Appl. Math.* 88,
1997; Verwer, Sommeijer and Hundsdorfer, *J. Comput. Phys.* 201, 2004): second order, s
stages of a Chebyshev recurrence with damping ε = 2/13, stable on the negative real axis
to β(s) ≈ 0.653·s², so a step of any length costs ≈ √(h·ρ / 0.653) evaluations where
DOP853 pays 12 per h·ρ ≈ 6. The stage count comes from ρ, the spectral radius of ∂f/∂y,
estimated by nonlinear power iteration (RKC's own ``rkcrho``: at the handover, every 25
steps and after a rejection, × 1.2). Its local error estimate (0.8·(yₙ − yₙ₊₁) +
0.4·h·(fₙ + fₙ₊₁)) is held to the run's rtol and atol in the RMS norm DOP853 uses, the
step following with factor 0.8·err^(−1/3) in [0.1, 10]; outputs inside a step are the
cubic Hermite interpolant of its ends. It hands back to DOP853 when its next step would
cost twice as many evaluations a second as DOP853 at its stable step (12 per 7.2/ρ s,
its outputs' three not counted: the steps never depend on the outputs asked for): the
motion has picked up again and the order 2 no longer pays.
"""

import math

import numpy as np


def jit(f):  # the module's header defines numba's
    return f


def rhs(t, y, law, c, rt, rv, out, ws):  # the template's
    raise NotImplementedError


STATUS_OK = STATUS_NONFINITE = STATUS_STEP_UNDERFLOW = STATUS_MAX_STEPS = 0
MIN_FACTOR = 0.0
# --- rkc ---

#: Steps in a row DOP853 takes at the edge of its stability before it hands over (Hairer's
#: count in DOP853 for "the problem seems to become stiff").
N_STIFF = 15
#: DOP853's stiffness test: h·ρ̂ above this.
STIFF_H_RHO = 3.25
#: RKC's damping and its stability bound's slope: β(s) ≈ RKC_BETA·s² (a bound, 0.653 s²).
RKC_EPS = 2.0 / 13.0
RKC_BETA = 0.65
#: The most stages an RKC step takes (β ≈ 40,000: h·ρ up to that).
RKC_MAX_STAGES = 250
#: Accepted steps between two estimates of ρ.
RKC_RHO_EVERY = 25
#: h·ρ at DOP853's stable step, with ρ the estimate (× 1.2 of the power iteration's).
D8_STABLE_H_RHO = 7.2
#: RKC hands back when its next step costs this many times DOP853's at its stable step
#: (evaluations a second): at the handover the two are about even, RKC's order 2 being
#: held to the tolerance at DOP853's stable step; as the motion dies out RKC's steps grow.
HAND_BACK = 2.0


@jit
def rkc_rho(t, y, fy, v, law, c, rt, rv, z, fz, ws):
    """1.2 × the spectral radius of ∂f/∂y at (t, y) by nonlinear power iteration (RKC's rkcrho).

    ``fy`` = f(t, y); ``v`` (n,): the start direction, left as the dominant one; ``z``
    and ``fz`` (n,): scratch. Returns (ρ, evaluations); ρ is not finite where f was not.
    """
    n = y.shape[0]
    ynorm = 0.0
    vnorm = 0.0
    for i in range(n):
        ynorm += y[i] * y[i]
        vnorm += v[i] * v[i]
    ynorm = math.sqrt(ynorm)
    vnorm = math.sqrt(vnorm)
    dz = math.sqrt(2.220446049250313e-16) * max(ynorm, 1e-3)
    if not vnorm > 0.0:
        for i in range(n):
            v[i] = 1.0
        vnorm = math.sqrt(n)
    for i in range(n):
        z[i] = y[i] + v[i] * (dz / vnorm)
    rho = 0.0
    evals = 0
    for it in range(20):
        rhs(t, z, law, c, rt, rv, fz, ws)
        evals += 1
        dnorm = 0.0
        for i in range(n):
            d = fz[i] - fy[i]
            dnorm += d * d
        dnorm = math.sqrt(dnorm)
        before = rho
        rho = dnorm / dz
        if not math.isfinite(rho):
            return rho, evals
        if dnorm == 0.0 or (it > 1 and abs(rho - before) <= 0.01 * max(rho, before)):
            break
        for i in range(n):
            z[i] = y[i] + (fz[i] - fy[i]) * (dz / dnorm)
    for i in range(n):
        v[i] = z[i] - y[i]
    return 1.2 * rho, evals


@jit
def rkc_stages(h, rho):
    """(s, h): the stages a step h needs at spectral radius ρ, and the step (shortened at the cap)."""
    s = 1 + int(math.sqrt(1.0 + 1.54 * h * rho))
    if s < 2:
        s = 2
    if s > RKC_MAX_STAGES:
        s = RKC_MAX_STAGES
        h = (s * s - 1) / (1.54 * rho)
    return s, h


@jit
def rkc_coefficients(s, cheb):
    """RKC's recurrence of s stages: T_j, T_j', T_j'' at w0 and b_j into cheb's rows 0–3.

    Returns (w0, w1). The one computation of them: single runs' and the lanes' steps
    take the same bits from it.
    """
    w0 = 1.0 + RKC_EPS / (s * s)
    T, dT, d2T, b = cheb[0], cheb[1], cheb[2], cheb[3]
    T[0], dT[0], d2T[0] = 1.0, 0.0, 0.0
    T[1], dT[1], d2T[1] = w0, 1.0, 0.0
    for j in range(2, s + 1):
        T[j] = 2.0 * w0 * T[j - 1] - T[j - 2]
        dT[j] = 2.0 * T[j - 1] + 2.0 * w0 * dT[j - 1] - dT[j - 2]
        d2T[j] = 4.0 * dT[j - 1] + 2.0 * w0 * d2T[j - 1] - d2T[j - 2]
    w1 = dT[s] / d2T[s]
    for j in range(2, s + 1):
        b[j] = d2T[j] / (dT[j] * dT[j])
    b[0] = b[1] = b[2]
    return w0, w1


@jit
def rkc_step(t, y, fy, h, s, law, c, rt, rv, W, cheb, ws):
    """One RKC step of s stages from (t, y), fy = f(t, y): the new state into W[0].

    W (4, n): rows 0–2 the stages' states (rotated), row 3 f at a stage; ``cheb``
    (4, RKC_MAX_STAGES + 1): T_j(w0), T_j'(w0), T_j''(w0) and b_j. Returns the row of W
    holding the result.
    """
    n = y.shape[0]
    w0, w1 = rkc_coefficients(s, cheb)
    T, b = cheb[0], cheb[3]
    # Y1 = y + μ̃₁·h·f(y) (row 1), Y0 = y (row 2)
    mu1 = b[1] * w1
    older, old, new = 2, 1, 0
    for i in range(n):
        W[older, i] = y[i]
        W[old, i] = y[i] + mu1 * h * fy[i]
    c_older, c_old = 0.0, mu1
    for j in range(2, s + 1):
        mu = 2.0 * b[j] * w0 / b[j - 1]
        nu = -b[j] / b[j - 2]
        mut = 2.0 * b[j] * w1 / b[j - 1]
        gt = -(1.0 - b[j - 1] * T[j - 1]) * mut
        rhs(t + c_old * h, W[old], law, c, rt, rv, W[3], ws)
        for i in range(n):
            W[new, i] = (
                (1.0 - mu - nu) * y[i] + mu * W[old, i] + nu * W[older, i]
                + h * (mut * W[3, i] + gt * fy[i])
            )  # fmt: skip
        c_new = mu * c_old + nu * c_older + mut + gt
        c_older, c_old = c_old, c_new
        older, old, new = old, new, older
    return old


@jit
def rkc_tail(t, y, f, h_abs, t_eval, i_out, atol, rtol, max_step, budget, law, c, rt, rv,
             dense, out_y, ws):  # fmt: skip
    """RKC from (t, y), f = f(t, y), to t_eval's end, or until DOP853 would cost less.

    ``h_abs``: the first step to try [s]; ``budget``: the steps (accepted or not) left
    of the run's ``max_steps``; ``dense``: the outputs t_eval[i_out …] inside each step
    into out_y. y and f are left at the point reached. Returns (status, coordinate,
    evaluations, steps, i_out, t, h_abs, done): done when the end is reached; else
    DOP853 goes on from t with the step h_abs (when status is STATUS_OK).
    """
    n = y.shape[0]
    T_out = t_eval.shape[0]
    t_bound = t_eval[T_out - 1]
    W = np.empty((4, n))
    cheb = np.empty((4, RKC_MAX_STAGES + 1))
    v = np.zeros(n)
    z = np.empty(n)
    fz = np.empty(n)
    f_new = np.empty(n)
    for i in range(n):
        v[i] = 1.0
    rho, evals = rkc_rho(t, y, f, v, law, c, rt, rv, z, fz, ws)
    steps = 0
    since = 0
    while True:
        if not math.isfinite(rho):
            return STATUS_OK, -1, evals, steps, i_out, t, h_abs, False
        if steps >= budget:
            return STATUS_MAX_STEPS, 0, evals, steps, i_out, t, h_abs, False
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        h = min(h_abs, max_step)
        if h < min_step:
            return STATUS_STEP_UNDERFLOW, 0, evals, steps, i_out, t, h_abs, False
        s, h = rkc_stages(h, rho)
        t_new = t + h
        if t_new - t_bound > 0.0:
            t_new = t_bound
        h = t_new - t
        r = rkc_step(t, y, f, h, s, law, c, rt, rv, W, cheb, ws)
        rhs(t_new, W[r], law, c, rt, rv, f_new, ws)
        evals += s
        steps += 1
        e = 0.0
        worst = 0.0
        limiting = 0
        for i in range(n):
            yn = W[r, i]
            est = 0.8 * (y[i] - yn) + 0.4 * h * (f[i] + f_new[i])
            a = est / (atol[i] + max(abs(y[i]), abs(yn)) * rtol)
            e += a * a
            if not abs(a) <= worst:
                worst = abs(a)
                limiting = i
        err = math.sqrt(e / n)
        if not math.isfinite(err):
            h_abs = h * MIN_FACTOR
            rho, k = rkc_rho(t, y, f, v, law, c, rt, rv, z, fz, ws)
            evals += k
            since = 0
            if not h_abs >= min_step:
                return STATUS_NONFINITE, limiting, evals, steps, i_out, t, h_abs, False
            continue
        if err > 1.0:
            h_abs = h * max(0.1, 0.8 * err ** (-1.0 / 3.0))
            rho, k = rkc_rho(t, y, f, v, law, c, rt, rv, z, fz, ws)
            evals += k
            since = 0
            continue
        if dense:
            while i_out < T_out and t_eval[i_out] <= t_new:
                x = (t_eval[i_out] - t) / h
                x2 = x * x
                x3 = x2 * x
                h00 = 2.0 * x3 - 3.0 * x2 + 1.0
                h10 = x3 - 2.0 * x2 + x
                h01 = 3.0 * x2 - 2.0 * x3
                h11 = x3 - x2
                for i in range(n):
                    out_y[i_out, i] = (
                        h00 * y[i] + h10 * h * f[i] + h01 * W[r, i] + h11 * h * f_new[i]
                    )
                i_out += 1
        for i in range(n):
            y[i] = W[r, i]
            f[i] = f_new[i]
        t = t_new
        factor = 10.0 if err == 0.0 else min(10.0, max(0.1, 0.8 * err ** (-1.0 / 3.0)))
        h_abs = h * factor
        if t - t_bound >= 0.0:
            return STATUS_OK, -1, evals, steps, i_out, t, h_abs, True
        since += 1
        if since == RKC_RHO_EVERY:
            rho, k = rkc_rho(t, y, f, v, law, c, rt, rv, z, fz, ws)
            evals += k
            since = 0
        # Back to DOP853 where its stable step costs fewer evaluations a second (the
        # same rule with or without outputs: keep="final" ends where a trajectory does).
        h_stable = D8_STABLE_H_RHO / rho
        s_next, h_next = rkc_stages(min(h_abs, max_step), rho)
        if (s_next + 1) * h_stable > HAND_BACK * 12.0 * h_next:
            return STATUS_OK, -1, evals, steps, i_out, t, min(h_abs, h_stable), False
