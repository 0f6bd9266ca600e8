"""Direct dynamics: integrate M(q)·q̈ + b(q, q̇) = τ(q, q̇) under a feedback law.

Forward dynamics are Pinocchio's ABA (``pin.aba``; ``pin.abaInParallel`` for
batches). Units are SI: times [s], positions [rad or m], velocities [rad/s or m/s],
efforts [N·m or N].

Methods (:data:`METHODS`):

- ``"odepack"`` (the default): LSODA from ODEPACK (Fortran) with a lean driver:
  Adams methods up to order 12, switching to BDF if the problem turns stiff. A
  single run is one call of ``scipy.integrate.odeint``, which steps and
  interpolates to the output times in compiled code, so Python runs only the
  right-hand side. A batch steps with scipy's ``LSODA`` stepper and interpolates
  all variants at once from LSODA's Nordsieck history (one matrix product per
  step). LSODA's error test uses a weighted max-norm, so in a batch every
  variant is held to the tolerance.
- ``"RK45"``, ``"DOP853"``, ``"LSODA"``, ``"Radau"``, ``"BDF"``: scipy's
  ``solve_ivp``. The implicit ones (``LSODA``, ``Radau``, ``BDF``) get the
  analytic Jacobian of the closed loop from ``pin.computeABADerivatives`` and the
  controller's derivatives (``jacobian="analytic"``, the default) or scipy's
  finite differences (``jacobian="finite-difference"``).
- ``"symplectic_euler"``, ``"rk4"``, ``"verlet"``: fixed steps of at most ``step``
  [s] (see :mod:`rrt_pin.integrators`); ``rtol``/``atol`` do not apply.

Defaults: ``method="odepack"``, ``rtol=1e-9``, ``atol=1e-11`` for one run (on the
seed's run, 0–15 s, the largest position error is about 6e-11 against a
reference at rtol 1e-13); ``rtol=1e-9``, ``atol=1e-10`` for a batch, whose shared
step follows its most demanding variant (about 6e-11 on 1,000 seed variants: the
accuracy of scipy's DOP853 at rtol 1e-10, the baseline of issue 5).
``scripts/bench_direct.py`` measures both.

Gravity folding: when the controller's gravity term is exactly the model's
generalized gravity G(q) (``controller.compensates_gravity_of(model)``, true for
the seed's law on the RRT arm built from the same parameters, and for
:func:`~rrt_pin.control.pd_gravity_controller` on its own model), then
ABA(q, q̇, τ_PD + G(q)) = ABA₀(q, q̇, τ_PD) with ABA₀ on a copy of the model
without gravity: one Pinocchio call per evaluation and no gravity terms. The
efforts reported are always the controller's full output at the output times.

A run that produces a non-finite state or whose integrator fails (step size
underflow, too much work) raises :class:`~rrt_pin.errors.DivergenceError` with
the time and the coordinate; no NaN is returned.
"""

from __future__ import annotations

import math
import re
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.errors import DivergenceError, InputError
from rrt_pin.integrators import FIXED_STEP_METHODS, blame, integrate_fixed_step

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.control import Controller
    from rrt_pin.params import Params

__all__ = [
    "ADAPTIVE_METHODS",
    "BACKENDS",
    "BATCH_ATOL",
    "BATCH_METHODS",
    "BATCH_RTOL",
    "DEFAULT_ATOL",
    "DEFAULT_METHOD",
    "DEFAULT_RTOL",
    "METHODS",
    "BatchResult",
    "SimulationResult",
    "coordinate_names",
    "effort_names",
    "simulate",
    "simulate_batch",
]

#: Adaptive methods with error control (rtol, atol apply).
ADAPTIVE_METHODS = ("odepack", "RK45", "DOP853", "LSODA", "Radau", "BDF")
#: Every method :func:`simulate` accepts.
METHODS = (*ADAPTIVE_METHODS, *FIXED_STEP_METHODS, "leapfrog")
#: Fixed-step methods: ``step`` applies, rtol and atol do not.
STEPPED_METHODS = (*FIXED_STEP_METHODS, "leapfrog")
#: Methods :func:`simulate_batch` accepts (no dense Jacobian of the whole batch).
BATCH_METHODS = ("odepack", "RK45", "DOP853", *FIXED_STEP_METHODS)
_IMPLICIT = ("LSODA", "Radau", "BDF")
#: Dynamics engines: Pinocchio, or the numba kernel of :mod:`rrt_pin.compiled`.
BACKENDS = ("pinocchio", "compiled")
JACOBIANS = ("analytic", "finite-difference")

DEFAULT_METHOD = "odepack"
#: Default relative tolerance of the adaptive methods.
DEFAULT_RTOL = 1e-9
#: Default absolute tolerance of the adaptive methods [rad, m, rad/s, m/s].
DEFAULT_ATOL = 1e-11
#: Default relative tolerance of a batch.
BATCH_RTOL = 1e-9
#: Default absolute tolerance of a batch [rad, m, rad/s, m/s].
BATCH_ATOL = 1e-10
#: Internal steps odeint may take between two output times.
ODEINT_MXSTEP = 50_000
#: Right-hand-side evaluations a solve_ivp method may spend before it is stopped.
MAX_EVALS = 2_000_000

