"""The Pinocchio backend: one run or a batch on ABA, with scipy's, the fixed-step or the symplectic integrators."""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core.errors import DivergenceError
from rrt_pin.robot.limits import saturated
from rrt_pin.simulate.closed_loop import BatchLoop, ClosedLoop
from rrt_pin.simulate.methods import FIXED_STEP, ODEPACK, SYMPLECTIC
from rrt_pin.simulate.results import BatchResult, SimulationResult
from rrt_pin.simulate.scipy_runs import (
    Counted,
    diagnose,
    eval_budget,
    first_order,
    lsoda_batch,
    run_odeint,
    run_solve_ivp,
    too_much_work,
)

if TYPE_CHECKING:
    from rrt_pin.robot.limits import Physical
    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate.control import Controller
    from rrt_pin.simulate.options import Options

__all__ = ["run_batch", "run_one"]

#: Output rows handed to the batch's efforts at a time (a few MB: still cached).
_ROW_BLOCK = 32


def _check_efforts(t: np.ndarray, tau: np.ndarray, names: Sequence[str]) -> None:
    bad = np.argwhere(~np.isfinite(tau))
    if bad.size:
        *variant, i, k = (int(x) for x in bad[0])
        where = f" (variant {variant[0]})" if variant else ""
        raise DivergenceError(
            float(t[i]),
            f"{names[k]}{where}",
            f"the controller returned {float(tau[tuple(bad[0])])!r}",
        )


def run_one(
    robot: Robot,
    controller: Controller,
    q0: np.ndarray,
    qd0: np.ndarray,
    t: np.ndarray,
    options: Options,
    start: float,
    physical: Physical | None = None,
) -> SimulationResult:
    """One run on Pinocchio's ABA (inputs already validated).

    ``physical``: the limits and losses the joints get beyond the law (None: none);
    the efforts returned are the law's, saturated at its effort limits.
    """
    n = robot.nv
    names = (*robot.q_names, *robot.qd_names)
    loop = ClosedLoop(robot, controller, physical)
    method, rtol, atol, step = options.method, options.rtol, options.atol, options.step
    n_jac = 0
    if method.family == FIXED_STEP:
        from rrt_pin.simulate.integrators import integrate_fixed_step  # its family only

        fixed = integrate_fixed_step(method.name, loop.acceleration(), q0, qd0, t, step, names)
        Q, V, n_evals = fixed.q, fixed.v, fixed.n_evals
    elif method.family == SYMPLECTIC:
        from rrt_pin.simulate.symplectic import leapfrog

        run = leapfrog(
            robot.model,
            q0,
            qd0,
            t,
            step,
            efforts=loop.applied(),
            names=names,
            configuration=robot.configuration if robot.has_continuous_joints else None,
        )
        Q, V, n_evals = run.q, run.qd, run.n_evals
    else:
        f = first_order(loop.acceleration(), n)
        y0 = np.concatenate((q0, qd0))
        jac = None
        if (
            method.implicit
            and options.jacobian == "analytic"
            and loop.has_jacobian(float(t[0]), q0, qd0)
        ):

            def jac(s: float, y: np.ndarray) -> np.ndarray:
                return loop.jacobian(s, y[:n], y[n:])

        if method.family == ODEPACK:
            Y, info, ok = run_odeint(f, y0, t, rtol, atol, lean=loop.odeint_rhs())
            message, n_evals = str(info["message"]), int(info["nfe"][-1])
        else:
            counted = Counted(f, eval_budget(float(t[-1] - t[0])))
            Y, message, ok, njev = run_solve_ivp(counted, y0, t, method.name, rtol, atol, jac)
            n_evals, n_jac = counted.calls, njev
            if counted.too_much_work():  # said at once: not run again
                raise too_much_work(method.name, counted, float(t[-1] - t[0]), names, rtol, atol)
        if not ok:
            raise diagnose(method.name, f, y0, t, rtol, atol, names, message, jac=jac, states=Y)
        Q, V = Y[:, :n], Y[:, n:]
    tau = controller.efforts_many(t, Q, V)
    _check_efforts(t, tau, robot.effort_names)
    if physical is not None:
        tau = saturated(tau, physical)
    return SimulationResult(
        t=t,
        q=Q,
        qd=V,
        tau=tau,
        n_evals=n_evals,
        wall_time=time.perf_counter() - start,
        method=method.name,
        backend="pinocchio",
        rtol=rtol,
        atol=atol,
        step=step,
        n_jac=n_jac,
        threads=1,
        q_names=robot.q_names,
        qd_names=robot.qd_names,
        tau_names=robot.effort_names,
    )


