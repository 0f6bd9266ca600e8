"""Inverse dynamics over many samples: joint efforts τ(q, q̇, q̈).

The engine of record is Pinocchio's recursive Newton–Euler algorithm (RNEA),
run in C++ over the whole batch by ``pin.rneaInParallel`` with a
``pin.ModelPool`` (one model/data copy per thread), so Python is not entered
once per sample. For the RRT arm, two other backends give the same efforts
from the closed-form equations of motion: ``"symbolic"`` (the generated numpy
kernel :mod:`rrt_pin.kernel`) and ``"compiled"`` (the numba backend
:mod:`rrt_pin.compiled`).

Units: q in rad (revolute) or m (prismatic), q̇ in rad/s or m/s, q̈ in rad/s²
or m/s²; efforts in N·m (revolute) or N (prismatic).
"""

from __future__ import annotations

import os
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.errors import InputError

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.params import Params

__all__ = ["BACKENDS", "batch_arrays", "default_num_threads", "inverse_dynamics"]

#: Backend names accepted by :func:`inverse_dynamics`.
BACKENDS = ("pinocchio", "symbolic", "compiled")

#: Fewer samples than this per thread are not worth another thread.
_MIN_SAMPLES_PER_THREAD = 256


def default_num_threads() -> int:
    """The CPUs this process may run on (at least 1), capped by ``OMP_NUM_THREADS`` if set."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        cpus = os.cpu_count() or 1
    try:
        cap = int(os.environ.get("OMP_NUM_THREADS", "").split(",")[0])
    except ValueError:
        cap = cpus
    return max(1, min(cpus, cap if cap > 0 else cpus))


def _array(name: str, value: object, width: int, width_name: str) -> np.ndarray:
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError) as e:
        raise InputError(f"{name} is not an array of numbers: {e}") from e
    if arr.ndim == 1:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise InputError(
            f"{name}.shape={np.shape(value)} but {width_name}={width}: want (N, {width})"
        )
    return arr


def batch_arrays(
    q: object, qd: object, qdd: object, nq: int, nv: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Validate a batch of states: shapes (N, nq), (N, nv), (N, nv), all finite.

    A single state (1-D arrays) is taken as a batch of one.

    Raises:
        InputError: a shape is wrong, the sample counts differ, or a value is
            not finite (the message names the array, sample and column).
    """
    arrays = (
        _array("q", q, nq, "model.nq"),
        _array("qd", qd, nv, "model.nv"),
        _array("qdd", qdd, nv, "model.nv"),
    )
    counts = {a.shape[0] for a in arrays}
    if len(counts) != 1:
        shapes = ", ".join(
            f"{n}.shape={a.shape}" for n, a in zip(("q", "qd", "qdd"), arrays, strict=True)
        )
        raise InputError(f"sample counts differ: {shapes}")
    for name, arr in zip(("q", "qd", "qdd"), arrays, strict=True):
        bad = ~np.isfinite(arr)
        if bad.any():
            i, j = (int(k) for k in np.argwhere(bad)[0])
            raise InputError(f"{name}[{i}, {j}]={float(arr[i, j])!r} must be finite")
    return arrays