_RRT_EFFORTS = ("T01x", "T12y", "F23z")


# --------------------------------------------------------------------------
# Results
# --------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class SimulationResult:
    """One simulated run, sampled at the output times.

    Attributes:
        t: output times, shape (N,) [s].
        q: positions, shape (N, nv) [rad or m].
        qd: velocities, shape (N, nv) [rad/s or m/s].
        tau: efforts the controller applied at those states, (N, nv) [N·m or N].
        n_evals: right-hand-side (forward dynamics) evaluations.
        wall_time: duration of the call [s].
        method: the integration method (one of :data:`METHODS`).
        backend: ``"pinocchio"`` or ``"compiled"``.
        rtol: relative tolerance (adaptive methods), else None.
        atol: absolute tolerance (adaptive methods), else None.
        step: longest step [s] (fixed-step methods), else None.
        n_jac: Jacobian evaluations (implicit methods with the analytic Jacobian).
        q_names: position coordinate names (``q1``…, or ``q_<joint>``).
        qd_names: velocity coordinate names (``qd1``…, or ``qd_<joint>``).
        tau_names: effort names (``T01x, T12y, F23z``, or ``tau_<joint>``).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray
    n_evals: int
    wall_time: float
    method: str
    backend: str = "pinocchio"
    rtol: float | None = None
    atol: float | None = None
    step: float | None = None
    n_jac: int = 0
    q_names: tuple[str, ...] = ("q1", "q2", "q3")
    qd_names: tuple[str, ...] = ("qd1", "qd2", "qd3")
    tau_names: tuple[str, ...] = _RRT_EFFORTS

    def __post_init__(self) -> None:
        for name in ("t", "q", "qd", "tau"):
            arr = np.asarray(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def header(self) -> tuple[str, ...]:
        """Column names of :meth:`table`: t, positions, velocities, efforts."""
        return ("t", *self.q_names, *self.qd_names, *self.tau_names)

    def table(self) -> np.ndarray:
        """The run as rows ``t, q…, qd…, tau…`` (SI units), shape (N, 1 + 3·nv)."""
        return np.column_stack((self.t, self.q, self.qd, self.tau))


@dataclass(frozen=True, eq=False)
class BatchResult:
    """B variants integrated together, sampled at the same output times.

    Attributes:
        t: output times, shape (N,) [s].
        q: positions, shape (B, N, nv) [rad or m].
        qd: velocities, shape (B, N, nv) [rad/s or m/s].
        tau: applied efforts, (B, N, nv) [N·m or N], or None if not requested.
        n_evals: right-hand-side evaluations (each evaluates all B variants).
        wall_time: duration of the call [s].
        method, backend, rtol, atol, step, q_names, qd_names, tau_names: as in
            :class:`SimulationResult`.
        threads: threads given to ``pin.abaInParallel``.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    tau: np.ndarray | None
    n_evals: int
    wall_time: float
    method: str
    backend: str = "pinocchio"
    rtol: float | None = None
    atol: float | None = None
    step: float | None = None
    threads: int = 1
    q_names: tuple[str, ...] = ("q1", "q2", "q3")
    qd_names: tuple[str, ...] = ("qd1", "qd2", "qd3")
    tau_names: tuple[str, ...] = _RRT_EFFORTS

    def __len__(self) -> int:
        return int(self.q.shape[0])

    def variant(self, i: int) -> SimulationResult:
        """Variant ``i`` as a :class:`SimulationResult` (sharing the batch's cost figures).

        Raises:
            InputError: the batch ran with ``efforts=False`` (no efforts to hand over).
        """
        if self.tau is None:
            raise InputError("this batch ran with efforts=False: rerun with efforts=True")
        tau = self.tau[i]
        return SimulationResult(
            t=self.t,
            q=self.q[i],
            qd=self.qd[i],
            tau=tau,
            n_evals=self.n_evals,
            wall_time=self.wall_time,
            method=self.method,
            backend=self.backend,
            rtol=self.rtol,
            atol=self.atol,
            step=self.step,
            q_names=self.q_names,
            qd_names=self.qd_names,
            tau_names=self.tau_names,
        )


# --------------------------------------------------------------------------
# Names
# --------------------------------------------------------------------------
def _joint_labels(model: pin.Model) -> list[str]:
    labels = []
    for j in range(1, model.njoints):
        nv = model.joints[j].nv
        name = str(model.names[j])
        labels += [name] if nv == 1 else [f"{name}_{k}" for k in range(nv)]
    return labels


def coordinate_names(model: pin.Model) -> tuple[tuple[str, ...], tuple[str, ...]]:
    """Names of the position and velocity coordinates of ``model``.

    Joints named ``q1``, ``q2``… (the RRT arm) give ``q1…`` and ``qd1…``; other
    joints give ``q_<joint>`` and ``qd_<joint>`` (``<joint>_<k>`` for a joint with
    several degrees of freedom).
    """
    labels = _joint_labels(model)
    if all(re.fullmatch(r"q\d+", s) for s in labels):
        return tuple(labels), tuple("qd" + s[1:] for s in labels)
    return tuple(f"q_{s}" for s in labels), tuple(f"qd_{s}" for s in labels)


