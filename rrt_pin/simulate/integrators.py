"""Fixed-step integrators for mechanical systems q̈ = a(t, q, q̇).

Each method advances positions ``q`` [rad or m] and velocities ``v`` [rad/s or m/s]
by a step ``h`` [s]. They work unchanged on one state (arrays of shape (n,)) and
on a batch of states (shape (N, n)), as long as ``acc`` does.

- ``symplectic_euler`` (semi-implicit Euler, 1st order, 1 evaluation per step):
  v₁ = v₀ + h·a(q₀, v₀); q₁ = q₀ + h·v₁.
- ``rk4`` (classical Runge–Kutta, 4th order, 4 evaluations per step).
- ``verlet`` (velocity Verlet / Störmer–Verlet, 2nd order, time-symmetric):
  v½ = v₀ + h/2·a(q₀, v₀); q₁ = q₀ + h·v½; v₁ = v½ + h/2·a(q₁, v₁). When the
  acceleration depends on the velocity (damping, Coriolis), the last half kick is
  implicit and solved by fixed-point iteration; its final evaluation is reused as
  the next step's first kick, so a step costs as many evaluations as iterations.

Both Euler and Verlet are symplectic when written in canonical variables of a
separable system (constant mass matrix, position-only forces), where (q, v) and
(q, p) differ by a constant factor; for the RRT arm (configuration-dependent mass
matrix, velocity feedback) they keep their order and, for Verlet, time symmetry.

Outputs land exactly on the requested times: each interval between consecutive
output times is divided into ceil(interval / step) equal steps (never longer
than ``step``). Every step is checked: a non-finite state raises
:class:`~rrt_pin.core.errors.DivergenceError` naming the time and the coordinate.
"""

from __future__ import annotations

import functools
import importlib
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rrt_pin.core.errors import DivergenceError, InputError
from rrt_pin.simulate import methods

__all__ = ["FixedStepResult", "blame", "integrate_fixed_step", "rk4", "symplectic_euler", "verlet"]

#: a(t, q, v): accelerations from time [s], positions and velocities.
Acceleration = Callable[[float, np.ndarray, np.ndarray], np.ndarray]

#: Fixed-point iterations of Verlet's implicit half kick stop at this relative change.
VERLET_TOL = 1e-14
#: … or fail after this many iterations (the step is too long for the damping).
VERLET_MAX_ITER = 50


@dataclass(frozen=True, eq=False)
class FixedStepResult:
    """States at the output times and the cost.

    Attributes:
        q: positions, shape (len(t), …, n) [rad or m].
        v: velocities, same shape [rad/s or m/s].
        n_evals: evaluations of ``acc`` (each one call, whatever the batch size).
        n_steps: steps taken.
    """

    q: np.ndarray
    v: np.ndarray
    n_evals: int
    n_steps: int


def blame(values: np.ndarray, size: np.ndarray) -> np.ndarray:
    """Scores locating a blow-up in ``values``: the argmax is the entry to name.

    Non-finite entries only; infinite ones before NaNs (a NaN comes from mixing
    infinities); among those, the largest ``size`` (where the growth started).
    """
    infinite = np.isinf(values)
    candidates = infinite if infinite.any() else ~np.isfinite(values)
    return np.where(candidates, np.nan_to_num(size, nan=0.0), -1.0)


class _Stepper:
    """Evaluations of ``acc`` for one method's steps: the count, and Verlet's reusable kick."""

    def __init__(self, method: str, acc: Acceleration) -> None:

        entry = methods.get(method)
        if entry.runner is None:
            raise InputError(f"method={method!r} is not a fixed-step method")
        module, _, name = entry.runner.partition(":")
        self.step = functools.partial(getattr(importlib.import_module(module), name), self)
        self.acc = acc
        self.n_evals = 0
        self.a_last: np.ndarray | None = None

    def eval(self, q: np.ndarray, v: np.ndarray, t: float) -> np.ndarray:
        """a(t, q, v), counted and checked for non-finite values."""
        self.n_evals += 1
        # The stages' states are this integrator's own fresh arrays, never changed in
        # place: read-only, a law reads them without a protective view of its own.
        q.flags.writeable = v.flags.writeable = False
        a = self.acc(t, q, v)
        if not np.isfinite(a).all():
            infinite = np.isinf(a)
            candidates = infinite if infinite.any() else ~np.isfinite(a)
            size = np.abs(np.nan_to_num(q)) + np.abs(np.nan_to_num(v))
            raise _Failure(
                t, np.where(candidates, size, -1.0), "the acceleration became non-finite"
            )
        return a


# One function per method: (stepper, q, v, h, t) -> (q, v) after a step h [s] from time t.
def symplectic_euler(s: _Stepper, q: np.ndarray, v: np.ndarray, h: float, t: float):
    """Semi-implicit Euler: v₁ = v₀ + h·a(q₀, v₀); q₁ = q₀ + h·v₁."""
    v1 = v + h * s.eval(q, v, t)
    return q + h * v1, v1


