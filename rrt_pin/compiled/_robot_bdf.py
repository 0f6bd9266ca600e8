"""Any robot's implicit BDF: SciPy's ``solve_ivp(method="BDF")`` step for step, in machine code.

Appended by :mod:`rrt_pin.compiled.robot_code` to the module it makes from
:mod:`rrt_pin.compiled._robot_template` (from the line ``# --- bdf ---`` on); above
that line, stubs stand in for the template's functions it calls, so that this file
reads (and lints) as Python; it is never imported to run.

:func:`bdf` is ``scipy/integrate/_ivp/bdf.py`` with ``solve_ivp``'s outputs, its
decisions in the same order: the first step of ``select_initial_step`` (order 1), the
numerical differentiation formulas (NDF) of orders 1 … 5 with Klopfenstein and
Shampine's κ, the backward differences D of the interpolating polynomial rescaled on
every change of the step (``change_D``), the simplified Newton iteration of at most 4
iterations on an LU of I − c·J (c = h/α_k) with its convergence-rate test, the
Jacobian kept across steps and evaluated again (at the predicted state) only when
Newton fails with an old one, the LU kept while the step size is, a failed Newton
halving the step, the error estimate error_const[k]·d in SciPy's RMS norm with the
safety factor 0.9·9/(8 + Newton iterations), the order changed by one after k + 1
equal steps from the errors at orders k − 1, k, k + 1, and the outputs from SciPy's
dense output of D at each output time inside the step just taken. The last digits
differ from SciPy's (its BLAS and LAPACK sum in another order, and the generated
Jacobian's I − c·J is solved by its blocks: J = [[0, I], [A, B]], an LU of
I − c·B − c²·A of nv rows, :func:`bdf_schur`); the steps do not, given the same Jacobian.

The Jacobian ∂ẏ/∂y: under PD plus gravity with no physical model applied, the
generated one (``closed_loop_jac``: the loop's q̈ differentiated along q and q̇, the
law's derivatives included, :func:`rrt_pin.dynamics.forward_derivatives_source.closed_loop_derivatives_source`),
as ``jac=`` gives SciPy the Pinocchio backend's (``computeABADerivatives``); for any
other law, for the physical model (saturation, friction, limits), or with
``method == METHOD_BDF_NUMERIC`` (``jacobian="finite-difference"``), SciPy's own
finite differences when ``jac`` is None (``num_jac``: forward differences along each
component, the step's factor adapted from call to call, one evaluation at (t, y)
first as SciPy makes it).

Tolerances are SciPy's: a step is accepted when the RMS norm of its estimated error over
atol_i + rtol·|y_i| (y the new state) is at most 1 [rad, m, rad/s, m/s]. A step that
must fall below 10 units of roundoff of t ends the run with ``STATUS_STEP_UNDERFLOW``
(``STATUS_NONFINITE`` when the evaluations that failed were not finite), the step
budget (accepted and rejected steps) with ``STATUS_MAX_STEPS``.
"""

import math

import numpy as np


def jit(f):  # the module's header defines numba's
    return f


def rhs(t, y, law, c, rt, rv, out, ws):  # the template's: ẏ of the closed loop into out
    raise NotImplementedError


def first_nonfinite(v):  # the template's: index of the first non-finite entry, or -1
    raise NotImplementedError


def first_step(t, y, law, c, rt, rv, atol, rtol, order, interval, max_step, f, ytmp, err, scale,
               ws):  # fmt: skip
    raise NotImplementedError  # the template's: SciPy's select_initial_step


def closed_loop_jac(y, c, out):  # generated: q̈ and ∂q̈/∂(q, q̇) of PD + gravity (nv, 1 + 2nv)
    raise NotImplementedError


LAW_PD_GRAVITY = 1
METHOD_BDF_NUMERIC = 4
STATUS_OK, STATUS_NONFINITE, STATUS_STEP_UNDERFLOW, STATUS_MAX_STEPS = 0, 1, 2, 4
# --- bdf ---

