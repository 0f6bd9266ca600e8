"""Any robot's variable-step, variable-order Adams method: Shampine and Gordon's DE/STEP/INTRP.

Appended by :mod:`rrt_pin.compiled.robot_code` to the module it makes from
:mod:`rrt_pin.compiled._robot_template` (from the line ``# --- adams ---`` on); above
that line, stubs stand in for the template's functions it calls, so that this file
reads (and lints) as Python; it is never imported to run.

:func:`adams` is the algorithm of Shampine and Gordon's ``ode.f`` (netlib ``ode``;
SLATEC's DSTEPS and DINTP are the same; *Computer Solution of Ordinary Differential
Equations: the Initial Value Problem*, 1975), its decisions in the same order (it
multiplies by 1/w and 1/ψ where ode.f divides: the last digits differ): Adams PECE in modified
divided differences, orders 1 … 12, local extrapolation, the step size halved, kept
or doubled (or set from the error when it must shrink), the order raised in the
starting phase and then chosen from the estimated errors at orders k − 2 … k + 1,
the roundoff control (summation of the propagated rounding) of tight tolerances.
It is explicit: on a stiff closed loop (high gains against light links) its steps
are held by its stability, not by the tolerance.
A step costs two evaluations of the template's ``rhs`` (every law, the physical
model); a rejected step one. The outputs are the method's own interpolating
polynomial (INTRP) at each ``t_eval`` inside the step just taken: the steps never
land on the outputs, only the last one on the final time.

Tolerances (ode.f's weights per component): a step is accepted when the Euclidean
norm over the components i of e_i / (rtol·|y_i| + atol_i) is at most 1, e_i its
estimated local error and y_i the state at the step's start [rad, m, rad/s, m/s].
(ode.f states it as ‖e / w‖ ≤ eps with eps = max(rtol, atol) and
w = (rtol·|y| + atol) / eps: the same test.) A tolerance too tight for float64 at the
current state, which ode.f answers by loosening it, ends the run here with
``STATUS_STEP_UNDERFLOW``, as does a step below four units of roundoff of t.
"""

import math

import numpy as np


def jit(f):  # the module's header defines numba's
    return f


def rhs(t, y, law, c, rt, rv, out, ws):  # the template's: ẏ of the closed loop into out
    raise NotImplementedError


def first_nonfinite(v):  # the template's: index of the first non-finite entry, or -1
    raise NotImplementedError


STATUS_OK, STATUS_NONFINITE, STATUS_STEP_UNDERFLOW, STATUS_MAX_STEPS = 0, 1, 2, 4
# --- adams ---

#: Unit roundoff of float64 (ode.f's u: 1 + u > 1), twice and four times it.
ADAMS_TWOU = 2.0 * 2.220446049250313e-16
ADAMS_FOURU = 4.0 * 2.220446049250313e-16
#: The highest order.
ADAMS_KMAX = 12
#: ode.f's constants, 1-based as there (entry 0 unused): 2^k and the error constants.
ADAMS_TWO = np.array([0.0] + [2.0**k for k in range(1, 14)])
ADAMS_GSTR = np.array(
    [0.0, 0.5, 0.0833, 0.0417, 0.0264, 0.0188, 0.0143, 0.0114, 0.00936, 0.00789,
     0.00679, 0.00592, 0.00524, 0.00468]
)  # fmt: skip
#: 1/i, i = 1 … 13 (entry 0 unused): INTRP's first w.
ADAMS_INV = np.array([0.0] + [1.0 / i for i in range(1, 14)])


@jit
def adams_intrp(x, y, xout, out_y, row, kold, phi, psi, rpsi, w, g):
    """INTRP: the solution at ``xout`` into out_y[row], from the polynomial of the last step.

    ``x``, ``y``: the step's end and the solution there; ``kold`` its order; ``phi``
    (17, n) and ``psi`` (13,) the differences and step history the step left, ``rpsi``
    1/psi (a step's outputs share it: multiplications instead of divisions); ``w``,
    ``g`` (14,) scratch.
    """
    n = y.shape[0]
    hi = xout - x
    ki = kold + 1
    kip1 = ki + 1
    for i in range(1, ki + 1):
        w[i] = ADAMS_INV[i]
    g[1] = 1.0
    term = 0.0
    for j in range(2, ki + 1):
        gamma = (hi + term) * rpsi[j - 1]
        eta = hi * rpsi[j - 1]
        for i in range(1, kip1 - j + 1):
            w[i] = gamma * w[i] - eta * w[i + 1]
        g[j] = w[1]
        term = psi[j - 1]
    for ix in range(n):
        out_y[row, ix] = 0.0
    for j in range(1, ki + 1):
        i = kip1 - j
        gi = g[i]
        for ix in range(n):
            out_y[row, ix] += gi * phi[i, ix]
    for ix in range(n):
        out_y[row, ix] = y[ix] + hi * out_y[row, ix]