def effort_names(model: pin.Model) -> tuple[str, ...]:
    """Effort names: the seed's ``T01x, T12y, F23z`` for joints ``q1, q2, q3``, else ``tau_<joint>``."""
    labels = _joint_labels(model)
    if labels == ["q1", "q2", "q3"]:
        return _RRT_EFFORTS
    return tuple(f"tau_{s}" for s in labels)


# --------------------------------------------------------------------------
# Validation
# --------------------------------------------------------------------------
def _check_model(model: Any) -> None:
    import pinocchio as pin

    if not isinstance(model, pin.Model):
        raise InputError(f"model must be a pinocchio.Model, not {type(model).__name__}")
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if joint.nq != joint.nv or (joint.nv != 1 and "Translation" not in joint.shortname()):
            raise InputError(
                f"joint {model.names[j]!r} ({joint.shortname()}, nq={joint.nq}, nv={joint.nv}) "
                "is not supported: simulate needs joints whose q̇ is v "
                "(revolute with limits, prismatic, helical, translation)"
            )


def _check_vector(name: str, value: Any, n: int, unit: str) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name}={value!r} is not a list of numbers") from e
    if arr.shape != (n,):
        raise InputError(f"{name} has shape {arr.shape} but the model needs ({n},) [{unit}]")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        raise InputError(f"{name}[{bad[0]}]={float(arr[bad[0]])!r} must be finite [{unit}]")
    return arr


def _check_states(name: str, value: Any, n: int, unit: str) -> np.ndarray:
    try:
        arr = np.array(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name} is not an array of numbers") from e
    if arr.ndim != 2 or arr.shape[1] != n or arr.shape[0] < 1:
        raise InputError(f"{name} has shape {arr.shape} but the batch needs (B, {n}) [{unit}]")
    bad = np.argwhere(~np.isfinite(arr))
    if bad.size:
        i, k = bad[0]
        raise InputError(f"{name}[{i}, {k}]={float(arr[i, k])!r} must be finite [{unit}]")
    return arr


def _check_times(t_eval: Any) -> np.ndarray:
    try:
        t = np.array(t_eval, dtype=float)
    except (TypeError, ValueError) as e:
        raise InputError("t_eval is not an array of numbers [s]") from e
    if t.ndim != 1 or t.size < 2:
        raise InputError(f"t_eval has shape {t.shape}; it needs at least 2 times [s]")
    bad = np.flatnonzero(~np.isfinite(t))
    if bad.size:
        raise InputError(f"t_eval[{bad[0]}]={float(t[bad[0]])!r} must be finite [s]")
    steps = np.diff(t)
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0])
        raise InputError(
            f"t_eval must increase: t_eval[{i + 1}]={float(t[i + 1])!r} <= {float(t[i])!r} [s]"
        )
    return t


def _check_options(
    method: str,
    rtol: float | None,
    atol: float | None,
    step: float | None,
    t: np.ndarray,
    defaults: tuple[float, float] = (DEFAULT_RTOL, DEFAULT_ATOL),
) -> tuple[float | None, float | None, float | None]:
    if method not in METHODS:
        raise InputError(f"method={method!r} is not one of {', '.join(METHODS)}")
    for name, value in (("rtol", rtol), ("atol", atol), ("step", step)):
        if value is not None and not (
            isinstance(value, (int, float)) and math.isfinite(value) and value > 0
        ):
            raise InputError(f"{name}={value!r} must be a finite number > 0")
    if method in STEPPED_METHODS:
        return None, None, float(step) if step is not None else float(np.diff(t).min())
    return (
        float(rtol) if rtol is not None else defaults[0],
        float(atol) if atol is not None else defaults[1],
        None,
    )