BDF_MAX_ORDER = 5
BDF_NEWTON_MAXITER = 4
BDF_MIN_FACTOR = 0.2
BDF_MAX_FACTOR = 10.0
BDF_EPS = np.finfo(float).eps
#: SciPy's constants, computed as scipy/integrate/_ivp/bdf.py computes them.
BDF_KAPPA = np.array([0, -0.1850, -1 / 9, -0.0823, -0.0415, 0])
BDF_GAMMA = np.hstack((0, np.cumsum(1 / np.arange(1, BDF_MAX_ORDER + 1))))
BDF_ALPHA = (1 - BDF_KAPPA) * BDF_GAMMA
BDF_ERROR_CONST = BDF_KAPPA * BDF_GAMMA + 1 / np.arange(1, BDF_MAX_ORDER + 2)
#: scipy/integrate/_ivp/common.py's constants of ``num_jac``.
BDF_DIFF_REJECT = BDF_EPS**0.875
BDF_DIFF_SMALL = BDF_EPS**0.75
BDF_DIFF_BIG = BDF_EPS**0.25
BDF_MIN_JAC_FACTOR = 1e3 * BDF_EPS


@jit
def no_closed_loop_jac(y, c, out):
    """NaN: stands for ``closed_loop_jac`` where BDF's Jacobian is always numerical.

    In ``run_bdf_num`` and ``run_bdf_num_pd``: nothing generated to compile.
    """
    for i in range(out.shape[0]):
        for j in range(out.shape[1]):
            out[i, j] = math.nan


@jit
def bdf_rms(v, scale):
    """SciPy's ``norm(v / scale)``: ‖v / scale‖₂ / √n."""
    s = 0.0
    for i in range(v.shape[0]):
        x = v[i] / scale[i]
        s += x * x
    return math.sqrt(s) / math.sqrt(v.shape[0])


@jit
def bdf_compute_r(order, factor, R):
    """SciPy's ``compute_R`` into R[:order + 1, :order + 1]."""
    for j in range(order + 1):
        R[0, j] = 1.0
    for i in range(1, order + 1):
        R[i, 0] = 0.0
        for j in range(1, order + 1):
            R[i, j] = R[i - 1, j] * ((i - 1 - factor * j) / i)


@jit
def bdf_change_d(D, order, factor, R, U, tmp):
    """SciPy's ``change_D``: D[:order + 1] = (R·U)ᵀ·D[:order + 1] for a step times ``factor``."""
    bdf_compute_r(order, factor, R)
    bdf_compute_r(order, 1.0, U)
    n = D.shape[1]
    for i in range(order + 1):  # tmp[i] = Σ_k (R·U)[k, i]·D[k]
        for x in range(n):
            tmp[i, x] = 0.0
        for k in range(order + 1):
            ru = 0.0
            for m in range(order + 1):
                ru += R[k, m] * U[m, i]
            for x in range(n):
                tmp[i, x] += ru * D[k, x]
    for i in range(order + 1):
        for x in range(n):
            D[i, x] = tmp[i, x]


@jit
def bdf_lu(A, piv):
    """A = P·L·U in place (LAPACK's getrf: partial pivoting, the first largest |pivot|)."""
    n = A.shape[0]
    for k in range(n):
        p = k
        big = abs(A[k, k])
        for i in range(k + 1, n):
            if abs(A[i, k]) > big:
                big = abs(A[i, k])
                p = i
        piv[k] = p
        if p != k:
            for j in range(n):
                A[k, j], A[p, j] = A[p, j], A[k, j]
        pivot = A[k, k]
        if pivot != 0.0:
            r = 1.0 / pivot
            for i in range(k + 1, n):
                A[i, k] *= r
        for i in range(k + 1, n):
            a = A[i, k]
            if a != 0.0:
                for j in range(k + 1, n):
                    A[i, j] -= a * A[k, j]