def inverse_dynamics(
    model: pin.Model | None,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    *,
    backend: str = "pinocchio",
    params: Params | None = None,
    num_threads: int | None = None,
) -> np.ndarray:
    """Joint efforts τ = M(q)·q̈ + C(q, q̇)·q̇ + G(q) for each sample.

    Args:
        model: the Pinocchio model (any fixed-base arm); its gravity is used.
            Ignored (may be None) by the ``"symbolic"`` and ``"compiled"``
            backends, which take the RRT arm from ``params``.
        q: configurations, shape (N, model.nq) [rad or m]; (nq,) for one sample.
        qd: velocities, shape (N, model.nv) [rad/s or m/s].
        qdd: accelerations, shape (N, model.nv) [rad/s² or m/s²].
        backend: ``"pinocchio"`` (RNEA in C++ over the batch, any model),
            ``"symbolic"`` (the generated numpy kernel of the RRT arm) or
            ``"compiled"`` (the numba kernel of the RRT arm).
        params: the RRT arm's parameters; required by ``"symbolic"`` and
            ``"compiled"``.
        num_threads: threads for the Pinocchio backend; default: the CPUs
            available, fewer for small batches.

    Returns:
        Efforts, shape (N, nv) [N·m for revolute joints, N for prismatic ones].
        For the RRT arm the columns are (T01x, T12y, F23z).

    Raises:
        InputError: bad shapes, non-finite values, an unknown backend, or a
            backend that needs ``params`` or is not installed.
    """
    if backend == "pinocchio":
        if model is None:
            raise InputError("backend='pinocchio' needs a Pinocchio model")
        q, qd, qdd = batch_arrays(q, qd, qdd, model.nq, model.nv)
        return _rnea_batch(model, q, qd, qdd, num_threads)
    if backend not in BACKENDS:
        raise InputError(f"backend={backend!r} is unknown; valid: {', '.join(BACKENDS)}")
    if params is None:
        raise InputError(f"backend={backend!r} needs params (the RRT arm's Params)")
    if model is not None and (model.nq, model.nv) != (3, 3):
        raise InputError(
            f"backend={backend!r} is the RRT arm's kernel, but {model.nq=} and {model.nv=}; "
            "use backend='pinocchio' for other models"
        )
    q, qd, qdd = batch_arrays(q, qd, qdd, 3, 3)
    if backend == "symbolic":
        try:
            from rrt_pin import kernel
        except ImportError as e:
            raise InputError(
                "backend='symbolic' needs rrt_pin/kernel.py (generate it with the symbolic "
                f"derivation): {e}"
            ) from e
        return np.asarray(kernel.inverse_dynamics(q, qd, qdd, params), dtype=float)
    try:
        from rrt_pin import compiled

        compiled_id = compiled.inverse_dynamics
        available = getattr(compiled, "available", lambda: True)
    except (ImportError, AttributeError) as e:
        raise InputError(
            f"backend='compiled' is unavailable ({e}); it needs rrt_pin.compiled and numba: "
            "pip install rrt-pin[fast]"
        ) from e
    if not available():
        raise InputError(
            "backend='compiled' is unavailable (numba missing?): pip install rrt-pin[fast]"
        )
    return np.asarray(compiled_id(q, qd, qdd, params), dtype=float)


def _rnea_batch(
    model: pin.Model, q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, num_threads: int | None
) -> np.ndarray:
    """RNEA over a validated batch with ``pin.rneaInParallel``.

    Pinocchio wants one sample per column: (nq, N) and (nv, N) arrays in
    column-major order, which the transposes of C-ordered (N, ·) arrays are,
    so nothing is copied. The result (nv, N), column-major, transposes back to
    a C-ordered (N, nv) array.
    """
    import pinocchio as pin

    n = q.shape[0]
    if n == 0:
        return np.empty((0, model.nv))
    if num_threads is None:
        num_threads = default_num_threads()
    if isinstance(num_threads, bool) or not isinstance(num_threads, (int, np.integer)):
        raise InputError(f"num_threads={num_threads!r} must be an integer >= 1")
    if num_threads < 1:
        raise InputError(f"num_threads={num_threads!r} must be >= 1")
    threads = int(max(1, min(num_threads, n // _MIN_SAMPLES_PER_THREAD)))
    pool = pin.ModelPool(model, threads)
    tau = np.empty((model.nv, n), order="F")
    pin.rneaInParallel(
        threads,
        pool,
        np.ascontiguousarray(q).T,
        np.ascontiguousarray(qd).T,
        np.ascontiguousarray(qdd).T,
        tau,
    )
    return tau.T