# --------------------------------------------------------------------------
# The closed loop
# --------------------------------------------------------------------------
class _ClosedLoop:
    """Accelerations a(q, q̇) = ABA(q, q̇, controller(q, q̇)) and their Jacobian."""

    def __init__(self, model: pin.Model, controller: Controller) -> None:
        import pinocchio as pin

        self.n = model.nv
        self.controller = controller
        fold = getattr(controller, "compensates_gravity_of", None)
        self.folded = bool(fold is not None and hasattr(controller, "pd") and fold(model))
        if self.folded:
            free = model.copy()
            free.gravity = pin.Motion.Zero()
            self.model = free
            self.kp = np.array(controller.kp)  # type: ignore[attr-defined]
            self.kd = np.array(controller.kd)  # type: ignore[attr-defined]
            self.qf = np.array(controller.qf)  # type: ignore[attr-defined]
        else:
            self.model = model
        self.data = self.model.createData()

    def acceleration(self) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """a(q, q̇) for one state, as lean as possible."""
        import pinocchio as pin

        aba, model, data = pin.aba, self.model, self.data
        if self.folded:
            kp, kd, qf = self.kp, self.kd, self.qf
            return lambda q, v: aba(model, data, q, v, -kd * v - kp * (q - qf))
        controller = self.controller
        return lambda q, v: aba(model, data, q, v, controller(q, v))

    def odeint_rhs(self) -> Callable[[np.ndarray, float], np.ndarray]:
        """The f(y, t) of odeint, inlined; odeint copies the result, so one buffer serves all calls."""
        import pinocchio as pin

        aba, model, data, n = pin.aba, self.model, self.data, self.n
        out = np.empty(2 * n)
        if self.folded and n == 3:
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

        elif self.folded:
            kp, kd, qf = self.kp, self.kd, self.qf

            def f(y: np.ndarray, t: float) -> np.ndarray:
                q, v = y[:n], y[n:]
                out[:n] = v
                out[n:] = aba(model, data, q, v, -kd * v - kp * (q - qf))
                return out

        else:
            controller = self.controller

            def f(y: np.ndarray, t: float) -> np.ndarray:
                q, v = y[:n], y[n:]
                out[:n] = v
                out[n:] = aba(model, data, q, v, controller(q, v))
                return out

        return f

    def has_jacobian(self) -> bool:
        return self.folded or hasattr(self.controller, "derivatives")

    def jacobian(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """∂(q̇, q̈)/∂(q, q̇), shape (2n, 2n), from ``pin.computeABADerivatives``."""
        import pinocchio as pin

        n = self.n
        if self.folded:
            tau = -self.kd * v - self.kp * (q - self.qf)
            dtau_dq, dtau_dv = -np.diag(self.kp), -np.diag(self.kd)
        else:
            tau = self.controller(q, v)
            dtau_dq, dtau_dv = self.controller.derivatives(q, v)  # type: ignore[attr-defined]
        da_dq, da_dv, minv = pin.computeABADerivatives(self.model, self.data, q, v, tau)
        J = np.zeros((2 * n, 2 * n))
        J[:n, n:] = np.eye(n)
        J[n:, :n] = da_dq + minv @ dtau_dq
        J[n:, n:] = da_dv + minv @ dtau_dv
        return J


class _TooMuchWork(Exception):
    pass


class _NonFinite(Exception):
    def __init__(self, t: float, index: int) -> None:
        super().__init__(t, index)
        self.t, self.index = t, index


class _Watch:
    """A right-hand side f(t, y) that checks its input and output.

    Records the last (t, y, f) and raises _NonFinite at the first non-finite
    state or derivative.
    """

    def __init__(self, f: Callable[[float, np.ndarray], np.ndarray]) -> None:
        self.f = f
        self.calls = 0
        self.last: tuple[float, np.ndarray, np.ndarray] | None = None

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        self.calls += 1
        if self.calls > MAX_EVALS:
            raise _TooMuchWork(t)
        size = np.abs(np.nan_to_num(y))
        if not np.isfinite(y).all():
            raise _NonFinite(t, int(np.argmax(blame(y, size))))
        dy = self.f(t, y)
        if not np.isfinite(dy).all():
            raise _NonFinite(t, int(np.argmax(blame(dy, size))))
        self.last = (t, np.array(y), np.array(dy))
        return dy


def _fastest(watch: _Watch, rtol: float, atol: float) -> int:
    """Index of the coordinate changing fastest relative to its error weight."""
    if watch.last is None:
        return 0
    _, y, dy = watch.last
    return int(np.argmax(np.abs(dy) / (atol + rtol * np.abs(y))))


def _first_order(acc: Callable[[np.ndarray, np.ndarray], np.ndarray], n: int):
    def f(t: float, y: np.ndarray) -> np.ndarray:
        v = y[n:]
        return np.concatenate((v, acc(y[:n], v)))

    return f


def _run_odeint(
    f: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    rtol: float,
    atol: float,
    band: int | None = None,
    lean: Callable[[np.ndarray, float], np.ndarray] | None = None,
) -> tuple[np.ndarray, dict[str, Any], bool]:
    from scipy.integrate import ODEintWarning, odeint

    func = lean if lean is not None else (lambda y, s: f(s, y))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ODEintWarning)
        Y, info = odeint(
            func,
            y0,
            t,
            rtol=rtol,
            atol=atol,
            full_output=True,
            mxstep=ODEINT_MXSTEP,
            ml=band,
            mu=band,
        )
    ok = info["message"] == "Integration successful." and bool(np.isfinite(Y).all())
    return Y, info, ok


def _run_solve_ivp(
    f: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    method: str,
    rtol: float,
    atol: float,
    jac: Callable[[float, np.ndarray], np.ndarray] | None,
) -> tuple[np.ndarray, str, bool, int]:
    from scipy.integrate import solve_ivp

    options: dict[str, Any] = {"jac": jac} if method in _IMPLICIT and jac is not None else {}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            sol = solve_ivp(
                f, (t[0], t[-1]), y0, method=method, t_eval=t, rtol=rtol, atol=atol, **options
            )
        except (ValueError, ArithmeticError, np.linalg.LinAlgError) as e:
            # e.g. an implicit method's LU of a non-finite Jacobian
            return np.empty((0, y0.size)), f"{type(e).__name__}: {e}", False, 0
        except _TooMuchWork:
            return np.empty((0, y0.size)), f"more than {MAX_EVALS} evaluations", False, 0
    ok = sol.status == 0 and sol.y.shape[1] == t.size and bool(np.isfinite(sol.y).all())
    return sol.y.T, sol.message, ok, int(sol.njev)


