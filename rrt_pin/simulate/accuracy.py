"""Accuracy the user can rely on: the catalogue of hard problems and the global-error estimate.

Three things live here, all about how far a simulated q(t) is from the exact one:

* :data:`PROBLEMS`, the accuracy catalogue: runs of the chapter's arm chosen to be
  hard for error-controlled integrators (light damping over long horizons, stiff
  gains, fast motions, small and large masses). Tests, ``scripts/bench/accuracy.py``
  and ``docs/benchmarks.md`` all read it; :func:`reference` integrates a problem at
  rtol 1e-13 to judge the defaults against.
* the estimate of the global error of a run that :func:`rrt_pin.simulate.simulate`
  attaches to every result (``result.error_estimate``,
  :mod:`rrt_pin.simulate.estimate`): a companion run of the same method at looser
  tolerances and the method's measured rate of error ∝ tolᵖ (fixed-step methods:
  twice or half the step, Richardson's formula);
* :data:`ROBOT_PROBLEMS`: a UR5 and a Panda run under PD plus gravity, which the
  calibration of the default tolerances (``scripts/bench/calibrate.py``) also keeps.

Why an estimate: error-controlled integrators bound the error of each step, not the
error at the end; in lightly damped oscillations the phase error of every step adds
up, so the global error depends on the problem, silently.

Units: q errors in rad (revolute joints) or m (prismatic joints).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core import backends
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.trajectory import RestToRest
from rrt_pin.robot import robots
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import control, simulate

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate.results import SimulationResult

__all__ = [
    "ACCURACY",
    "REFERENCE_ATOL",
    "REFERENCE_RTOL",
    "PROBLEMS",
    "ROBOT_PROBLEMS",
    "Problem",
    "RobotProblem",
    "reference",
]

#: The default accuracy asked for, which the default tolerances keep on every problem of
#: :data:`PROBLEMS`: max |q − q_exact| over the output times [rad or m].
ACCURACY = 1e-8
#: Tolerances of the catalogue's references (relative; absolute [rad, m, rad/s, m/s]).
REFERENCE_RTOL = 1e-13
REFERENCE_ATOL = 1e-15


@dataclass(frozen=True)
class Problem:
    """One run of the chapter's arm in the accuracy catalogue.

    Attributes:
        name: short name (``chapter``, ``slider-150s`` …).
        summary: what makes it hard, one line.
        params: the chapter's symbols that differ from the chapter (SI units).
        tf: final time [s] (runs start at 0).
        dt: output interval [s].
        tracking: gains (kp, kd) of a computed-torque law along eq. (30) (the
            problem then runs on Pinocchio only), or None for eq. (31).
    """

    name: str
    summary: str
    params: dict[str, float] = field(default_factory=dict)
    tf: float = 15.0
    dt: float = 0.01
    tracking: tuple[float, float] | None = None

    @property
    def arm(self) -> Robot:
        """The chapter's arm with this problem's parameters."""
        return chapter_arm(Params(**self.params))

    @property
    def backends(self) -> tuple[str, ...]:
        """The backends that run it (a tracking law runs on Pinocchio only)."""
        return ("pinocchio",) if self.tracking is not None else ("pinocchio", "compiled")

    def times(self) -> np.ndarray:
        """Output times 0 .. tf [s]."""
        return time_grid(self.tf, self.dt)

    def controller(self, robot: Robot | None = None) -> Any:
        """The problem's law: eq. (31), or computed torque along eq. (30) with Tp from params."""
        robot = self.arm if robot is None else robot
        if self.tracking is None:
            return control.regulator(robot)

        d = robot.defaults
        kp, kd = self.tracking
        return control.tracking_controller(robot, RestToRest(d.q0, d.qf, d.Tp), kp=kp, kd=kd)

    def start(self, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
        """The initial state (q0 [rad or m], q̇0 [rad/s or m/s]): the chapter's."""
        d = robot.defaults
        return np.asarray(d.q0, dtype=float), np.asarray(d.qd0, dtype=float)

    def run(self, **options: Any) -> SimulationResult:
        """``simulate`` this problem (keyword options as :func:`rrt_pin.simulate.simulate`)."""
        robot = self.arm
        q0, qd0 = self.start(robot)
        return simulate(robot, self.controller(robot), q0, qd0, self.times(), **options)


@dataclass(frozen=True)
class RobotProblem:
    """A run of another robot under PD plus gravity compensation (the tolerances' calibration).

    The gains are critically damped at 10 rad/s on the diagonal of M(qf):
    kp_k = 100·M_kk(qf) [N·m/rad or N/m], kd_k = 20·M_kk(qf) [N·m·s/rad or N·s/m];
    the run starts at rest, 0.3 rad (0.01 m for a slider) from qf.

    Attributes:
        name: short name (``ur5``, ``panda``).
        summary: one line.
        robot: the robot's name in :func:`rrt_pin.robot.robots.get` (needs
            example-robot-data).
        qf: the target (nv,) [rad or m].
        tf: final time [s].
        dt: output interval [s].
    """

    name: str
    summary: str
    robot: str
    qf: tuple[float, ...]
    tf: float = 5.0
    dt: float = 0.01
    backends: tuple[str, ...] = ("pinocchio", "compiled")

    @property
    def arm(self) -> Robot:
        """The robot (raises MissingExtra without example-robot-data)."""
        return robots.get(self.robot)

    def times(self) -> np.ndarray:
        """Output times 0 .. tf [s]."""
        return time_grid(self.tf, self.dt)

    def controller(self, robot: Robot | None = None) -> Any:
        """PD plus gravity compensation to qf, gains from M(qf)."""
        import pinocchio as pin

        robot = self.arm if robot is None else robot
        qf = np.array(self.qf)
        m = np.diag(pin.crba(robot.model, robot.model.createData(), robot.configuration(qf)))
        return control.pd_gravity_controller(robot, kp=100.0 * m, kd=20.0 * m, qf=qf)

    def start(self, robot: Robot) -> tuple[np.ndarray, np.ndarray]:
        """q0 = qf + 0.3 rad (0.01 m) [rad or m], at rest."""
        offset = [0.01 if u == "m" else 0.3 for u in robot.coordinate_units]
        return np.array(self.qf) + np.array(offset), np.zeros(robot.nv)

    def run(self, **options: Any) -> SimulationResult:
        """``simulate`` this problem (keyword options as :func:`rrt_pin.simulate.simulate`)."""
        robot = self.arm
        q0, qd0 = self.start(robot)
        return simulate(robot, self.controller(robot), q0, qd0, self.times(), **options)


def _problems(*problems: Problem) -> dict[str, Problem]:
    return {s.name: s for s in problems}


_STIFF_100 = dict(
    gamma01=3e4, gamma12=3e4, gamma23=5e3, beta01=4500.0, beta12=2000.0, beta23=1500.0
)
_STIFF_10K = {k: 100.0 * v for k, v in _STIFF_100.items()}

#: The accuracy catalogue, by name (the defaults must reach :data:`ACCURACY` on each).
PROBLEMS: dict[str, Problem] = _problems(
    Problem("chapter", "the chapter's run, eq. (31), strongly damped"),
    Problem(
        "slider-150s",
        "lightly damped slider: beta23 = 0.5 N·s/m, gamma23 = 400 N/m, 150 s",
        dict(beta23=0.5, gamma23=400.0),
        tf=150.0,
    ),
    Problem("long-1000s", "the chapter's gains over a long horizon, 1,000 s", tf=1000.0),
    Problem(
        "light-joint1",
        "lightly damped joint 1: beta01 = 1 N·m·s/rad, 150 s",
        dict(beta01=1.0),
        tf=150.0,
    ),
    Problem(
        "light-joint2",
        "lightly damped joint 2: beta12 = 1 N·m·s/rad, 150 s",
        dict(beta12=1.0),
        tf=150.0,
    ),
    Problem(
        "light-joint3",
        "lightly damped slider: beta23 = 1 N·s/m, 150 s",
        dict(beta23=1.0),
        tf=150.0,
    ),
    Problem("stiff-x100", "every gain ×100", _STIFF_100),
    Problem("stiff-x1e4", "every gain ×10⁴", _STIFF_10K),
    Problem(
        "fast-oscillation",
        "fast, lightly damped slider: gamma23 = 4·10⁴ N/m (5 Hz), beta23 = 0.5 N·s/m",
        dict(beta23=0.5, gamma23=4e4),
    ),
    Problem(
        "fast-motion",
        "computed torque along eq. (30) with Tp = 0.5 s, kp = 400, kd = 40, 3 s",
        dict(Tp=0.5),
        tf=3.0,
        dt=0.001,
        tracking=(400.0, 40.0),
    ),
    Problem(
        "small-masses",
        "masses and inertias ÷100 (the chapter's gains: fast modes)",
        dict(m1=0.9, m2=0.6, m3=0.4, I3x=0.05, I3y=0.04, I3z=0.01),
    ),
    Problem(
        "large-masses",
        "masses and inertias ×100 (slow, barely moving)",
        dict(m1=9000.0, m2=6000.0, m3=4000.0, I3x=500.0, I3y=400.0, I3z=100.0),
    ),
)

#: Two robots of example-robot-data, 5 s under PD plus gravity: the calibration of the
#: default tolerances (:mod:`rrt_pin.simulate.calibration`) meets the accuracy on these too.
ROBOT_PROBLEMS: dict[str, RobotProblem] = {
    p.name: p
    for p in (
        RobotProblem("ur5", "UR5, 6 revolute joints", "ur5", (0.0, -1.2, 1.2, -1.0, -1.2, 0.0)),
        RobotProblem(
            "panda",
            "Panda, 7 revolute joints and 2 finger sliders",
            "panda",
            (0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.8, 0.02, 0.02),
        ),
    )
}

#: Old names of the catalogue and its entries (kept for one release; not in ``__all__``).
SCENES = PROBLEMS
Scene = Problem


@dataclass(frozen=True, eq=False)
class Reference:
    """A problem integrated at :data:`REFERENCE_RTOL`.

    Attributes:
        q: coordinates at the problem's output times (N, 3) [rad, rad, m].
        how: backend and method that computed it.
    """

    q: np.ndarray
    how: str


def reference(problem: Problem | RobotProblem, backend: str | None = None) -> Reference:
    """The problem at rtol 1e-13, atol 1e-15 with DOP853 (order 8).

    Args:
        problem: a catalogue problem.
        backend: ``compiled`` (fast; eq. (31) problems only) or ``pinocchio``
            (scipy's DOP853 on ``pin.aba``, :func:`rrt_pin.simulate.reference.reference_run`,
            sharing no code with :func:`~rrt_pin.simulate.simulate`); default
            compiled when the problem and numba allow it.
    """
    if backend is None:
        backend = (
            "compiled"
            if "compiled" in problem.backends and backends.get("compiled").available()
            else "pinocchio"
        )
    if backend == "compiled":
        run = problem.run(
            backend="compiled",
            method="DOP853",
            rtol=REFERENCE_RTOL,
            atol=REFERENCE_ATOL,
            estimate_error=False,
        )
        return Reference(q=np.array(run.q), how="compiled DOP853")
    from rrt_pin.simulate.reference import reference_run

    robot = problem.arm
    q0, qd0 = problem.start(robot)
    ref = reference_run(
        robot.model,
        problem.controller(robot),
        q0,
        qd0,
        problem.times(),
        rtol=REFERENCE_RTOL,
        atol=REFERENCE_ATOL,
        methods=("DOP853",),
    )
    return Reference(q=np.array(ref.q), how="scipy DOP853 on pin.aba")


def max_error(q: np.ndarray, q_ref: np.ndarray) -> float:
    """The largest |q − q_ref| over times and coordinates [rad or m]."""
    return float(np.abs(np.asarray(q) - np.asarray(q_ref)).max())
