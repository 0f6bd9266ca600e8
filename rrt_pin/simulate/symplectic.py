"""A symplectic integrator for mechanical systems with a configuration-dependent mass matrix.

Störmer–Verlet in canonical variables (the generalized leapfrog; Hairer, Lubich
and Wanner, *Geometric Numerical Integration*, VI.3): with the momentum
p = M(q)·q̇ and the Hamiltonian H(q, p) = ½·pᵀ·M(q)⁻¹·p + V(q),

    p½  = p₀ − h/2 · H_q(q₀, p½)                      (implicit in p½)
    q₁  = q₀ + h/2 · (H_p(q₀, p½) + H_p(q₁, p½))      (implicit in q₁)
    p₁  = p½ − h/2 · H_q(q₁, p½)

where H_p = M⁻¹·p = q̇ and −H_q = ∂L/∂q = C(q, q̇)ᵀ·q̇ − G(q) (Pinocchio's
Coriolis matrix satisfies Ṁ = C + Cᵀ, so d/dt(M·q̇) = M·q̈ + Ṁ·q̇ = Cᵀ·q̇ − G
when τ = 0). The method is second order, time-symmetric and symplectic for
any H, so the energy error of passive motion stays bounded, without secular
drift, over long runs — which the (q, q̇) velocity Verlet of
:mod:`rrt_pin.simulate.integrators` does not guarantee when M depends on q. Efforts
τ(q, q̇) may be added to ṗ; the method is then symplectic only when they are
zero or derive from a potential. Units: q [rad, m], q̇ [rad/s, m/s], p
[kg·m²/s, kg·m/s], h [s].
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core.errors import DivergenceError, InputError

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = ["LeapfrogResult", "leapfrog", "mechanical_energy"]

#: Fixed-point iterations stop at this relative change …
TOL = 1e-14
#: … or fail after this many (the step is too long).
MAX_ITER = 60


@dataclass(frozen=True, eq=False)
class LeapfrogResult:
    """States at the output times.

    Attributes:
        t: output times [s].
        q: positions (len(t), nv) [rad, m].
        qd: velocities (len(t), nv) [rad/s, m/s].
        n_evals: evaluations of H_q or H_p (each a Pinocchio CRBA and maybe a Coriolis matrix).
        n_steps: steps taken.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    n_evals: int
    n_steps: int