def _diagnose(
    method: str,
    f: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    rtol: float,
    atol: float,
    names: Sequence[str],
    message: str,
    band: int | None = None,
    jac: Callable[[float, np.ndarray], np.ndarray] | None = None,
    width: int | None = None,
) -> DivergenceError:
    """Rerun a failed integration with checks, to say when and where it failed."""
    watch = _Watch(f)

    def label(index: int) -> str:
        if width is None:
            return names[index]
        return f"{names[index % width]} (variant {index // width})"

    try:
        if method == "odepack":
            _, info, _ = _run_odeint(watch, y0, t, rtol, atol, band)
            message = str(info["message"])
            imxer = int(info.get("imxer", -1))
            index = imxer - 1 if imxer > 0 else _fastest(watch, rtol, atol)
        else:
            _, message, _, _ = _run_solve_ivp(watch, y0, t, method, rtol, atol, jac)
            index = _fastest(watch, rtol, atol)
    except _NonFinite as e:
        return DivergenceError(e.t, label(e.index), "the state or its derivative became non-finite")
    except _TooMuchWork:
        index, message = _fastest(watch, rtol, atol), f"more than {MAX_EVALS} evaluations"
    t_fail = watch.last[0] if watch.last is not None else float(t[0])
    return DivergenceError(t_fail, label(index), f"the integrator {method} stopped: {message}")


# --------------------------------------------------------------------------
# simulate
# --------------------------------------------------------------------------
def simulate(
    model: pin.Model,
    controller: Controller,
    q0: Sequence[float] | np.ndarray,
    qd0: Sequence[float] | np.ndarray,
    t_eval: Sequence[float] | np.ndarray,
    method: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    backend: str = "pinocchio",
    step: float | None = None,
    jacobian: str = "analytic",
    params: Params | None = None,
) -> SimulationResult:
    """Simulate ``model`` under ``controller`` from (q0, qd0), sampled at ``t_eval``.

    Args:
        model: a Pinocchio model whose joints have q̇ = v (revolute, prismatic…).
        controller: τ = controller(q, q̇) (see :mod:`rrt_pin.control`); any callable.
        q0: initial positions (nq,) [rad or m].
        qd0: initial velocities (nv,) [rad/s or m/s].
        t_eval: increasing output times [s]; the run starts at ``t_eval[0]``.
        method: one of :data:`METHODS` (default ``"odepack"``; with the compiled
            backend, that backend's default).
        rtol: relative tolerance (adaptive methods; default 1e-9).
        atol: absolute tolerance (adaptive methods; default 1e-11) [SI units of each state].
        backend: ``"pinocchio"`` or ``"compiled"`` (numba kernel of the RRT arm,
            :mod:`rrt_pin.compiled`, needs ``params``).
        step: longest step of the fixed-step methods [s]; default the shortest
            interval of ``t_eval``.
        jacobian: ``"analytic"`` or ``"finite-difference"`` for LSODA, Radau, BDF.
        params: the arm's parameters, for the compiled backend (default: the
            controller's ``params`` if it has them).

    Returns:
        States and applied efforts at ``t_eval``, evaluation count and wall time.

    Raises:
        InputError: a bad model, state, time grid or option (the message names it).
        DivergenceError: the state became non-finite or the integrator failed.
    """
    import pinocchio  # noqa: F401  (imports are not simulation time)
    import scipy.integrate  # noqa: F401

    start = time.perf_counter()
    _check_model(model)
    q0 = _check_vector("q0", q0, model.nq, "rad or m")
    qd0 = _check_vector("qd0", qd0, model.nv, "rad/s or m/s")
    t = _check_times(t_eval)
    if not callable(controller):
        raise InputError(f"controller must be callable, not {type(controller).__name__}")
    if jacobian not in JACOBIANS:
        raise InputError(f"jacobian={jacobian!r} is not one of {', '.join(JACOBIANS)}")
    if backend == "compiled":
        _check_options(method or DEFAULT_METHOD, rtol, atol, step, t)  # values only
        return _simulate_compiled(model, params, controller, q0, qd0, t, method, rtol, atol, step)
    if backend != "pinocchio":
        raise InputError(f"backend={backend!r} is not one of {', '.join(BACKENDS)}")
    method = method or DEFAULT_METHOD
    rtol, atol, step = _check_options(method, rtol, atol, step, t)

    n = model.nv
    q_names, qd_names = coordinate_names(model)
    names = (*q_names, *qd_names)
    loop = _ClosedLoop(model, controller)
    acc = loop.acceleration()
    n_jac = 0
    if method in FIXED_STEP_METHODS:
        fixed = integrate_fixed_step(method, acc, q0, qd0, t, step, names)
        Q, V, n_evals = fixed.q, fixed.v, fixed.n_evals
    elif method == "leapfrog":
        from rrt_pin.symplectic import leapfrog

        run = leapfrog(model, q0, qd0, t, step, efforts=controller, names=names)
        Q, V, n_evals = run.q, run.qd, run.n_evals
    else:
        f = _first_order(acc, n)
        y0 = np.concatenate((q0, qd0))
        jac = None
        if method in _IMPLICIT and jacobian == "analytic" and loop.has_jacobian():
            calls = [0]

            def jac(s: float, y: np.ndarray) -> np.ndarray:
                calls[0] += 1
                return loop.jacobian(y[:n], y[n:])

        if method == "odepack":
            Y, info, ok = _run_odeint(f, y0, t, rtol, atol, lean=loop.odeint_rhs())
            message, n_evals = str(info["message"]), int(info["nfe"][-1])
        else:
            counted = _Counted(f)
            Y, message, ok, njev = _run_solve_ivp(counted, y0, t, method, rtol, atol, jac)
            n_evals, n_jac = counted.calls, njev
        if not ok:
            raise _diagnose(method, f, y0, t, rtol, atol, names, message, jac=jac)
        Q, V = Y[:, :n], Y[:, n:]
    tau = _efforts(controller, Q, V)
    bad = np.argwhere(~np.isfinite(tau))
    if bad.size:
        i, k = bad[0]
        raise DivergenceError(
            float(t[i]), effort_names(model)[k], f"the controller returned {float(tau[i, k])!r}"
        )
    return SimulationResult(
        t=t,
        q=Q,
        qd=V,
        tau=tau,
        n_evals=n_evals,
        wall_time=time.perf_counter() - start,
        method=method,
        backend="pinocchio",
        rtol=rtol,
        atol=atol,
        step=step,
        n_jac=n_jac,
        q_names=q_names,
        qd_names=qd_names,
        tau_names=effort_names(model),
    )