@jit
def bdf_solve(LU, piv, b):
    """Solve A·x = b in place (x into ``b``) from :func:`bdf_lu`'s factors (LAPACK's getrs)."""
    n = b.shape[0]
    for k in range(n):
        p = piv[k]
        if p != k:
            b[k], b[p] = b[p], b[k]
    for i in range(1, n):
        s = b[i]
        for j in range(i):
            s -= LU[i, j] * b[j]
        b[i] = s
    for i in range(n - 1, -1, -1):
        s = b[i]
        for j in range(i + 1, n):
            s -= LU[i, j] * b[j]
        b[i] = s / LU[i, i]


@jit
def bdf_schur(J, c, S, piv):
    """The LU of S = I − c·B − c²·A (nv, nv): I − c·J's by its blocks (J = [[0, I], [A, B]]).

    (I − c·J)·(x₁, x₂) = (b₁, b₂) is x₂ = S⁻¹·(b₂ + c·A·b₁), x₁ = b₁ + c·x₂
    (:func:`bdf_solve_blocks`): an LU of nv rows instead of 2·nv, the same solution to
    rounding. Only for a J whose upper blocks are exactly 0 and I (the generated one).
    """
    nv = S.shape[0]
    cc = c * c
    for i in range(nv):
        for j in range(nv):
            S[i, j] = (1.0 if i == j else 0.0) - c * J[nv + i, nv + j] - cc * J[nv + i, j]
    bdf_lu(S, piv)


@jit
def bdf_solve_blocks(S, piv, J, c, b, r):
    """Solve (I − c·J)·x = b in place from :func:`bdf_schur`'s factors; ``r`` (≥ nv,) scratch."""
    nv = S.shape[0]
    for i in range(nv):
        s = b[nv + i]
        for j in range(nv):
            s += c * J[nv + i, j] * b[j]
        r[i] = s
    for k in range(nv):
        p = piv[k]
        if p != k:
            r[k], r[p] = r[p], r[k]
    for i in range(1, nv):
        s = r[i]
        for j in range(i):
            s -= S[i, j] * r[j]
        r[i] = s
    for i in range(nv - 1, -1, -1):
        s = r[i]
        for j in range(i + 1, nv):
            s -= S[i, j] * r[j]
        r[i] = s / S[i, i]
    for i in range(nv):
        b[nv + i] = r[i]
        b[i] = b[i] + c * r[i]


@jit
def bdf_difference(f, col):
    """Make ``col`` = ẏ(y + h·e_j) − f; (its largest |entry|, the scale at that row).

    num_jac's: the row of the first largest |difference| (NumPy's argmax: a NaN first),
    the scale max(|f|, |ẏ(y + h·e_j)|) there.
    """
    at = 0
    biggest = -1.0
    f_new = 0.0
    for i in range(f.shape[0]):
        new = col[i]
        col[i] = new - f[i]
        a = abs(col[i])
        if a > biggest or (a != a and biggest == biggest):
            biggest = a
            at = i
            f_new = new
    return biggest, max(abs(f[at]), abs(f_new))