def run_batch(
    robot: Robot,
    controllers: Sequence[Controller],
    q0s: np.ndarray,
    qd0s: np.ndarray,
    t: np.ndarray,
    options: Options,
    threads: int | None,
    efforts: bool,
    start: float,
    physical: Physical | None = None,
) -> BatchResult:
    """B variants as one vectorized state on ``pin.abaInParallel`` (inputs already validated).

    ``physical`` as :func:`run_one`'s.
    """
    B, n = q0s.shape
    names = (*robot.q_names, *robot.qd_names)
    width = 2 * n
    method, rtol, atol, step = options.method, options.rtol, options.atol, options.step

    def label(index: int) -> str:
        return f"{names[index % width]} (variant {index // width})"

    loop = BatchLoop(robot, controllers, threads, physical)
    acc = loop.acceleration()
    tau = None
    if method.family == FIXED_STEP:
        from rrt_pin.simulate.integrators import integrate_fixed_step

        fixed = integrate_fixed_step(method.name, acc, q0s, qd0s, t, step, names)
        Q, V, n_evals = fixed.q, fixed.v, fixed.n_evals  # time-major (T, B, n)
        if efforts:
            tau = loop.efforts(t, Q, V)
    else:
        y0 = np.concatenate((q0s, qd0s), axis=1).ravel()

        def f(s: float, y: np.ndarray) -> np.ndarray:
            # Variant-major state: the Jacobian is block diagonal (bandwidth 2n − 1).
            Y = y.reshape(B, width)
            v = Y[:, n:]
            out = np.empty((B, width))
            out[:, :n] = v
            out[:, n:] = acc(s, Y[:, :n], v)
            return out.ravel()

        tau = np.empty((t.size, B, n)) if efforts else None

        def on_rows(Y: np.ndarray, rows: slice) -> None:
            block = Y[rows].reshape(-1, B, width)
            tau[rows] = loop.efforts(t[rows], block[..., :n], block[..., n:])  # type: ignore[index]

        if method.family == ODEPACK:
            Y, n_evals = lsoda_batch(
                f, y0, t, rtol, atol, width - 1, label, on_rows if efforts else None
            )
        else:
            counted = Counted(f, eval_budget(float(t[-1] - t[0])), width)
            Y, message, ok, _ = run_solve_ivp(counted, y0, t, method.name, rtol, atol, None)
            n_evals = counted.calls
            if counted.too_much_work():

                def label(index: int) -> str:
                    return f"{names[index % width]} (variant {index // width})"

                span = float(t[-1] - t[0])
                raise too_much_work(method.name, counted, span, names, rtol, atol, label)
            if not ok:
                raise diagnose(
                    method.name, f, y0, t, rtol, atol, names, message, width=width, states=Y
                )
            if efforts:
                for i in range(0, t.size, _ROW_BLOCK):  # blocks of rows that stay cached
                    on_rows(Y, slice(i, i + _ROW_BLOCK))
        Y = Y.reshape(t.size, B, width)
        Q, V = Y[..., :n], Y[..., n:]  # (T, B, n) views
    if tau is not None:
        _check_efforts(t, np.moveaxis(tau, 0, 1), robot.effort_names)
        if physical is not None:
            tau = saturated(tau, physical)
    return BatchResult(
        t=t,
        q=np.moveaxis(Q, 0, 1),
        qd=np.moveaxis(V, 0, 1),
        tau=np.moveaxis(tau, 0, 1) if tau is not None else None,
        n_evals=n_evals,
        wall_time=time.perf_counter() - start,
        method=method.name,
        backend="pinocchio",
        rtol=rtol,
        atol=atol,
        step=step,
        threads=loop.threads.most,
        q_names=robot.q_names,
        qd_names=robot.qd_names,
        tau_names=robot.effort_names,
    )