def mechanical_energy(model: pin.Model, q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """T + V along states of shape (N, nv) [J], V from Pinocchio's potential energy."""
    import pinocchio as pin

    data = model.createData()
    return np.array(
        [
            pin.computeKineticEnergy(model, data, a, b) + pin.computePotentialEnergy(model, data, a)
            for a, b in zip(np.atleast_2d(q), np.atleast_2d(qd), strict=True)
        ]
    )


def leapfrog(
    model: pin.Model,
    q0: np.ndarray,
    qd0: np.ndarray,
    t_eval: np.ndarray,
    step: float,
    efforts: Callable[[float, np.ndarray, np.ndarray], np.ndarray] | None = None,
    names: Sequence[str] | None = None,
    configuration: Callable[[np.ndarray], np.ndarray] | None = None,
) -> LeapfrogResult:
    """Integrate with the canonical Störmer–Verlet method, landing on ``t_eval``.

    Args:
        model: a Pinocchio model (nq = nv, or ``configuration`` maps joint
            coordinates to its configuration vector).
        q0: initial positions [rad, m].
        qd0: initial velocities [rad/s, m/s].
        t_eval: increasing output times [s]; the first is the initial time.
        step: largest step [s]; each interval between output times is split
            into equal steps no longer than this.
        efforts: optional τ(t, q, q̇) [N·m, N] added to ṗ (zero when None).
        names: the 2·nv coordinate names used in errors (default q1…, qd1…).
        configuration: joint coordinates (nv,) -> Pinocchio's q (nq,) (e.g.
            :meth:`rrt_pin.robot.robot.Robot.configuration` for continuous joints).

    Raises:
        InputError: bad shapes, non-finite values, a non-positive step.
        DivergenceError: a non-finite state, or the implicit stages do not
            converge (the step is too long), with the time and coordinate.
    """
    import pinocchio as pin

    t_eval = np.asarray(t_eval, dtype=float)
    q = np.array(q0, dtype=float)
    qd = np.array(qd0, dtype=float)
    pin_q = configuration if configuration is not None else (lambda x: x)
    if (
        q.shape != (model.nv,)
        or qd.shape != (model.nv,)
        or (model.nq != model.nv and configuration is None)
    ):
        raise InputError(f"{q.shape=} and {qd.shape=} must be ({model.nv},) with nq = nv")
    if not (np.isfinite(q).all() and np.isfinite(qd).all() and np.isfinite(t_eval).all()):
        raise InputError("q0, qd0 and t_eval must be finite")
    if t_eval.ndim != 1 or t_eval.size < 1 or np.any(np.diff(t_eval) <= 0):
        raise InputError("t_eval must be a strictly increasing 1-D array [s]")
    if not (np.isfinite(step) and step > 0):
        raise InputError(f"step={float(step):.6g} must be > 0 [s]")
    data = model.createData()
    if names is None:
        names = [f"q{i + 1}" for i in range(model.nv)] + [f"qd{i + 1}" for i in range(model.nv)]
    n_evals = 0

    def mass(qq: np.ndarray) -> np.ndarray:
        M = pin.crba(model, data, pin_q(qq))
        return np.triu(M) + np.triu(M, 1).T

    def dLdq(qq: np.ndarray, vv: np.ndarray, tt: float) -> np.ndarray:
        x = pin_q(qq)
        C = pin.computeCoriolisMatrix(model, data, x, vv)
        out = C.T @ vv - pin.computeGeneralizedGravity(model, data, x)
        if efforts is not None:
            out = out + np.asarray(efforts(tt, qq, vv), dtype=float)
        return out

    def fail(t: float, q_: np.ndarray, p_: np.ndarray, what: str) -> None:
        x = np.concatenate([q_, p_])  # a non-finite momentum is a non-finite velocity
        bad = np.flatnonzero(~np.isfinite(x))
        if bad.size:
            inf = [i for i in bad if np.isinf(x[i])]
            raise DivergenceError(
                t, names[(inf or bad)[0]], f"the state became non-finite ({what})"
            )
        raise DivergenceError(t, "all coordinates", what)

    def converged(new: np.ndarray, old: np.ndarray) -> bool:
        return bool(np.abs(new - old).max() <= TOL * (1.0 + np.abs(new).max()))

    p = mass(q) @ qd
    out_q = np.empty((t_eval.size, model.nv))
    out_v = np.empty((t_eval.size, model.nv))
    out_q[0], out_v[0] = q, qd
    n_steps = 0
    for k in range(1, t_eval.size):
        span = t_eval[k] - t_eval[k - 1]
        n = max(1, int(np.ceil(span / step - 1e-9)))
        h = span / n
        for i in range(n):
            t = t_eval[k - 1] + i * h
            M0 = mass(q)
            ph = p
            for _ in range(MAX_ITER):
                v0 = np.linalg.solve(M0, ph)
                new = p + 0.5 * h * dLdq(q, v0, t)
                n_evals += 1
                if not np.isfinite(new).all():
                    fail(t, q, new, "momentum stage")
                done = converged(new, ph)
                ph = new
                if done:
                    break
            else:
                fail(t, q, ph, f"the momentum stage did not converge with step {h:.6g} s")
            v0 = np.linalg.solve(M0, ph)
            q1 = q + h * v0
            for _ in range(MAX_ITER):
                new = q + 0.5 * h * (v0 + np.linalg.solve(mass(q1), ph))
                n_evals += 1
                if not np.isfinite(new).all():
                    fail(t, new, ph, "position stage")
                done = converged(new, q1)
                q1 = new
                if done:
                    break
            else:
                fail(t, q1, ph, f"the position stage did not converge with step {h:.6g} s")
            v1 = np.linalg.solve(mass(q1), ph)
            p = ph + 0.5 * h * dLdq(q1, v1, t + h)
            n_evals += 1
            q = q1
            if not (np.isfinite(q).all() and np.isfinite(p).all()):
                fail(t + h, q, p, "last kick")
            n_steps += 1
        out_q[k] = q
        out_v[k] = np.linalg.solve(mass(q), p)
    return LeapfrogResult(t_eval, out_q, out_v, n_evals, n_steps)