class _Counted:
    """Counts the calls of f(t, y) and stops the run after MAX_EVALS of them."""

    def __init__(self, f: Callable[[float, np.ndarray], np.ndarray]) -> None:
        self.f, self.calls = f, 0

    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        self.calls += 1
        if self.calls > MAX_EVALS:
            raise _TooMuchWork(t)
        return self.f(t, y)


def _efforts(controller: Controller, Q: np.ndarray, V: np.ndarray) -> np.ndarray:
    batched = getattr(controller, "efforts", None)
    if batched is not None:
        return np.asarray(batched(Q, V), dtype=float)
    return np.array([np.asarray(controller(q, v), dtype=float) for q, v in zip(Q, V, strict=True)])


def _simulate_compiled(
    model: pin.Model,
    params: Params | None,
    controller: Controller,
    q0: np.ndarray,
    qd0: np.ndarray,
    t: np.ndarray,
    method: str | None,
    rtol: float | None,
    atol: float | None,
    step: float | None,
) -> SimulationResult:
    """Hand over to :func:`rrt_pin.compiled.simulate_compiled` (imported only now)."""
    params = params if params is not None else getattr(controller, "params", None)
    if params is None:
        raise InputError(
            "backend 'compiled' simulates the RRT arm from its Params: pass params=… "
            "or a seed controller"
        )
    try:
        from rrt_pin import compiled
    except ImportError as e:
        raise InputError(f"backend 'compiled' is not available: {e}") from e
    if not compiled.available():
        raise InputError(
            "backend 'compiled' is not available: numba not found (pip install rrt-pin[fast])"
        )
    kwargs: dict[str, Any] = {"model": model}
    if step is not None:
        kwargs["step"] = step
    if method is None:
        return compiled.simulate_compiled(
            params, controller, q0, qd0, t, rtol=rtol, atol=atol, **kwargs
        )
    return compiled.simulate_compiled(params, controller, q0, qd0, t, method, rtol, atol, **kwargs)


# --------------------------------------------------------------------------
# simulate_batch
# --------------------------------------------------------------------------
class _BatchLoop:
    """Accelerations of B variants at once with ``pin.abaInParallel``."""

    def __init__(self, model: pin.Model, controllers: Sequence[Controller], threads: int) -> None:
        import pinocchio as pin

        from rrt_pin.control import PDGravityController, SeedController

        first = controllers[0]
        if not isinstance(first, (SeedController, PDGravityController)):
            raise InputError(
                "simulate_batch needs seed_controller(...) or pd_gravity_controller(...) "
                f"controllers, not {type(first).__name__}"
            )
        for i, c in enumerate(controllers):
            if type(c) is not type(first) or not _same_plant(c, first):
                raise InputError(
                    f"controllers[{i}] differs from controllers[0] in more than kp, kd, qf: "
                    "a batch shares one model (pin.abaInParallel uses one model for all "
                    "variants); vary gains, targets and initial states only"
                )
        self.first = first
        self.kp = np.array([c.kp for c in controllers])  # type: ignore[attr-defined]
        self.kd = np.array([c.kd for c in controllers])  # type: ignore[attr-defined]
        self.qf = np.array([c.qf for c in controllers])  # type: ignore[attr-defined]
        self.folded = first.compensates_gravity_of(model)
        plant = model.copy()
        if self.folded:
            plant.gravity = pin.Motion.Zero()
        self.pool = pin.ModelPool(plant, threads)
        self.threads = threads

    def acceleration(self) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
        """a(q, q̇) for states of shape (B, n)."""
        import pinocchio as pin

        aba, pool, threads = pin.abaInParallel, self.pool, self.threads
        kp, kd, qf = self.kp, self.kd, self.qf
        if self.folded:
            return lambda q, v: aba(threads, pool, q.T, v.T, (-kd * v - kp * (q - qf)).T).T
        gravity = self.first.gravity  # type: ignore[attr-defined]
        return lambda q, v: aba(threads, pool, q.T, v.T, (-kd * v - kp * (q - qf) + gravity(q)).T).T

    def efforts(self, Q: np.ndarray, V: np.ndarray) -> np.ndarray:
        """Efforts at time-major states of shape (T, B, n) -> (T, B, n)."""
        T, B, n = Q.shape
        if hasattr(self.first, "params"):  # the seed's law: vectorized over any leading shape
            tau = self.first.gravity(Q)  # type: ignore[attr-defined]
        else:
            tau = self.first.gravity(Q.reshape(T * B, n)).reshape(T, B, n)  # type: ignore[attr-defined]
        for i in range(n):  # column by column: fewer passes over large arrays
            column = tau[..., i]
            column -= V[..., i] * self.kd[:, i]
            column -= (Q[..., i] - self.qf[:, i]) * self.kp[:, i]
        return tau