def rk4(s: _Stepper, q: np.ndarray, v: np.ndarray, h: float, t: float):
    """The classical 4th-order Runge–Kutta step."""
    a1 = s.eval(q, v, t)
    q2, v2 = q + 0.5 * h * v, v + 0.5 * h * a1
    a2 = s.eval(q2, v2, t + 0.5 * h)
    q3, v3 = q + 0.5 * h * v2, v + 0.5 * h * a2
    a3 = s.eval(q3, v3, t + 0.5 * h)
    q4, v4 = q + h * v3, v + h * a3
    a4 = s.eval(q4, v4, t + h)
    q1 = q + h / 6.0 * (v + 2.0 * v2 + 2.0 * v3 + v4)
    v1 = v + h / 6.0 * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
    return q1, v1


def verlet(s: _Stepper, q: np.ndarray, v: np.ndarray, h: float, t: float):
    """Velocity Verlet; the last half kick is solved by fixed-point iteration."""
    a0 = s.a_last if s.a_last is not None else s.eval(q, v, t)
    v_half = v + 0.5 * h * a0
    q1 = q + h * v_half
    v1 = v_half
    s.a_last = None
    for _ in range(VERLET_MAX_ITER):
        a1 = s.eval(q1, v1, t + h)
        v_new = v_half + 0.5 * h * a1
        change = np.abs(v_new - v1)
        v1 = v_new
        if change.max() <= VERLET_TOL * (1.0 + np.abs(v1).max()):
            # a(q1, v1) at the converged v1, to within the tolerance: reuse it.
            s.a_last = a1
            return q1, v1
    raise _Failure(
        t + h,
        change,
        f"the implicit half kick of 'verlet' did not converge in {VERLET_MAX_ITER} "
        f"iterations; use a step shorter than {h:.3g} s",
    )


class _Failure(Exception):
    """A step failed at time t.

    ``where`` (shaped like a velocity) locates it: its largest entry.
    """

    def __init__(self, t: float, where: np.ndarray, problem: str) -> None:
        super().__init__(t, problem)
        self.t, self.problem = t, problem
        self.index = np.unravel_index(int(np.argmax(where)), np.shape(where))


def integrate_fixed_step(
    method: str,
    acc: Acceleration,
    q0: np.ndarray,
    v0: np.ndarray,
    t_eval: np.ndarray,
    step: float,
    names: Sequence[str],
) -> FixedStepResult:
    """Integrate q̈ = acc(t, q, q̇) with a fixed-step method, outputs at ``t_eval``.

    Args:
        method: a fixed-step method of :data:`rrt_pin.simulate.methods.METHODS`.
        acc: accelerations [rad/s² or m/s²] from time, positions and velocities.
        q0: initial positions, shape (n,) or (N, n) [rad or m].
        v0: initial velocities, same shape [rad/s or m/s].
        t_eval: increasing output times [s]; ``t_eval[0]`` is the initial time.
        step: the longest step [s].
        names: the state's coordinate names, positions then velocities (2n names),
            for error messages.

    Raises:
        DivergenceError: a state became non-finite, or Verlet's implicit kick did
            not converge (the step is too long).
    """
    stepper = _Stepper(method, acc)
    q = np.array(q0, dtype=float)
    v = np.array(v0, dtype=float)
    n = q.shape[-1]
    Q = np.empty((len(t_eval), *q.shape))
    V = np.empty_like(Q)
    Q[0], V[0] = q, v
    n_steps = 0
    for k in range(len(t_eval) - 1):
        t0, t1 = float(t_eval[k]), float(t_eval[k + 1])
        m = max(1, math.ceil((t1 - t0) / step * (1.0 - 1e-12)))
        h = (t1 - t0) / m
        for i in range(m):
            t = t0 + i * h
            q_prev, v_prev = q, v
            try:
                q, v = stepper.step(q, v, h, t)
            except _Failure as e:
                where = tuple(int(i) for i in e.index)
                raise DivergenceError(
                    e.t, f"{names[n + where[-1]]}{_variant_text(where[:-1])}", e.problem
                ) from None
            if not (np.isfinite(q).all() and np.isfinite(v).all()):
                _raise_non_finite(t + h, q, v, names, np.concatenate((q_prev, v_prev), axis=-1))
            n_steps += 1
        Q[k + 1], V[k + 1] = q, v
    return FixedStepResult(q=Q, v=V, n_evals=stepper.n_evals, n_steps=n_steps)


def _variant_text(variant: tuple[int, ...]) -> str:
    return f" (variant {variant[0]})" if variant else ""


def _raise_non_finite(
    t: float,
    q: np.ndarray,
    v: np.ndarray,
    names: Sequence[str],
    previous: np.ndarray | None = None,
) -> None:
    """Raise DivergenceError naming the coordinate where the blow-up shows.

    An infinite coordinate rather than a NaN (NaN comes from mixing infinities),
    and among those the largest before the step.
    """
    state = np.concatenate((q, v), axis=-1)
    bad = ~np.isfinite(state)
    infinite = np.isinf(state)
    candidates = infinite if infinite.any() else bad
    if previous is not None:
        score = np.where(candidates, np.abs(np.nan_to_num(previous)), -1.0)
        where = np.unravel_index(int(np.argmax(score)), state.shape)
    else:
        where = tuple(np.argwhere(candidates)[0])
    value = float(state[where])
    raise DivergenceError(
        t,
        f"{names[int(where[-1])]}{_variant_text(tuple(int(i) for i in where[:-1]))}",
        f"the state became non-finite ({value!r})",
    )
