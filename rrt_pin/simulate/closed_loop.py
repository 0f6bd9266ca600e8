"""The closed loop on Pinocchio: accelerations a(t, q, q̇) = ABA(q, q̇, τ(t, q, q̇)), one run or a batch.

Gravity folding: when a controller's :meth:`~rrt_pin.simulate.control.Controller.feedback`
says its gravity term is exactly the model's generalized gravity G(q), then
ABA(q, q̇, τ_PD + G(q)) = ABA₀(q, q̇, τ_PD) with ABA₀ on a copy of the model
without gravity: one Pinocchio call per evaluation and no gravity terms. The
efforts reported are always the controller's full output at the output times.

With a robot's physical model (:class:`~rrt_pin.robot.limits.Physical`, active), the
joints get :func:`~rrt_pin.robot.limits.applied_efforts` of the law's efforts
(saturated, minus damping and friction, plus the compliant position limits).
Saturation needs the law's whole effort, PD plus G(q); for PD plus the model's G,
gravity is still folded at the states where that effort cannot be saturated
(|τ_PD| ≤ effort − a bound of |G| over the joints' ranges,
:func:`~rrt_pin.robot.limits.gravity_bound`) and no joint is past a position limit:
there the joints get τ_PD + G minus the losses, and ABA₀ needs neither G nor the
saturation. Elsewhere G(q) is computed and the whole model applied.

Joint coordinates (angles for continuous joints) are mapped to Pinocchio's
configuration by the robot (:meth:`rrt_pin.robot.robot.Robot.configuration`), which
is the identity when every joint has one configuration entry.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core import cpus
from rrt_pin.core.memory import check_data

if TYPE_CHECKING:
    from rrt_pin.robot.limits import Physical
    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate.control import Controller

__all__ = ["BatchLoop", "ClosedLoop"]


def _without_gravity(model):  # noqa: ANN001, ANN202
    import pinocchio as pin

    free = model.copy()
    free.gravity = pin.Motion.Zero()
    return free


def _unsaturated(robot: Robot, p: Physical) -> Callable[[np.ndarray, np.ndarray], bool]:
    """f(τ_PD, q) for one state: whether τ_PD + G(q) cannot saturate and no joint is past a limit.

    :func:`~rrt_pin.robot.limits.within`, with G's bound taken off the effort limits.
    """
    from rrt_pin.robot.limits import within

    return within(p, _room(robot, p))


def _room(robot: Robot, p: Physical) -> np.ndarray:
    """The effort limits less a bound of |G| over the joints' ranges [N·m or N] (inf: no limit)."""
    from rrt_pin.robot.limits import gravity_bound

    finite = np.isfinite(p.effort)
    bound = gravity_bound(robot.model, p)
    with np.errstate(invalid="ignore"):
        return np.where(finite, p.effort - np.where(finite, bound, 0.0), np.inf)


def q_is_x(robot: Robot) -> bool:
    """Whether the joint coordinates are Pinocchio's configuration (no continuous joint)."""
    return not robot.has_continuous_joints