@jit
def bdf_jacobian(t, y, law, c, rt, rv, numeric, atol, J, factor, f, col, again, ytmp, jw, ws):
    """∂ẏ/∂y at (t, y) into J (n, n): generated, or SciPy's ``num_jac``. Returns evaluations.

    ``factor`` (n,): num_jac's step factors, kept from call to call (√eps at first);
    ``f``, ``col``, ``again``, ``ytmp`` (n,) and ``jw`` (nv, 1 + n): scratch.
    """
    n = y.shape[0]
    nv = n // 2
    if not numeric:
        closed_loop_jac(y, c, jw)
        for i in range(nv):
            for j in range(n):
                J[i, j] = 1.0 if j == nv + i else 0.0
                J[nv + i, j] = jw[i, 1 + j]
        return 0
    rhs(t, y, law, c, rt, rv, f, ws)  # SciPy's jac_wrapped: f = fun_single(t, y)
    evals = 1
    for j in range(n):
        sign = 1.0 if f[j] >= 0.0 else -1.0
        y_scale = sign * max(atol[j], abs(y[j]))
        h = (y[j] + factor[j] * y_scale) - y[j]
        while h == 0.0:
            factor[j] *= 10.0
            h = (y[j] + factor[j] * y_scale) - y[j]
        for i in range(n):
            ytmp[i] = y[i]
        ytmp[j] = y[j] + h
        rhs(t, ytmp, law, c, rt, rv, col, ws)
        evals += 1
        max_diff, scale = bdf_difference(f, col)
        if max_diff < BDF_DIFF_REJECT * scale:  # too small against rounding: 10× the step
            new_factor = 10.0 * factor[j]
            h_new = (y[j] + new_factor * y_scale) - y[j]
            ytmp[j] = y[j] + h_new
            rhs(t, ytmp, law, c, rt, rv, again, ws)
            evals += 1
            max_diff_new, scale_new = bdf_difference(f, again)
            if max_diff * scale_new < max_diff_new * scale:
                factor[j] = new_factor
                h = h_new
                for i in range(n):
                    col[i] = again[i]
                scale = scale_new
                max_diff = max_diff_new
        for i in range(n):
            J[i, j] = col[i] / h
        if max_diff < BDF_DIFF_SMALL * scale:
            factor[j] *= 10.0
        elif max_diff > BDF_DIFF_BIG * scale:
            factor[j] *= 0.1
        factor[j] = max(factor[j], BDF_MIN_JAC_FACTOR)
    return evals


@jit
def bdf_dense(te, t, h, order, D, out):
    """SciPy's ``BdfDenseOutput`` at ``te`` into ``out`` (n,): the polynomial of D, step h."""
    n = out.shape[0]
    for i in range(n):
        out[i] = 0.0
    p = 1.0
    for j in range(order):
        p *= (te - (t - h * j)) / (h * (1 + j))
        for i in range(n):
            out[i] += D[1 + j, i] * p
    for i in range(n):
        out[i] += D[0, i]