@jit
def adams_limiting(yp, phi, iw):
    """The component of the largest weighted local error (the first non-finite one first).

    ``iw``: the inverse weights (n,).
    """
    worst, at = -1.0, 0
    for ix in range(yp.shape[0]):
        e = abs((yp[ix] - phi[1, ix]) * iw[ix])
        if not math.isfinite(e):
            return ix
        if e > worst:
            worst, at = e, ix
    return at


@jit
def adams(method, y0, t_eval, atol, rtol, max_step, max_steps, law, c, rt, rv, dense, out_y, ws):
    """Shampine and Gordon's Adams method from (t_eval[0], y0) to t_eval[-1].

    The arguments and results of the template's ``adaptive`` (``method`` unused):
    ``dense``, the state at every t_eval into out_y (T, n), else the final one into
    out_y[0]. ``atol`` (n,), ``rtol``: the tolerances (the module's docstring);
    ``max_step`` [s]; ``max_steps``: accepted and rejected steps. Returns (status,
    coordinate, evals, rows, t).
    """
    n = y0.shape[0]
    n_out = t_eval.shape[0]
    yy = y0.copy()
    p = np.empty(n)
    yp = np.empty(n)
    iw = np.empty(n)  # 1 / ode.f's weights
    abseps = np.empty(n)
    phi = np.zeros((17, n))
    psi = np.zeros(13)
    alpha = np.zeros(13)
    beta = np.zeros(13)
    sig = np.zeros(14)
    v = np.zeros(13)
    w = np.zeros(13)
    g = np.zeros(14)
    wi = np.zeros(14)
    gi = np.zeros(14)
    rpsi = np.zeros(13)
    x = t_eval[0]
    t_bound = t_eval[n_out - 1]
    eps = rtol
    for ix in range(n):
        eps = max(eps, atol[ix])
    if not eps > 0.0:
        return STATUS_STEP_UNDERFLOW, 0, 0, 0, x
    releps = rtol / eps
    for ix in range(n):
        abseps[ix] = atol[ix] / eps
    p5eps = 0.5 * eps
    fouru, twou = ADAMS_FOURU, ADAMS_TWOU
    h = max(t_bound - x, fouru * abs(x))
    start = True
    hold = 0.0
    k = 1
    kold = 0
    ns = 0
    phase1 = True
    nornd = True
    n_evals = 0
    n_steps = 0
    i_out = 0
    if dense:
        while i_out < n_out and t_eval[i_out] <= x:
            for ix in range(n):
                out_y[i_out, ix] = yy[ix]
            i_out += 1
    while t_bound - x > fouru * abs(x):
        if n_steps >= max_steps:
            return STATUS_MAX_STEPS, adams_limiting(yp, phi, iw), n_evals, i_out, x
        h = min(h, t_bound - x, max_step)
        for ix in range(n):
            iw[ix] = 1.0 / max(releps * abs(yy[ix]) + abseps[ix], 1e-300)
        # ---- STEP, block 0: a step or tolerance too small; the first step's size
        if h < fouru * abs(x):
            return STATUS_STEP_UNDERFLOW, adams_limiting(yp, phi, iw), n_evals, i_out, x
        s = 0.0
        for ix in range(n):
            s += (yy[ix] * iw[ix]) ** 2
        rounding = twou * math.sqrt(s)
        if p5eps < rounding:
            return STATUS_STEP_UNDERFLOW, 0, n_evals, i_out, x
        g[1] = 1.0
        g[2] = 0.5
        sig[1] = 1.0
        if start:
            rhs(x, yy, law, c, rt, rv, yp, ws)
            n_evals += 1
            bad = first_nonfinite(yp)
            if bad >= 0:
                return STATUS_NONFINITE, bad, n_evals, i_out, x
            s = 0.0
            for ix in range(n):
                phi[1, ix] = yp[ix]
                phi[2, ix] = 0.0
                s += (yp[ix] * iw[ix]) ** 2
            s = math.sqrt(s)
            absh = h
            if eps < 16.0 * s * h * h:
                absh = 0.25 * math.sqrt(eps / s)
            h = max(absh, fouru * abs(x))
            hold = 0.0
            k = 1
            kold = 0
            start = False
            phase1 = True
            nornd = True
            if p5eps <= 100.0 * rounding:
                nornd = False
                for ix in range(n):
                    phi[15, ix] = 0.0
        ifail = 0
        erk = erkm1 = 0.0
        knew = k
        while True:
            # ---- block 1: the coefficients of this step (only those that changed)
            kp1 = k + 1
            kp2 = k + 2
            km1 = k - 1
            km2 = k - 2
            if h != hold:
                ns = 0
            if ns <= kold:
                ns += 1
            nsp1 = ns + 1
            if k >= ns:
                beta[ns] = 1.0
                alpha[ns] = 1.0 / ns
                temp1 = h * ns
                sig[nsp1] = 1.0
                for i in range(nsp1, k + 1):
                    temp2 = psi[i - 1]
                    psi[i - 1] = temp1
                    beta[i] = beta[i - 1] * psi[i - 1] / temp2
                    temp1 = temp2 + h
                    alpha[i] = h / temp1
                    sig[i + 1] = i * alpha[i] * sig[i]
                psi[k] = temp1
                if ns <= 1:
                    for iq in range(1, k + 1):
                        v[iq] = 1.0 / (iq * (iq + 1))
                        w[iq] = v[iq]
                else:
                    if k > kold:
                        v[k] = 1.0 / (k * kp1)
                        for j in range(1, ns - 1):
                            i = k - j
                            v[i] = v[i] - alpha[j + 1] * v[i + 1]
                    temp5 = alpha[ns]
                    for iq in range(1, kp1 - ns + 1):
                        v[iq] = v[iq] - temp5 * v[iq + 1]
                        w[iq] = v[iq]
                    g[nsp1] = w[1]
                for i in range(ns + 2, kp1 + 1):
                    temp6 = alpha[i - 1]
                    for iq in range(1, kp2 - i + 1):
                        w[iq] = w[iq] - temp6 * w[iq + 1]
                    g[i] = w[1]
            # ---- block 2: predict, evaluate, estimate the errors at orders k, k-1, k-2
            for i in range(nsp1, k + 1):
                b = beta[i]
                for ix in range(n):
                    phi[i, ix] = b * phi[i, ix]
            for ix in range(n):
                phi[kp2, ix] = phi[kp1, ix]
                phi[kp1, ix] = 0.0
                p[ix] = 0.0
            for j in range(1, k + 1):
                i = kp1 - j
                gj = g[i]
                for ix in range(n):
                    p[ix] = p[ix] + gj * phi[i, ix]
                    phi[i, ix] = phi[i, ix] + phi[i + 1, ix]
            if nornd:
                for ix in range(n):
                    p[ix] = yy[ix] + h * p[ix]
            else:
                for ix in range(n):
                    tau = h * p[ix] - phi[15, ix]
                    p[ix] = yy[ix] + tau
                    phi[16, ix] = (p[ix] - yy[ix]) - tau
            xold = x
            x = x + h
            absh = abs(h)
            rhs(x, p, law, c, rt, rv, yp, ws)
            n_evals += 1
            erkm2 = 0.0
            erkm1 = 0.0
            erk = 0.0
            for ix in range(n):
                temp3 = iw[ix]
                temp4 = yp[ix] - phi[1, ix]
                if km2 > 0:
                    erkm2 += ((phi[km1, ix] + temp4) * temp3) ** 2
                if km2 >= 0:
                    erkm1 += ((phi[k, ix] + temp4) * temp3) ** 2
                erk += (temp4 * temp3) ** 2
            if km2 > 0:
                erkm2 = absh * sig[km1] * ADAMS_GSTR[km2] * math.sqrt(erkm2)
            if km2 >= 0:
                erkm1 = absh * sig[k] * ADAMS_GSTR[km1] * math.sqrt(erkm1)
            temp5 = absh * math.sqrt(erk)
            err = temp5 * (g[k] - g[kp1])
            erk = temp5 * sig[kp1] * ADAMS_GSTR[k]
            knew = k
            if km2 > 0:
                if max(erkm1, erkm2) <= erk:
                    knew = km1
            elif km2 == 0:
                if erkm1 <= 0.5 * erk:
                    knew = km1
            if err <= eps:
                break
            # ---- block 3: rejected (or not finite): restore, halve, order 1 on the third
            limiting = adams_limiting(yp, phi, iw)
            phase1 = False
            x = xold
            for i in range(1, k + 1):
                rb = 1.0 / beta[i]
                for ix in range(n):
                    phi[i, ix] = rb * (phi[i, ix] - phi[i + 1, ix])
            for i in range(2, k + 1):
                psi[i - 1] = psi[i] - h
            ifail += 1
            n_steps += 1
            temp2 = 0.5
            if ifail > 3 and p5eps < 0.25 * erk:
                temp2 = math.sqrt(p5eps / erk)
            if ifail >= 3:
                knew = 1
            h = temp2 * h
            k = knew
            if n_steps >= max_steps:
                return STATUS_MAX_STEPS, limiting, n_evals, i_out, x
            if abs(h) < fouru * abs(x):
                return STATUS_STEP_UNDERFLOW, limiting, n_evals, i_out, x
        # ---- block 4: accepted: correct, evaluate, update; the next order and step
        kold = k
        hold = h
        kp1 = k + 1
        kp2 = k + 2
        km1 = k - 1
        temp1 = h * g[kp1]
        if nornd:
            for ix in range(n):
                yy[ix] = p[ix] + temp1 * (yp[ix] - phi[1, ix])
        else:
            for ix in range(n):
                r = temp1 * (yp[ix] - phi[1, ix]) - phi[16, ix]
                yy[ix] = p[ix] + r
                phi[15, ix] = (yy[ix] - p[ix]) - r
        rhs(x, yy, law, c, rt, rv, yp, ws)
        n_evals += 1
        n_steps += 1
        bad = first_nonfinite(yp)
        if bad >= 0:
            return STATUS_NONFINITE, bad, n_evals, i_out, x
        for ix in range(n):
            phi[kp1, ix] = yp[ix] - phi[1, ix]
            phi[kp2, ix] = phi[kp1, ix] - phi[kp2, ix]
        for i in range(1, k + 1):
            for ix in range(n):
                phi[i, ix] = phi[i, ix] + phi[kp1, ix]
        if knew == km1 or k == ADAMS_KMAX:
            phase1 = False
        if phase1:
            k = kp1
            erk = 0.0
        elif knew == km1:
            k = km1
            erk = erkm1
        elif kp1 <= ns:
            erkp1 = 0.0
            for ix in range(n):
                erkp1 += (phi[kp2, ix] * iw[ix]) ** 2
            erkp1 = absh * ADAMS_GSTR[kp1] * math.sqrt(erkp1)
            if k > 1:
                if erkm1 <= min(erk, erkp1):
                    k = km1
                    erk = erkm1
                elif not (erkp1 >= erk or k == ADAMS_KMAX):
                    k = kp1
                    erk = erkp1
            elif erkp1 < 0.5 * erk:
                k = kp1
                erk = erkp1
        hnew = h + h
        if not phase1 and p5eps < erk * ADAMS_TWO[k + 1]:
            hnew = h
            if p5eps < erk:
                r = (p5eps / erk) ** (1.0 / (k + 1))
                hnew = max(absh * max(0.5, min(0.9, r)), fouru * abs(x))
        h = hnew
        if dense and i_out < n_out and t_eval[i_out] <= x:
            for j in range(1, kold + 1):
                rpsi[j] = 1.0 / psi[j]
            while i_out < n_out and t_eval[i_out] <= x:
                adams_intrp(x, yy, t_eval[i_out], out_y, i_out, kold, phi, psi, rpsi, wi, gi)
                i_out += 1
    # at the final time (to four units of roundoff): the outputs left, from the last step
    first = i_out if dense else n_out - 1
    for j in range(1, kold + 1):
        rpsi[j] = 1.0 / psi[j]
    for j in range(first, n_out):
        row = j if dense else 0
        if kold == 0:
            for ix in range(n):
                out_y[row, ix] = yy[ix]
        else:
            adams_intrp(x, yy, t_eval[j], out_y, row, kold, phi, psi, rpsi, wi, gi)
    return STATUS_OK, -1, n_evals, n_out if dense else 1, t_bound