class ClosedLoop:
    """Accelerations of one run, and their Jacobian."""

    def __init__(
        self, robot: Robot, controller: Controller, physical: Physical | None = None
    ) -> None:
        from rrt_pin.robot.limits import applier, losses

        self.robot = robot
        self.n = robot.nv
        self.controller = controller
        self.physical = physical
        self.apply = None if physical is None else applier(physical)
        self.plain = not robot.has_continuous_joints
        feedback = controller.feedback()
        exact = feedback is not None and feedback.exact_for(robot)
        self.folded = exact and physical is None
        #: PD plus the model's own G(q) under a physical model: G by Pinocchio, no law call
        self.gravity_pd = exact and physical is not None
        if exact:
            self.kp, self.kd, self.qf = feedback.kp, feedback.kd, feedback.qf
        if self.folded:
            self.model = _without_gravity(robot.model)
        else:
            self.model = robot.model

        check_data(self.model, f"a simulation of a {self.n}-joint model")
        self.data = self.model.createData()
        if self.gravity_pd and q_is_x(robot):
            #: where PD plus G cannot saturate and no joint is past a limit: G folded
            self.unsaturated = _unsaturated(robot, physical)  # type: ignore[arg-type]
            self.losses = losses(physical)  # type: ignore[arg-type]
            self.model0 = _without_gravity(robot.model)
            self.data0 = self.model0.createData()

    def acceleration(self) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray]:
        """a(t, q, q̇) for one state (or a batch of one robot's states, fixed-step methods)."""
        import pinocchio as pin

        aba, model, data, to_q = pin.aba, self.model, self.data, self.robot.configuration
        if self.folded:
            kp, kd, qf = self.kp, self.kd, self.qf
            return lambda t, q, v: aba(model, data, to_q(q), v, -kd * v - kp * (q - qf))
        efforts = self.controller.efforts
        if self.gravity_pd and q_is_x(self.robot):
            gravity, apply = pin.computeGeneralizedGravity, self.apply
            kp, kd, qf = self.kp, self.kd, self.qf
            unsaturated, lose, model0, data0 = (
                self.unsaturated, self.losses, self.model0, self.data0,
            )  # fmt: skip

            def acc(t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
                tau = -kd * v - kp * (q - qf)
                if unsaturated(tau, q):  # ABA(τ_PD + G − losses) = ABA₀(τ_PD − losses)
                    return aba(model0, data0, q, v, tau if lose is None else lose(tau, v))
                return aba(model, data, q, v, apply(tau + gravity(model, data, q), q, v))

            return acc
        if self.apply is not None:
            apply = self.apply
            return lambda t, q, v: aba(model, data, to_q(q), v, apply(efforts(t, q, v), q, v))
        return lambda t, q, v: aba(model, data, to_q(q), v, efforts(t, q, v))

    def applied(self) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray]:
        """τ(t, q, q̇) the joints get: the law's, through the physical model if any."""
        efforts = self.controller.efforts
        if self.apply is None:
            return efforts
        apply = self.apply
        return lambda t, q, v: apply(efforts(t, q, v), q, v)

    def odeint_rhs(self) -> Callable[[np.ndarray, float], np.ndarray]:
        """The f(y, t) of odeint, inlined; odeint copies the result, so one buffer serves all calls."""
        import pinocchio as pin

        aba, model, data, n = pin.aba, self.model, self.data, self.n
        out = np.empty(2 * n)
        if self.folded and n == 3 and self.plain:
            # Three joints (the RRT arm): the PD efforts in Python floats cost less
            # than four numpy operations on 3-vectors.
            (k1, k2, k3), (b1, b2, b3) = self.kp.tolist(), self.kd.tolist()
            c1, c2, c3 = (self.kp * self.qf).tolist()
            array = np.array

            def f(y: np.ndarray, t: float) -> np.ndarray:
                q1, q2, q3, v1, v2, v3 = y.tolist()
                v = y[3:]
                out[:3] = v
                tau = array(
                    (c1 - b1 * v1 - k1 * q1, c2 - b2 * v2 - k2 * q2, c3 - b3 * v3 - k3 * q3)
                )
                out[3:] = aba(model, data, y[:3], v, tau)
                return out

            return f
        acc = self.acceleration()

        def g(y: np.ndarray, t: float) -> np.ndarray:
            q, v = y[:n], y[n:]
            q.flags.writeable = v.flags.writeable = False  # a law reads them, never writes
            out[:n] = v
            out[n:] = acc(t, q, v)
            return out

        return g

    def has_jacobian(self, t: float, q: np.ndarray, v: np.ndarray) -> bool:
        """Whether the analytic Jacobian is available (the controller provides ∂τ)."""
        return self.folded or self.controller.jacobian(t, q, v) is not None

    def jacobian(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """∂(q̇, q̈)/∂(q, q̇), shape (2n, 2n), from ``pin.computeABADerivatives``."""
        import pinocchio as pin

        n = self.n
        if self.folded:
            tau = -self.kd * v - self.kp * (q - self.qf)
            dtau_dq, dtau_dv = -np.diag(self.kp), -np.diag(self.kd)
        else:
            tau = self.controller.efforts(t, q, v)
            dtau_dq, dtau_dv = self.controller.jacobian(t, q, v)  # type: ignore[misc]
            if self.physical is not None:
                from rrt_pin.robot.limits import applied_jacobian

                dtau_dq, dtau_dv = applied_jacobian(tau, dtau_dq, dtau_dv, q, v, self.physical)
                tau = self.apply(tau, q, v)  # type: ignore[misc]
        x = self.robot.configuration(q)
        da_dq, da_dv, minv = pin.computeABADerivatives(self.model, self.data, x, v, tau)
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:, :n] = da_dq + minv @ dtau_dq
        J[n:, n:] = da_dv + minv @ dtau_dv
        return J