@jit
def bdf(method, y0, t_eval, atol, rtol, max_step, max_steps, law, c, rt, rv, dense, out_y, ws):
    """SciPy's BDF from (t_eval[0], y0) to t_eval[-1] (see the module's docstring).

    The arguments and results of the template's ``adaptive``: ``method`` is
    ``METHOD_BDF`` or ``METHOD_BDF_NUMERIC`` (finite differences whatever the law);
    ``dense``, the state at every t_eval into out_y (T, n), else the final one into
    out_y[0]; ``atol`` (n,), ``rtol``: the tolerances; ``max_step`` [s]; ``max_steps``:
    accepted and rejected steps. Returns (status, coordinate, evals, rows, t).
    """
    n = y0.shape[0]
    nv = n // 2
    n_out = t_eval.shape[0]
    tau, work, m, P, phys = ws
    numeric = method == METHOD_BDF_NUMERIC or law != LAW_PD_GRAVITY or phys[0] != 0
    y = y0.copy()
    f = np.empty(n)
    ytmp = np.empty(n)
    err = np.empty(n)
    scale = np.empty(n)
    y_predict = np.empty(n)
    y_new = np.empty(n)
    psi = np.empty(n)
    d = np.empty(n)
    dy = np.empty(n)
    col = np.empty(n)
    factor = np.full(n, BDF_EPS**0.5)
    D = np.zeros((BDF_MAX_ORDER + 3, n))
    tmp = np.empty((BDF_MAX_ORDER + 3, n))
    R = np.empty((BDF_MAX_ORDER + 1, BDF_MAX_ORDER + 1))
    U = np.empty((BDF_MAX_ORDER + 1, BDF_MAX_ORDER + 1))
    J = np.empty((n, n))
    LU = np.empty((n, n))
    piv = np.empty(n, dtype=np.int64)
    S = np.empty((nv, nv))
    pivs = np.empty(nv, dtype=np.int64)
    c_lu = 0.0
    jw = np.empty((nv, 1 + n))
    t = t_eval[0]
    t_bound = t_eval[n_out - 1]
    status, k, n_evals, h_abs_self = first_step(
        t, y, law, c, rt, rv, atol, rtol, 1.0, t_bound - t, max_step, f, ytmp, err, scale, ws
    )
    if status != STATUS_OK:
        return status, k, n_evals, 0, h_abs_self
    newton_tol = max(10.0 * BDF_EPS / rtol, min(0.03, rtol**0.5))
    n_evals += bdf_jacobian(
        t, y, law, c, rt, rv, numeric, atol, J, factor, ytmp, col, dy, err, jw, ws
    )
    bad = first_nonfinite(J.ravel())
    if bad >= 0:
        return STATUS_NONFINITE, bad // n, n_evals, 0, t
    for i in range(n):
        D[0, i] = y[i]
        D[1, i] = f[i] * h_abs_self
    order = 1
    n_equal_steps = 0
    have_lu = False
    n_steps = 0
    i_out = 0
    limiting = 0
    failed_nonfinite = -1
    while True:
        # ---- _step_impl
        min_step = 10.0 * abs(np.nextafter(t, np.inf) - t)
        if h_abs_self > max_step:
            h_abs = max_step
            bdf_change_d(D, order, max_step / h_abs_self, R, U, tmp)
            n_equal_steps = 0
        elif h_abs_self < min_step:
            h_abs = min_step
            bdf_change_d(D, order, min_step / h_abs_self, R, U, tmp)
            n_equal_steps = 0
        else:
            h_abs = h_abs_self
        current_jac = False
        accepted = False
        n_iter = 0
        t_new = t
        while not accepted:
            if h_abs < min_step:
                if failed_nonfinite >= 0:
                    return STATUS_NONFINITE, failed_nonfinite, n_evals, i_out, t
                return STATUS_STEP_UNDERFLOW, limiting, n_evals, i_out, t
            if n_steps >= max_steps:
                return STATUS_MAX_STEPS, limiting, n_evals, i_out, t
            n_steps += 1
            h = h_abs
            t_new = t + h
            if t_new - t_bound > 0.0:
                t_new = t_bound
                bdf_change_d(D, order, abs(t_new - t) / h_abs, R, U, tmp)
                n_equal_steps = 0
                have_lu = False
            h = t_new - t
            h_abs = abs(h)
            for i in range(n):
                s = 0.0
                for j in range(order + 1):
                    s += D[j, i]
                y_predict[i] = s
                scale[i] = atol[i] + rtol * abs(s)
                p = 0.0
                for j in range(1, order + 1):
                    p += D[j, i] * BDF_GAMMA[j]
                psi[i] = p / BDF_ALPHA[order]
            converged = False
            cc = h / BDF_ALPHA[order]
            while not converged:
                if not have_lu:
                    c_lu = cc
                    if numeric:
                        for i in range(n):
                            for j in range(n):
                                LU[i, j] = (1.0 if i == j else 0.0) - cc * J[i, j]
                        bdf_lu(LU, piv)
                    else:
                        bdf_schur(J, cc, S, pivs)
                    have_lu = True
                # ---- solve_bdf_system
                for i in range(n):
                    y_new[i] = y_predict[i]
                    d[i] = 0.0
                dy_norm_old = 0.0
                have_old = False
                converged = False
                kk = 0
                for kk in range(BDF_NEWTON_MAXITER):
                    rhs(t_new, y_new, law, c, rt, rv, f, ws)
                    n_evals += 1
                    bad = first_nonfinite(f)
                    if bad >= 0:
                        failed_nonfinite = bad
                        break
                    for i in range(n):
                        dy[i] = cc * f[i] - psi[i] - d[i]
                    if numeric:
                        bdf_solve(LU, piv, dy)
                    else:
                        bdf_solve_blocks(S, pivs, J, c_lu, dy, ytmp)
                    dy_norm = bdf_rms(dy, scale)
                    rate = 0.0
                    if have_old:
                        rate = dy_norm / dy_norm_old
                        if rate >= 1.0 or (
                            rate ** (BDF_NEWTON_MAXITER - kk) / (1.0 - rate) * dy_norm > newton_tol
                        ):
                            break
                    for i in range(n):
                        y_new[i] += dy[i]
                        d[i] += dy[i]
                    if dy_norm == 0.0 or (have_old and rate / (1.0 - rate) * dy_norm < newton_tol):
                        converged = True
                        break
                    dy_norm_old = dy_norm
                    have_old = True
                n_iter = kk + 1
                if not converged:
                    if current_jac:
                        break
                    n_evals += bdf_jacobian(
                        t_new, y_predict, law, c, rt, rv, numeric, atol, J, factor, ytmp, col,
                        dy, err, jw, ws,
                    )  # fmt: skip
                    bad = first_nonfinite(J.ravel())
                    if bad >= 0:
                        return STATUS_NONFINITE, bad // n, n_evals, i_out, t
                    have_lu = False
                    current_jac = True
            if not converged:
                h_abs *= 0.5
                bdf_change_d(D, order, 0.5, R, U, tmp)
                n_equal_steps = 0
                have_lu = False
                continue
            failed_nonfinite = -1
            safety = 0.9 * (2 * BDF_NEWTON_MAXITER + 1) / (2 * BDF_NEWTON_MAXITER + n_iter)
            worst = -1.0
            for i in range(n):
                scale[i] = atol[i] + rtol * abs(y_new[i])
                err[i] = BDF_ERROR_CONST[order] * d[i]
                e = abs(err[i] / scale[i])
                if e > worst:
                    worst = e
                    limiting = i
            error_norm = bdf_rms(err, scale)
            if error_norm > 1.0:
                fac = max(BDF_MIN_FACTOR, safety * error_norm ** (-1.0 / (order + 1)))
                h_abs *= fac
                bdf_change_d(D, order, fac, R, U, tmp)
                n_equal_steps = 0
            else:
                accepted = True
        bad = first_nonfinite(y_new)
        if bad >= 0:
            return STATUS_NONFINITE, bad, n_evals, i_out, t_new
        n_equal_steps += 1
        t = t_new
        for i in range(n):
            y[i] = y_new[i]
        h_abs_self = h_abs
        for i in range(n):
            D[order + 2, i] = d[i] - D[order + 1, i]
            D[order + 1, i] = d[i]
        for j in range(order, -1, -1):
            for i in range(n):
                D[j, i] += D[j + 1, i]
        if n_equal_steps >= order + 1:
            error_m_norm = math.inf
            error_p_norm = math.inf
            if order > 1:
                for i in range(n):
                    err[i] = BDF_ERROR_CONST[order - 1] * D[order, i]
                error_m_norm = bdf_rms(err, scale)
            if order < BDF_MAX_ORDER:
                for i in range(n):
                    err[i] = BDF_ERROR_CONST[order + 1] * D[order + 2, i]
                error_p_norm = bdf_rms(err, scale)
            best = -1
            biggest = -1.0
            for j in range(3):
                e = error_m_norm if j == 0 else (error_norm if j == 1 else error_p_norm)
                x = math.inf if e == 0.0 else e ** (-1.0 / (order + j))
                if x > biggest or best < 0:
                    biggest = x
                    best = j
            order += best - 1
            fac = min(BDF_MAX_FACTOR, safety * biggest)
            h_abs_self *= fac
            bdf_change_d(D, order, fac, R, U, tmp)
            n_equal_steps = 0
            have_lu = False
        # ---- solve_ivp's outputs: SciPy's BdfDenseOutput of this step (the final state
        # too: D[0], which rounds otherwise than y)
        if dense:
            while i_out < n_out and t_eval[i_out] <= t:
                bdf_dense(t_eval[i_out], t, h_abs_self, order, D, out_y[i_out])
                i_out += 1
        if t - t_bound >= 0.0:
            if not dense:
                bdf_dense(t_bound, t, h_abs_self, order, D, out_y[0])
                i_out = 1
            return STATUS_OK, -1, n_evals, i_out, t
