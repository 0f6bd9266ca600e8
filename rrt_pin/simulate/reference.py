"""Reference solutions of the direct dynamics, to judge the fast methods against.

A reference run integrates the closed loop at rtol 1e-13 with two unrelated
methods of scipy's ``solve_ivp`` – DOP853 (explicit Runge–Kutta, order 8) and
Radau (implicit Runge–Kutta, order 5) – on the plain right-hand side
``pin.aba(model, data, q, q̇, controller.efforts(t, q, q̇))`` (no gravity folding, no
shortcut shared with :mod:`rrt_pin.simulate`), and reports how far the two
disagree. The DOP853 solution is the reference.

:func:`chapter_reference` caches the chapter's run in a ``.npz`` file (in
``$RRT_PIN_CACHE_DIR/references`` or the system's temporary folder), keyed by the parameters,
the grid and the versions of Pinocchio and scipy.
"""

from __future__ import annotations

import hashlib
import io
import math
import os
import tempfile
import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.io.files import atomic_write_bytes
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.simulate.control import as_controller, chapter_controller

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.simulate.control import Controller

__all__ = [
    "REFERENCE_ATOL",
    "REFERENCE_RTOL",
    "Reference",
    "chapter_reference",
    "reference_run",
    "seed_reference",
]

REFERENCE_RTOL = 1e-13
#: Absolute tolerance of the reference [rad, m, rad/s, m/s].
REFERENCE_ATOL = 1e-15
REFERENCE_METHODS = ("DOP853", "Radau")
#: Bump when the way references are computed changes (invalidates the cache).
_VERSION = 2  # 2: the exact mount rotation (rrt_model)


@dataclass(frozen=True, eq=False)
class Reference:
    """A reference run and the disagreement of its two methods.

    Attributes:
        t: output times (N,) [s].
        q: positions (N, nv) of the first method [rad or m].
        qd: velocities (N, nv) of the first method [rad/s or m/s].
        methods: the methods (two, or one when only one was asked for).
        rtol: their relative tolerance.
        atol: their absolute tolerance.
        difference_q: max |q_a − q_b| over all times and joints [rad or m]
            (NaN with one method).
        difference_qd: max |q̇_a − q̇_b| [rad/s or m/s] (NaN with one method).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    methods: tuple[str, ...]
    rtol: float
    atol: float
    difference_q: float
    difference_qd: float


def reference_run(
    model: pin.Model,
    controller: Controller,
    q0: Sequence[float] | np.ndarray,
    qd0: Sequence[float] | np.ndarray,
    t_eval: Sequence[float] | np.ndarray,
    rtol: float = REFERENCE_RTOL,
    atol: float = REFERENCE_ATOL,
    methods: tuple[str, ...] = REFERENCE_METHODS,
) -> Reference:
    """Integrate the closed loop with two methods (or one) at a tight tolerance.

    Raises:
        InputError: an integrator failed or returned a non-finite state.
    """
    import pinocchio as pin
    from scipy.integrate import solve_ivp

    robot = Robot.from_model(model)
    law = as_controller(controller, model.nv)
    n = model.nv
    data = model.createData()

    def f(t: float, y: np.ndarray) -> np.ndarray:
        q, v = y[:n], y[n:]
        tau = law.efforts(t, q, v)
        return np.concatenate((v, pin.aba(model, data, robot.configuration(q), v, tau)))

    t = np.asarray(t_eval, dtype=float)
    y0 = np.concatenate((np.asarray(q0, dtype=float), np.asarray(qd0, dtype=float)))
    runs = []
    for method in methods:
        sol = solve_ivp(f, (t[0], t[-1]), y0, method=method, t_eval=t, rtol=rtol, atol=atol)
        if sol.status != 0 or sol.y.shape[1] != t.size or not np.isfinite(sol.y).all():
            raise InputError(f"reference run with {method} failed: {sol.message}")
        runs.append(sol.y.T)
    a, b = runs[0], runs[-1]
    two = len(runs) > 1
    return Reference(
        t=t,
        q=a[:, :n].copy(),
        qd=a[:, n:].copy(),
        methods=tuple(methods),
        rtol=rtol,
        atol=atol,
        difference_q=float(np.abs(a[:, :n] - b[:, :n]).max()) if two else math.nan,
        difference_qd=float(np.abs(a[:, n:] - b[:, n:]).max()) if two else math.nan,
    )


def _cache_dir() -> Path:
    """``$RRT_PIN_CACHE_DIR/references`` (the one cache variable), else the temporary folder's."""
    base = os.environ.get("RRT_PIN_CACHE_DIR")
    if base:
        return Path(base) / "references"
    old = os.environ.get("RRT_PIN_CACHE")
    if old:
        warnings.warn(
            "RRT_PIN_CACHE is deprecated: set RRT_PIN_CACHE_DIR (references go to its "
            "'references' folder)",
            DeprecationWarning,
            stacklevel=3,
        )
        return Path(old)
    return Path(tempfile.gettempdir()) / "rrt-pin-cache"


def chapter_reference(
    params: Params | None = None,
    tf: float = 15.0,
    dt: float = 0.01,
    cache: bool = True,
    cache_dir: str | Path | None = None,
) -> Reference:
    """The reference of the chapter's run: eq. (31) on the RRT arm, 0..tf at step dt [s].

    Args:
        params: the arm, gains, target and initial state (the chapter's by default).
        tf: final time [s].
        dt: output interval [s] (grid of :func:`rrt_pin.core.grid.time_grid`).
        cache: read and write the ``.npz`` cache.
        cache_dir: where (default ``$RRT_PIN_CACHE_DIR/references`` or ``<tmp>/rrt-pin-cache``).
    """
    import pinocchio as pin
    import scipy

    from rrt_pin.robot.model import rrt_model

    p = params if params is not None else Params()
    t = time_grid(tf, dt)
    key = hashlib.sha256(
        repr((_VERSION, sorted(p.as_dict().items()), pin.__version__, scipy.__version__)).encode()
        + t.tobytes()
    ).hexdigest()[:20]
    path = Path(cache_dir) if cache_dir is not None else _cache_dir()
    path = path / f"chapter-reference-{key}.npz"
    if cache and path.exists():
        try:
            with np.load(path) as z:
                return Reference(
                    t=z["t"],
                    q=z["q"],
                    qd=z["qd"],
                    methods=REFERENCE_METHODS,
                    rtol=REFERENCE_RTOL,
                    atol=REFERENCE_ATOL,
                    difference_q=float(z["difference_q"]),
                    difference_qd=float(z["difference_qd"]),
                )
        except (OSError, KeyError, ValueError):
            pass  # unreadable cache: recompute
    ref = reference_run(rrt_model(p), chapter_controller(p), p.q0, p.qd0, t)
    if cache:
        buffer = io.BytesIO()
        np.savez(
            buffer,
            t=ref.t,
            q=ref.q,
            qd=ref.qd,
            difference_q=ref.difference_q,
            difference_qd=ref.difference_qd,
        )
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_bytes(path, buffer.getvalue())
        except OSError:
            pass  # a cache that cannot be written is not an error
    return ref


#: Deprecated name of :func:`chapter_reference` (kept for one release).
seed_reference = chapter_reference