class Threads:
    """The thread count of a batch's parallel calls: fixed, or following the free CPUs.

    Adaptive (``fixed=None``): at most one thread per :data:`MIN_VARIANTS_PER_THREAD`
    variants, and only the CPUs no other process is running on, looked up again
    every :data:`RECHECK` seconds of the run, so that a job starting beside a long
    batch does not stall every statically split call on its busy core.
    """

    #: Fewer variants than this per thread are not worth another thread.
    MIN_VARIANTS_PER_THREAD = 32
    #: Seconds between two looks at the free CPUs [s].
    RECHECK = 0.05

    def __init__(self, fixed: int | None, variants: int) -> None:

        self.fixed = fixed
        self.variants = variants
        self._cpus = cpus
        self.most = 1
        self._count = 1
        self._next = -1.0
        if fixed is not None:
            self._count = self.most = fixed

    def __call__(self) -> int:
        """The thread count for the next call."""
        if self.fixed is not None:
            return self.fixed
        now = time.monotonic()
        if now >= self._next:
            self._count = self._cpus.threads_for(self.variants, self.MIN_VARIANTS_PER_THREAD)
            self.most = max(self.most, self._count)
            self._next = now + self.RECHECK
        return self._count


class BatchLoop:
    """Accelerations of B variants of one robot at once with ``pin.abaInParallel``.

    Laws whose :meth:`~rrt_pin.simulate.control.Controller.feedback` share one gravity
    term are evaluated as arrays (gains and targets stacked; folded into the
    dynamics when that term is the model's G); other controllers are evaluated
    variant by variant through ``efforts(t, q, qd)``. ``threads`` None: as many
    as the CPUs free during the run (:class:`Threads`).
    """

    def __init__(
        self,
        robot: Robot,
        controllers: Sequence[Controller],
        threads: int | None,
        physical: Physical | None = None,
    ) -> None:
        import pinocchio as pin

        from rrt_pin.robot.limits import applier, losses

        self.apply = None if physical is None else applier(physical)
        self.physical = physical
        self.robot = robot
        self.controllers = list(controllers)
        self.threads = Threads(threads, len(self.controllers))
        feedbacks = [c.feedback() for c in self.controllers]
        first = feedbacks[0]
        self.stacked = all(f is not None and f.key == first.key for f in feedbacks)
        self.folded = False
        #: PD plus the model's G under a physical model: G folded where it cannot saturate
        self.split = False
        if self.stacked:
            self.kp = np.array([f.kp for f in feedbacks])
            self.kd = np.array([f.kd for f in feedbacks])
            self.qf = np.array([f.qf for f in feedbacks])
            self.gravity = first.gravity
            exact = first.exact_for(robot)
            self.folded = exact and physical is None
            self.split = exact and physical is not None
        if self.split:
            self.room = _room(robot, physical)  # type: ignore[arg-type]
            self.losses = losses(physical)  # type: ignore[arg-type]
        plant = _without_gravity(robot.model) if self.folded or self.split else robot.model

        self.pool = pin.ModelPool(plant, threads if threads is not None else cpus.available())

    def acceleration(self) -> Callable[[float, np.ndarray, np.ndarray], np.ndarray]:
        """a(t, q, q̇) for states of shape (B, n)."""
        import pinocchio as pin

        aba, pool, threads, to_q = (
            pin.abaInParallel,
            self.pool,
            self.threads,
            self.robot.configuration,
        )
        if self.stacked:
            kp, kd, qf, gravity = self.kp, self.kd, self.qf, self.gravity
            if self.folded:
                return lambda t, q, v: (
                    aba(threads(), pool, to_q(q).T, v.T, (-kd * v - kp * (q - qf)).T).T
                )
            if self.split:
                return self._split(aba, pool, threads, to_q)
            if self.apply is not None:
                apply = self.apply
                return lambda t, q, v: (
                    aba(threads(), pool, to_q(q).T, v.T,
                        apply(-kd * v - kp * (q - qf) + gravity(q), q, v).T).T
                )  # fmt: skip
            return lambda t, q, v: (
                aba(threads(), pool, to_q(q).T, v.T, (-kd * v - kp * (q - qf) + gravity(q)).T).T
            )
        laws = [c.efforts for c in self.controllers]
        apply = self.apply

        def acc(t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
            tau = np.empty(q.shape)
            for b, law in enumerate(laws):
                tau[b] = law(t, q[b], v[b])
            if apply is not None:
                tau = apply(tau, q, v)
            return aba(threads(), pool, to_q(q).T, v.T, tau.T).T

        return acc

    def _split(self, aba, pool, threads, to_q):  # noqa: ANN001, ANN202
        """a(t, q, q̇) of stacked PD plus the model's G under the physical model, on ABA₀.

        Variants whose PD plus G cannot saturate and that are past no position limit
        get τ_PD − losses (G folded); the others apply(τ_PD + G) − G, G computed for them only.
        """
        kp, kd, qf, gravity, apply, lose = (
            self.kp, self.kd, self.qf, self.gravity, self.apply, self.losses,
        )  # fmt: skip
        p: Physical = self.physical  # type: ignore[assignment]
        # the bounds spelt out (B, n): cheaper than broadcasting them at each call
        lower, upper, room = (
            np.broadcast_to(x, self.kp.shape).copy() for x in (p.lower, p.upper, self.room)
        )
        every = np.logical_and.reduce

        def acc(t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
            tau = -kd * v - kp * (q - qf)
            free = (abs(tau) <= room) & (q >= lower) & (q <= upper)  # NaN: not free
            out = tau if lose is None else lose(tau, v)
            if not every(free, axis=None):
                rows = np.flatnonzero(~every(free, axis=1))
                qs, g = q[rows], gravity(q[rows])
                out[rows] = apply(tau[rows] + g, qs, v[rows]) - g
            return aba(threads(), pool, to_q(q).T, v.T, out.T).T

        return acc

    def efforts(self, t: np.ndarray, Q: np.ndarray, V: np.ndarray) -> np.ndarray:
        """Efforts at time-major states (T, B, n) -> (T, B, n); ``t`` the T times [s]."""
        T, B, n = Q.shape
        if not self.stacked:
            tau = np.empty(Q.shape)
            for b, c in enumerate(self.controllers):
                tau[:, b] = c.efforts_many(t, Q[:, b], V[:, b])
            return tau
        tau = np.asarray(self.gravity(Q.reshape(T * B, n))).reshape(T, B, n)
        for i in range(n):  # column by column: fewer passes over large arrays
            column = tau[..., i]
            column -= V[..., i] * self.kd[:, i]
            column -= (Q[..., i] - self.qf[:, i]) * self.kp[:, i]
        return tau
