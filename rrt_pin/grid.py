"""Time grids [s]: uniform, both ends included, validated at the boundary."""

from __future__ import annotations

import math

import numpy as np

from rrt_pin.errors import InputError

__all__ = ["time_grid"]


def time_grid(tf: float, dt: float, t0: float = 0.0) -> np.ndarray:
    """Uniform grid t0, t0 + dt, …, tf [s], both ends included.

    ``tf - t0`` should be a whole number of steps; when it is not (beyond
    rounding), the last interval is shorter so that the grid still ends at tf.

    Raises:
        InputError: a value is not finite, ``tf <= t0``, ``dt <= 0`` or ``dt > tf - t0``.
    """
    for name, value in (("tf", tf), ("dt", dt), ("t0", t0)):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"{name}={value!r} must be a finite number [s]")
    span = tf - t0
    if span <= 0.0:
        raise InputError(f"tf={tf!r} must be > t0={t0!r} [s]")
    if dt <= 0.0:
        raise InputError(f"dt={dt!r} must be > 0 [s]")
    if dt > span:
        raise InputError(f"dt={dt!r} is larger than tf - t0 = {span!r} [s]")
    steps = span / dt
    n = round(steps)
    if abs(steps - n) > 1e-9 * max(1.0, steps):
        n = math.ceil(steps)
        t = t0 + dt * np.arange(n + 1, dtype=float)
        t[-1] = tf
        return t
    t = np.linspace(t0, tf, n + 1)
    return t
