"""What a simulation returns: one run, or a batch of variants (the bottom of the package).

Both backends return these same types with the same fields. Units are SI:
times [s], coordinates [rad or m], velocities [rad/s or m/s], efforts [N·m or N].
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.core.extras import MissingExtra
from rrt_pin.robot.robot import CHAPTER_COLUMNS, Robot

__all__ = ["KEEPS", "BatchResult", "ErrorEstimate", "SimulationResult"]

#: What a batch may keep of each variant: every output time, the last one, or the
#: last one and per-variant metrics (see :class:`BatchResult`).
KEEPS = ("trajectories", "final", "metrics")


@dataclass(frozen=True, eq=False)
class ErrorEstimate:
    """An estimate of a run's global error in q, from a companion run.

    See :mod:`rrt_pin.simulate.estimate` for how it is made.

    Attributes:
        q: per coordinate, max over the output times (and the variants of a
            batch) of the estimated |q − q_exact|, shape (nv,) [rad or m].
        accuracy: the accuracy the run asked for [rad or m] (``accuracy=``; with
            explicit tolerances and none asked, the larger of 1e-8 and its rtol and atol).
        how: the companion run, e.g. ``"odepack at rtol 1e-10, atol 1e-12"``.
        n_evals: the companion run's right-hand-side evaluations.
        wall_time: the companion run's duration [s] (not in the result's ``wall_time``).
        variants: a batch's estimate per variant, shape (B, nv) [rad or m]; else None.
    """

    q: np.ndarray
    accuracy: float
    how: str
    n_evals: int
    wall_time: float
    variants: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("q", "variants"):
            value = getattr(self, name)
            if value is not None:
                arr = np.array(value, dtype=float)
                arr.setflags(write=False)
                object.__setattr__(self, name, arr)

    @property
    def max(self) -> float:
        """The largest estimate over coordinates, times (and variants) [rad or m]."""
        return float(self.q.max()) if self.q.size else 0.0

    @property
    def exceeded(self) -> bool:
        """Whether the estimate exceeds the accuracy asked for."""
        return self.max > self.accuracy

    def variant(self, i: int) -> ErrorEstimate:
        """Variant ``i``'s estimate (a batch's); the same estimate for a single run."""
        if self.variants is None:
            return self
        return replace(self, q=self.variants[i], variants=None)


@dataclass(frozen=True, eq=False)
class _Run:
    """Fields every result has.

    Attributes:
        t: output times, shape (N,) [s].
        q: joint coordinates [rad or m]: (N, nv) for one run, (B, N, nv) for a batch.
        qd: velocities [rad/s or m/s], same shape.
        tau: efforts the actuators applied at those states [N·m or N]: the law's,
            saturated at the effort limits when they apply (not the damping, friction
            or position-limit efforts); same shape (None for a batch run with
            ``efforts=False``).
        n_evals: right-hand-side (forward dynamics) evaluations (a batch: each
            evaluates all variants on the Pinocchio backend; the sum over the
            variants on the compiled one).
        wall_time: duration of the call [s].
        method: the integration method (see :mod:`rrt_pin.simulate.methods`).
        backend: ``"pinocchio"`` or ``"compiled"``.
        rtol: relative tolerance (adaptive methods), else None.
        atol: absolute tolerance [rad, m, rad/s, m/s] (adaptive methods), else None.
        step: longest step [s] (fixed-step methods), else None.
        n_jac: Jacobian evaluations (implicit methods with the analytic Jacobian).
        threads: threads the run used.
        q_names: coordinate names (``q1``…, or ``q_<joint>``).
        qd_names: velocity names (``qd1``…, or ``qd_<joint>``).
        tau_names: effort names (``T01x, T12y, F23z``, or ``tau_<joint>``).
        coordinate_units: each coordinate's unit, ``rad`` or ``m`` (the chapter's arm:
            rad, rad, m); velocities and efforts follow (rad/s, N·m; m/s, N).
        estimate: the estimate of the global error in q (:class:`ErrorEstimate`),
            or None (``estimate_error=False``, or no second run possible).
        estimate_failure: why ``estimate`` is None although it was asked for (the
            comparison run failed, with its error; or the tolerance cannot be
            tightened), else None. A failed comparison run also warns
            (:class:`~rrt_pin.simulate.estimate.EstimateWarning`).
        robot: the :class:`~rrt_pin.robot.robot.Robot` that moved (``show(result)``
            draws it), or None for a result made by hand; not pickled (a robot holds
            its model's factory).
        limits: what the run crossed, measured at the output samples against the
            robot's stated limits (enforced or not): a tuple of
            :class:`~rrt_pin.simulate.crossings.LimitEvent` (joint, kind, first time,
            extent, count, saturated time) for one run; for a batch, one such tuple
            a variant, or None where they were not measured (a compiled batch that
            kept no trajectories).
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
    n_jac: int = 0
    threads: int = 1
    q_names: tuple[str, ...] = CHAPTER_COLUMNS[0]
    qd_names: tuple[str, ...] = CHAPTER_COLUMNS[1]
    tau_names: tuple[str, ...] = CHAPTER_COLUMNS[3]
    coordinate_units: tuple[str, ...] = ("rad", "rad", "m")
    estimate: ErrorEstimate | None = None
    estimate_failure: str | None = None
    robot: Robot | None = field(default=None, repr=False)
    limits: Any = ()

    def __post_init__(self) -> None:
        for name in ("t", "q", "qd", "tau"):
            value = getattr(self, name)
            if value is None:
                continue
            if type(value) is np.ndarray and value.dtype == np.float64:
                if value.flags.writeable:
                    value.setflags(write=False)
                continue  # already what is kept: no conversion
            arr = np.asarray(value, dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "robot": None}

    @property
    def error_estimate(self) -> float | None:
        """Estimated global error of q: max over coordinates and times [rad or m], or None."""
        return None if self.estimate is None else self.estimate.max

    @property
    def error_estimate_q(self) -> np.ndarray | None:
        """Estimated global error per coordinate, max over times, shape (nv,) [rad or m]."""
        return None if self.estimate is None else self.estimate.q

    @property
    def header(self) -> tuple[str, ...]:
        """Column names of a table: t, coordinates, velocities, efforts."""
        return ("t", *self.q_names, *self.qd_names, *self.tau_names)

    @property
    def units(self) -> dict[str, str]:
        """The SI unit of every column of :attr:`header`."""
        rate = {"rad": "rad/s", "m": "m/s"}
        effort = {"rad": "N·m", "m": "N"}
        units = self.coordinate_units
        return {
            "t": "s",
            **dict(zip(self.q_names, units, strict=True)),
            **{n: rate.get(u, f"{u}/s") for n, u in zip(self.qd_names, units, strict=True)},
            **{n: effort.get(u, "") for n, u in zip(self.tau_names, units, strict=True)},
        }


@dataclass(frozen=True, eq=False)
class SimulationResult(_Run):
    """One simulated run, sampled at the output times (shapes (N, nv))."""

    def frame(self, name: str, velocity: bool = False) -> Any:
        """Frame ``name`` of the robot along the run (world frame).

        Its position [m], orientation quaternion (x, y, z, w), and with ``velocity`` its
        spatial velocity [m/s, rad/s] (:class:`~rrt_pin.dynamics.kinematics.FrameMotion`).

        Raises:
            InputError: the result has no robot (made by hand), or no such frame.
        """
        from rrt_pin.dynamics.kinematics import frame_motion

        return frame_motion(self._robot(), self.t, self.q, name, self.qd if velocity else None)

    def jacobian(self, name: str, k: int) -> np.ndarray:
        """Frame ``name``'s Jacobian (6, nv) at sample ``k`` (world-aligned; linear rows first).

        Raises:
            InputError: the result has no robot, no such frame, or no sample ``k``.
        """
        from rrt_pin.dynamics.kinematics import frame_jacobian

        if not -self.t.size <= k < self.t.size:
            raise InputError(f"sample k={k} is not one of the run's {self.t.size}")
        return frame_jacobian(self._robot(), self.q[k], name)

    def _robot(self) -> Robot:
        """The robot that moved (an error for a result without one)."""
        if self.robot is None:
            raise InputError("this result has no robot (made by hand, or unpickled)")
        return self.robot

    def table(self) -> np.ndarray:
        """The run as rows ``t, q…, qd…, tau…`` (SI units), shape (N, 1 + 3·nv)."""
        return np.column_stack((self.t, self.q, self.qd, self.tau))

    def to_frame(self) -> Any:
        """The run as a pandas DataFrame: columns :attr:`header`, one row per output time.

        ``frame.attrs["units"]`` maps each column to its SI unit, and
        ``frame.attrs["run"]`` holds the method, backend, tolerances and cost.
        Write it with ``frame.to_csv(path, index=False)`` or
        ``frame.to_parquet(path)`` (pyarrow keeps ``attrs`` in the file).

        Raises:
            ImportError: pandas is missing (``pip install rrt-pin[parquet]``).
        """
        try:
            import pandas as pd
        except ImportError as e:
            raise MissingExtra("pandas", "parquet", "to_frame") from e
        frame = pd.DataFrame(self.table(), columns=list(self.header))
        frame.attrs["units"] = self.units
        frame.attrs["run"] = {
            "method": self.method,
            "backend": self.backend,
            "rtol": self.rtol,
            "atol": self.atol,
            "step": self.step,
            "n_evals": self.n_evals,
            "wall_time": self.wall_time,
        }
        return frame


@dataclass(frozen=True, eq=False)
class BatchResult(_Run):
    """B variants sampled at the same output times (shapes (B, N, nv)).

    Attributes (besides those of every result):
        keep: what was kept of each variant: ``"trajectories"`` (every output
            time), ``"final"`` or ``"metrics"`` (the last output time only: ``t``
            holds that one time [s], q, qd and tau have shape (B, 1, nv)).
        metrics: with ``keep="metrics"``, the columns of
            :func:`rrt_pin.simulate.metrics.batch_metrics` (final_error_<q> [rad or m],
            settling_time_<q> [s], peak_effort_<τ> [N·m or N],
            peak_effort_time_<τ> [s], excursion_<q> [rad or m], control_energy
            [J], limit_violation_<q> [rad or m], saturation_time_<τ> [s],
            peak_demand_<τ> [N·m or N]), each of
            shape (B,), from the samples at every output time; else None.
        evaluations: dynamics evaluations of each variant (B,), where the backend
            counts them apart (the compiled backend's generated integrators); else None.
        failures: with ``failures="record"``, each variant's
            :class:`~rrt_pin.core.errors.DivergenceError`, or None where it succeeded (its
            states, efforts and metrics are NaN); else None.
    """

    keep: str = "trajectories"
    metrics: dict[str, np.ndarray] | None = None
    evaluations: np.ndarray | None = None
    failures: tuple[Any, ...] | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.metrics is not None:
            frozen = {}
            for name, value in self.metrics.items():
                arr = np.array(value, dtype=float)
                arr.setflags(write=False)
                frozen[name] = arr
            object.__setattr__(self, "metrics", frozen)

    def __len__(self) -> int:
        return int(self.q.shape[0])

    def variant(self, i: int) -> SimulationResult:
        """Variant ``i`` as a :class:`SimulationResult` (sharing the batch's cost figures).

        Raises:
            InputError: the batch ran with ``efforts=False`` (no efforts to hand over).
        """
        if self.tau is None:
            raise InputError("this batch ran with efforts=False: rerun with efforts=True")
        return SimulationResult(
            t=self.t,
            q=self.q[i],
            qd=self.qd[i],
            tau=self.tau[i],
            n_evals=self.n_evals,
            wall_time=self.wall_time,
            method=self.method,
            backend=self.backend,
            rtol=self.rtol,
            atol=self.atol,
            step=self.step,
            n_jac=self.n_jac,
            threads=self.threads,
            q_names=self.q_names,
            qd_names=self.qd_names,
            tau_names=self.tau_names,
            coordinate_units=self.coordinate_units,
            estimate=None if self.estimate is None else self.estimate.variant(i),
            estimate_failure=self.estimate_failure,
            robot=self.robot,
            limits=self.limits[i] if self.limits else (),
        )
