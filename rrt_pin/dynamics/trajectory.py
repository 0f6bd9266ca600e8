"""The chapter's rest-to-rest motion, eq. (30), for any number of joints.

    q(t) = q(0) + (qf − q(0))/Tp · [t − Tp/(2π)·sin(2πt/Tp)],   0 ≤ t ≤ Tp

with its analytic derivatives

    q̇(t) = (qf − q(0))/Tp · [1 − cos(2πt/Tp)],
    q̈(t) = (qf − q(0))/Tp · (2π/Tp)·sin(2πt/Tp).

Velocity and acceleration vanish at both ends, so the arm starts and stops at
rest. Outside [0, Tp] the arm is held at rest: at q(0) before, at qf after.
Units follow the coordinates: rad, rad/s, rad/s² for revolute joints; m, m/s,
m/s² for prismatic ones; times in s.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rrt_pin.core import validate
from rrt_pin.core.errors import InputError

__all__ = ["RestToRest", "Trajectory", "rest_to_rest"]


@dataclass(frozen=True)
class Trajectory:
    """Samples of a prescribed motion (read-only arrays).

    Attributes:
        t: sample times, shape (N,) [s].
        q: coordinates, shape (N, n) [rad or m].
        qd: velocities, shape (N, n) [rad/s or m/s].
        qdd: accelerations, shape (N, n) [rad/s² or m/s²].
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray

    @property
    def n(self) -> int:
        """Number of coordinates."""
        return self.q.shape[1]

    def __len__(self) -> int:
        return self.t.shape[0]


def _vector(name: str, value: Sequence[float] | np.ndarray) -> np.ndarray:
    arr = np.asarray(value)
    if arr.ndim != 1 or arr.size == 0:
        raise InputError(f"{name} must be a non-empty 1-D sequence, got shape {arr.shape}")
    return validate.vector(name, value, arr.size, "rad or m")


def rest_to_rest(
    q0: Sequence[float] | np.ndarray,
    qf: Sequence[float] | np.ndarray,
    Tp: float,
    t: float | Sequence[float] | np.ndarray,
) -> Trajectory:
    """Eq. (30): from rest at ``q0`` (t = 0) to rest at ``qf`` (t = Tp).

    Args:
        q0: initial coordinates, n values [rad or m].
        qf: final coordinates, n values [rad or m].
        Tp: duration of the motion [s], > 0.
        t: sample times [s], a number or a 1-D sequence; times outside [0, Tp]
            hold the arm at rest (at q0 before 0, at qf after Tp).

    Returns:
        The samples; ``q``, ``qd``, ``qdd`` have shape (len(t), n).

    Raises:
        InputError: a value is not finite, ``Tp <= 0``, ``q0`` and ``qf``
            differ in length, or ``t`` is not a number or a 1-D sequence.
    """
    q0 = _vector("q0", q0)
    qf = _vector("qf", qf)
    if q0.shape != qf.shape:
        raise InputError(f"q0 has {q0.size} values but qf has {qf.size}")
    if isinstance(Tp, bool) or not isinstance(Tp, (int, float, np.floating, np.integer)):
        raise InputError(f"Tp={Tp!r} must be a number [s]")
    Tp = float(Tp)
    if not math.isfinite(Tp) or Tp <= 0.0:
        raise InputError(f"Tp={Tp!r} must be finite and > 0 [s]")
    try:
        times = np.array(t, dtype=float)
    except (TypeError, ValueError) as e:
        raise InputError(f"t={t!r} is not a number or a sequence of numbers [s]") from e
    if times.ndim > 1:
        raise InputError(f"t must be a number or 1-D, got shape {times.shape}")
    times = np.atleast_1d(times)
    bad = ~np.isfinite(times)
    if bad.any():
        i = int(np.argmax(bad))
        raise InputError(f"t[{i}]={float(times[i])!r} must be finite [s]")

    tau = np.clip(times, 0.0, Tp)  # outside [0, Tp]: at rest at an end
    phase = (2.0 * math.pi / Tp) * tau
    sin, cos = np.sin(phase), np.cos(phase)
    moving = ((times >= 0.0) & (times <= Tp)).astype(float)
    rate = (qf - q0) / Tp  # mean speed [rad/s or m/s]
    q = q0 + np.outer(tau - Tp / (2.0 * math.pi) * sin, rate)
    qd = np.outer(moving * (1.0 - cos), rate)
    qdd = np.outer(moving * (2.0 * math.pi / Tp) * sin, rate)
    if (times >= Tp).any():  # exactly qf at and after Tp, without rounding
        q[times >= Tp] = qf
    for arr in (times, q, qd, qdd):
        arr.flags.writeable = False
    return Trajectory(t=times, q=q, qd=qd, qdd=qdd)


@dataclass(frozen=True)
class RestToRest:
    """Eq. (30) as a function of time: ``motion(t)`` samples it (see :func:`rest_to_rest`).

    A tracking controller (:class:`~rrt_pin.simulate.control.TrackingController`) follows it.

    Attributes:
        q0: initial coordinates [rad or m].
        qf: final coordinates [rad or m].
        Tp: duration of the motion [s].
    """

    q0: tuple[float, ...]
    qf: tuple[float, ...]
    Tp: float

    def __post_init__(self) -> None:
        rest_to_rest(self.q0, self.qf, self.Tp, 0.0)  # validates
        object.__setattr__(self, "q0", tuple(float(v) for v in self.q0))
        object.__setattr__(self, "qf", tuple(float(v) for v in self.qf))
        object.__setattr__(self, "Tp", float(self.Tp))

    @property
    def n(self) -> int:
        """Number of coordinates."""
        return len(self.q0)

    def __call__(self, t: float | Sequence[float] | np.ndarray) -> Trajectory:
        """The samples at time(s) ``t`` [s]."""
        return rest_to_rest(self.q0, self.qf, self.Tp, t)
