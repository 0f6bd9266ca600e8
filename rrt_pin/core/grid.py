"""Time grids [s]: uniform, both ends included, validated at the boundary.

A grid can be built whole (:func:`time_grid`) or a slice at a time
(:func:`grid_slice`, bit for bit the same samples), so that a long run never
holds all its times at once; :func:`grid_size` counts the samples without
building any and refuses a grid of more than :data:`MAX_SAMPLES`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rrt_pin.core.errors import InputError

__all__ = ["MAX_SAMPLES", "Grid", "grid_size", "grid_slice", "time_grid"]

#: The most samples a grid may have (10⁹: 8 GB for the times alone, ~100 GB of CSV).
MAX_SAMPLES = 10**9


@dataclass(frozen=True)
class Grid:
    """A uniform grid, described without its samples.

    Attributes:
        t0: first time [s].
        tf: last time [s].
        dt: the step [s].
        size: number of samples, both ends included.
        step: the spacing the samples use [s] (``(tf - t0)/(size - 1)`` when ``tf - t0``
            is a whole number of steps, else ``dt`` and a shorter last interval).
        exact: whether ``tf - t0`` is a whole number of steps.
    """

    t0: float
    tf: float
    dt: float
    size: int
    step: float
    exact: bool


def _grid(tf: float, dt: float, t0: float = 0.0, what: str = "") -> Grid:
    for name, value in (("tf", tf), ("dt", dt), ("t0", t0)):
        if not isinstance(value, (int, float)) or not math.isfinite(value):
            raise InputError(f"{name}={value!r} must be a finite number [s]")
    tf, dt, t0 = float(tf), float(dt), float(t0)  # numpy scalars print as plain numbers
    span = tf - t0
    if not math.isfinite(span):
        raise InputError(f"tf - t0 = {tf!r} - {t0!r} is not a finite number [s]")
    if span <= 0.0:
        raise InputError(f"tf={tf!r} must be > t0={t0!r} [s]")
    if dt <= 0.0:
        raise InputError(f"dt={dt!r} must be > 0 [s]")
    if dt > span:
        raise InputError(f"dt={dt!r} is larger than tf - t0 = {span!r} [s]")
    steps = span / dt
    if not math.isfinite(steps) or steps >= MAX_SAMPLES:
        lead = f"{what}: " if what else ""
        raise InputError(
            f"{lead}tf={tf:g} s at dt={dt:g} s makes {_count(steps + 1)} samples, over the "
            f"{MAX_SAMPLES:,} allowed; use a larger dt or a shorter tf"
        )
    n = round(steps)
    if abs(steps - n) > 1e-9 * max(1.0, steps):
        n = math.ceil(steps)
        return Grid(float(t0), float(tf), float(dt), n + 1, float(dt), False)
    return Grid(float(t0), float(tf), float(dt), n + 1, span / n, True)


def _count(n: float) -> str:
    return f"{n:,.0f}" if n < 1e15 else f"{n:.3g}"


def grid_size(tf: float, dt: float, t0: float = 0.0, *, what: str = "") -> Grid:
    """The grid t0, t0 + dt, …, tf [s] described (its size) without building it.

    Args:
        tf: last time [s].
        dt: step [s].
        t0: first time [s].
        what: named first in the message of a grid too large (e.g. ``"--tf/--dt"``).

    Raises:
        InputError: as :func:`time_grid`.
    """
    return _grid(tf, dt, t0, what)


def grid_slice(grid: Grid, start: int, stop: int) -> np.ndarray:
    """Samples ``start`` to ``stop - 1`` of ``grid`` [s], equal bit for bit to ``time_grid``'s."""
    start, stop = max(0, start), min(grid.size, stop)
    t = np.arange(start, stop, dtype=float)
    if grid.exact:
        # numpy.linspace's arithmetic: i * step + t0, the last sample set to tf.
        t *= grid.step
        t += grid.t0
    else:
        t = grid.t0 + grid.dt * t
    if stop == grid.size and stop > start:
        t[-1] = grid.tf
    return t


def time_grid(tf: float, dt: float, t0: float = 0.0) -> np.ndarray:
    """Uniform grid t0, t0 + dt, …, tf [s], both ends included.

    ``tf - t0`` should be a whole number of steps; when it is not (beyond
    rounding), the last interval is shorter so that the grid still ends at tf.

    Raises:
        InputError: a value is not finite, ``tf <= t0``, ``dt <= 0``, ``dt > tf - t0``,
            or the grid would have more than :data:`MAX_SAMPLES` samples.
    """
    grid = _grid(tf, dt, t0)
    if grid.exact:
        return np.linspace(t0, tf, grid.size)
    return grid_slice(grid, 0, grid.size)