def _same_plant(a: Any, b: Any) -> bool:
    if hasattr(a, "params"):
        pa, pb = a.params, b.params
        return (pa.g, pa.m2, pa.m3, pa.L2) == (pb.g, pb.m2, pb.m3, pb.L2)
    return bool(a.model == b.model)


#: Columns per matrix product of the batch interpolation: small products stay on one
#: thread in OpenBLAS, whose worker threads only slow things down on a busy machine.
_PRODUCT_SIZE = 200_000


def _product(powers: np.ndarray, yh: np.ndarray, out: np.ndarray) -> None:
    """Set ``out = powers @ yh.T`` in column blocks of at most _PRODUCT_SIZE multiply-adds."""
    k, order = powers.shape
    width = max(1, _PRODUCT_SIZE // (k * order))
    for s in range(0, yh.shape[0], width):
        np.matmul(powers, yh[s : s + width].T, out=out[:, s : s + width])


#: Output rows handed to the batch's efforts at a time (a few MB: still cached).
_ROW_BLOCK = 32


def _lsoda_batch(
    f: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    rtol: float,
    atol: float,
    band: int,
    label: Callable[[int], str],
    on_rows: Callable[[np.ndarray, slice], None] | None = None,
) -> tuple[np.ndarray, int]:
    """LSODA step by step, interpolating from its Nordsieck history; states (T, len(y0)).

    ``on_rows(Y, rows)`` is called on each new block of about ``_ROW_BLOCK`` output
    rows while it is still in the cache.
    """
    from scipy.integrate import LSODA

    solver = LSODA(f, t[0], y0, t[-1], rtol=rtol, atol=atol, lband=band, uband=band)
    Y = np.empty((t.size, y0.size))
    Y[0] = y0
    k, done = 1, 0
    while k < t.size:
        message = solver.step()
        bad = np.flatnonzero(~np.isfinite(solver.y))
        if bad.size:
            raise DivergenceError(solver.t, label(int(bad[0])), "the state became non-finite")
        if solver.status == "failed":
            raise DivergenceError(
                solver.t,
                label(int(np.argmax(np.abs(solver.y) / (atol + rtol * np.abs(solver.y))))),
                f"the integrator odepack stopped: {message}",
            )
        j = int(np.searchsorted(t, solver.t, side="right"))
        if j > k:
            dense = solver.dense_output()
            yh = getattr(dense, "yh", None)
            if yh is not None:  # y(t) = Σ_i yh[:, i]·((t − t_n)/h)^i, all outputs at once
                powers = ((t[k:j] - dense.t) / dense.h)[:, None] ** dense.p
                _product(powers, yh, Y[k:j])
            else:  # pragma: no cover - another scipy's dense output
                Y[k:j] = dense(t[k:j]).T
            if on_rows is not None and (j - done >= _ROW_BLOCK or j == t.size):
                on_rows(Y, slice(done, j))
                done = j
            k = j
    return Y, int(solver.nfev)


def simulate_batch(
    model: pin.Model,
    controllers: Controller | Sequence[Controller],
    q0s: np.ndarray,
    qd0s: np.ndarray,
    t_eval: Sequence[float] | np.ndarray,
    method: str | None = None,
    rtol: float | None = None,
    atol: float | None = None,
    step: float | None = None,
    threads: int | None = None,
    efforts: bool = True,
) -> BatchResult:
    """Simulate B variants of one model at once, as one vectorized state.

    Variants may differ in gains, targets and initial states, not in masses or
    geometry: ``pin.abaInParallel`` takes a ``ModelPool``, which holds one copy of
    one model per thread, not one model per variant.

    Args:
        model: the Pinocchio model shared by every variant.
        controllers: one controller per variant, or one for all; all
            :func:`~rrt_pin.control.seed_controller` (same g, m2, m3, L2) or all
            :func:`~rrt_pin.control.pd_gravity_controller` (same model).
        q0s: initial positions, shape (B, nq) [rad or m].
        qd0s: initial velocities, shape (B, nv) [rad/s or m/s].
        t_eval: increasing output times [s].
        method: ``odepack`` (default; its max-norm error test holds every variant
            to the tolerance), ``RK45``, ``DOP853`` (scipy's RMS norm over the
            whole batch is looser per variant), or a fixed-step method.
        rtol: relative tolerance (default 1e-9).
        atol: absolute tolerance (default 1e-10) [rad, m, rad/s, m/s].
        step: longest step of the fixed-step methods [s].
        threads: OpenMP threads of ``pin.abaInParallel``; default: the CPUs
            available (as :func:`rrt_pin.inverse.default_num_threads`, capped by
            ``OMP_NUM_THREADS``). Extra threads pay only on otherwise idle
            cores: pass 1 on a busy machine.
        efforts: also compute the applied efforts at every output time.

    Returns:
        States (B, T, nv) and efforts; ``result.variant(i)`` is one run.

    Raises:
        InputError: bad shapes, values, controllers or options.
        DivergenceError: a variant's state became non-finite or the integrator
            failed (the message names the coordinate and the variant).
    """
    import pinocchio  # noqa: F401  (imports are not simulation time)
    import scipy.integrate  # noqa: F401

    start = time.perf_counter()
    _check_model(model)
    q0s = _check_states("q0s", q0s, model.nq, "rad or m")
    qd0s = _check_states("qd0s", qd0s, model.nv, "rad/s or m/s")
    if q0s.shape[0] != qd0s.shape[0]:
        raise InputError(f"q0s has {q0s.shape[0]} rows but qd0s has {qd0s.shape[0]}")
    B, n = q0s.shape
    if callable(controllers):
        controllers = [controllers] * B
    controllers = list(controllers)  # type: ignore[arg-type]
    if len(controllers) != B:
        raise InputError(f"{len(controllers)} controllers for {B} initial states")
    t = _check_times(t_eval)
    method = method or DEFAULT_METHOD
    if method not in BATCH_METHODS:
        raise InputError(f"method={method!r} is not one of {', '.join(BATCH_METHODS)} for a batch")
    rtol, atol, step = _check_options(method, rtol, atol, step, t, (BATCH_RTOL, BATCH_ATOL))
    if threads is None:
        from rrt_pin.inverse import default_num_threads

        threads = default_num_threads()
    if isinstance(threads, bool) or not isinstance(threads, int) or threads < 1:
        raise InputError(f"threads={threads!r} must be an integer >= 1")
    for i, c in enumerate(controllers):
        if getattr(c, "nv", n) != n:
            raise InputError(
                f"controllers[{i}] has {c.nv} joints but the model has {n}"  # type: ignore[attr-defined]
            )

    q_names, qd_names = coordinate_names(model)
    names = (*q_names, *qd_names)
    width = 2 * n

    def label(index: int) -> str:
        return f"{names[index % width]} (variant {index // width})"

    loop = _BatchLoop(model, controllers, threads)
    acc = loop.acceleration()
    if method in FIXED_STEP_METHODS:
        fixed = integrate_fixed_step(method, acc, q0s, qd0s, t, step, names)
        Q, V, n_evals = fixed.q, fixed.v, fixed.n_evals  # time-major (T, B, n)
    else:
        y0 = np.concatenate((q0s, qd0s), axis=1).ravel()

        def f(s: float, y: np.ndarray) -> np.ndarray:
            # Variant-major state: the Jacobian is block diagonal (bandwidth 2n − 1).
            Y = y.reshape(B, width)
            v = Y[:, n:]
            out = np.empty((B, width))
            out[:, :n] = v
            out[:, n:] = acc(Y[:, :n], v)
            return out.ravel()

        tau = np.empty((t.size, B, n)) if efforts else None

        def on_rows(Y: np.ndarray, rows: slice) -> None:
            block = Y[rows].reshape(-1, B, width)
            tau[rows] = loop.efforts(block[..., :n], block[..., n:])  # type: ignore[index]

        if method == "odepack":
            Y, n_evals = _lsoda_batch(
                f, y0, t, rtol, atol, width - 1, label, on_rows if efforts else None
            )
        else:
            counted = _Counted(f)
            Y, message, ok, _ = _run_solve_ivp(counted, y0, t, method, rtol, atol, None)
            n_evals = counted.calls
            if not ok:
                raise _diagnose(method, f, y0, t, rtol, atol, names, message, width=width)
            if efforts:
                for i in range(0, t.size, _ROW_BLOCK):  # blocks of rows that stay cached
                    on_rows(Y, slice(i, i + _ROW_BLOCK))
        Y = Y.reshape(t.size, B, width)
        Q, V = Y[..., :n], Y[..., n:]  # (T, B, n) views
    if method in FIXED_STEP_METHODS:
        tau = loop.efforts(Q, V) if efforts else None
    return BatchResult(
        t=t,
        q=np.moveaxis(Q, 0, 1),
        qd=np.moveaxis(V, 0, 1),
        tau=np.moveaxis(tau, 0, 1) if tau is not None else None,
        n_evals=n_evals,
        wall_time=time.perf_counter() - start,
        method=method,
        backend="pinocchio",
        rtol=rtol,
        atol=atol,
        step=step,
        threads=threads,
        q_names=q_names,
        qd_names=qd_names,
        tau_names=effort_names(model),
    )
