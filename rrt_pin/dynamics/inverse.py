"""Inverse dynamics over many samples: joint efforts τ(q, q̇, q̈).

The engine of record is Pinocchio's recursive Newton–Euler algorithm (RNEA),
run in C++ over the whole batch by ``pin.rneaInParallel`` with a
``pin.ModelPool`` (one model/data copy per thread), so Python is not entered
once per sample. For the RRT arm, two other backends give the same efforts
from the closed-form equations of motion: ``"symbolic"`` (the generated numpy
kernel :mod:`rrt_pin.dynamics.kernel`) and ``"compiled"`` (the numba backend
:mod:`rrt_pin.compiled`). For any other fixed-base robot whose joints are
revolute, prismatic or continuous, ``"compiled"`` runs the RNEA generated from
its Pinocchio model (:mod:`rrt_pin.dynamics.rnea_source`, :mod:`rrt_pin.compiled.rnea`).

Units: q in rad (revolute) or m (prismatic), q̇ in rad/s or m/s, q̈ in rad/s²
or m/s²; efforts in N·m (revolute) or N (prismatic).
"""

from __future__ import annotations

import threading
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core import backends, cpus, memory, validate
from rrt_pin.core.errors import ArgumentTypeError, InputError
from rrt_pin.core.identity import IdentityCache
from rrt_pin.dynamics import kernel
from rrt_pin.robot.params import check_params, plant_difference
from rrt_pin.robot.robot import CHAPTER_COLUMNS, Robot, bare_model, params_given

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.robot.params import Params

__all__ = ["batch_arrays", "default_num_threads", "inverse_dynamics"]

#: Fewer samples than this per thread are not worth another thread.
_MIN_SAMPLES_PER_THREAD = 256
#: Samples a ``pin.rneaInParallel`` call takes at most: inputs and efforts go through
#: in chunks of this many, so a continuous joint's configuration array is bounded, and
#: Pinocchio writes into a scratch buffer that stays in cache (writing straight into a
#: fresh result array costs ~8 % more: its cache lines are all misses).
CHUNK = 16_384


class _Pool:
    """A ``pin.ModelPool`` and the scratch efforts array its calls write into."""

    def __init__(self, model: Any, threads: int) -> None:
        import pinocchio as pin

        self.model = model
        self.pool = pin.ModelPool(model, threads)
        self.scratch = np.empty((model.nv, CHUNK), order="F")
        self.lock = threading.Lock()

    def fits(self, model: Any, threads: int) -> bool:
        return self.pool.size() >= threads and bool(self.pool.getModel(0) == model)


#: Pools kept between calls, by their model's identity.
_POOLS: IdentityCache[_Pool] = IdentityCache(8)


def _pool(model: Any, threads: int) -> _Pool:
    """A pool of ``model`` with at least ``threads`` copies, reused across calls.

    Reused only while the pool's copy still equals ``model`` (a changed mass, gravity
    or joint makes a new one).
    """
    entry = _POOLS.get(model)
    if entry is not None and entry.fits(model, threads):
        return entry
    return _POOLS.put(model, value=_Pool(model, threads))


def _num_threads(value: Any) -> int:
    """``num_threads`` as an int from 1 to :func:`rrt_pin.core.cpus.max_threads`.

    Raises:
        InputError: otherwise.
    """
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise InputError(f"num_threads={value!r} must be an integer >= 1")
    if value < 1:
        raise InputError(f"num_threads={value!r} must be >= 1")
    return cpus.check_threads("num_threads", value)


def _threads_that_fit(model: Any, threads: int, name: str | None) -> int:
    """``threads`` cut to the pool's copies of the model's data that fit in memory.

    ``pin.ModelPool`` holds one ``Data`` a thread and, while it is built, one more;
    the scratch efforts are :data:`CHUNK` samples.

    Raises:
        MemoryLimitError: not even one thread's copy fits.
    """
    data = memory.data_bytes(model)
    return memory.threads_that_fit(
        threads,
        memory.Cost(data) + memory.thread_cost(),
        fixed=memory.Cost(data + model.nv * CHUNK * 8),
        what=f"inverse dynamics of a {model.nv}-joint model",
        each=f"{memory.describe(data)} a copy of Pinocchio's Data: one a thread, one more "
        "while they are made",
        name=name,
    )


def default_num_threads() -> int:
    """The CPUs this process may run on (see :func:`rrt_pin.core.cpus.available`)."""
    return cpus.available()


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
        validate.samples("q", q, nq, "rad or m")[0],
        validate.samples("qd", qd, nv, "rad/s or m/s")[0],
        validate.samples("qdd", qdd, nv, "rad/s² or m/s²")[0],
    )
    _same_count(*arrays)
    return arrays


def inverse_dynamics(
    model: Any,
    q: Any,
    qd: np.ndarray | None = None,
    qdd: np.ndarray | None = None,
    *,
    backend: str | None = None,
    params: Params | None = None,
    num_threads: int | None = None,
) -> np.ndarray:
    """Joint efforts τ = M(q)·q̈ + C(q, q̇)·q̇ + G(q) for each sample.

    ``inverse_dynamics(robot, motion)``: a motion instead of the three arrays — a
    :class:`~rrt_pin.dynamics.sampled.SampledMotion` (:func:`rrt_pin.read_motion`
    of a user's file), a :class:`~rrt_pin.dynamics.trajectory.Trajectory`, or a data
    frame with columns ``t`` and the robot's ``q`` names (and, if known, its ``qd``
    and ``qdd`` names: the others are differentiated, see
    :mod:`rrt_pin.dynamics.sampled`).

    Args:
        model: a :class:`~rrt_pin.robot.robot.Robot` (any fixed-base robot; its
            gravity is used); a bare Pinocchio model is deprecated (pass
            ``Robot.from_model(model)``). The ``symbolic`` backend
            computes the chapter's arm: from the robot's parameters, or from
            ``params`` (``model`` may then be None); so does ``compiled`` then,
            and for any other robot or model (no ``params``) it runs the RNEA
            generated from the model (revolute, prismatic and continuous joints).
        q: joint coordinates, shape (N, nv) [rad or m] (angles for continuous
            joints; with a Pinocchio model, its (N, nq) configurations); (nv,)
            for one sample.
        qd: velocities, shape (N, nv) [rad/s or m/s] (None with a motion as ``q``).
        qdd: accelerations, shape (N, nv) [rad/s² or m/s²] (None with a motion).
        backend: a backend of :mod:`rrt_pin.core.backends` that computes ``inverse``, or
            ``auto``: for a Robot, the default (or ``$RRT_PIN_BACKEND``): ``compiled``
            when its code is built (the same efforts to ~1e-13), else the cheaper of
            ``pinocchio`` and, for the chapter's arm, ``symbolic``
            (:func:`rrt_pin.core.backends.choose`; ``-v`` logs which and why); for a
            bare model, ``pinocchio``.
        params: the chapter arm's parameters (``symbolic``/``compiled`` with a model);
            deprecated: pass ``chapter_arm(params)`` as the robot.
        num_threads: threads for the Pinocchio backend and the generated
            kernels, at most :func:`rrt_pin.core.cpus.max_threads` (256); default: the
            CPUs free now, fewer for small batches. Each Pinocchio thread holds a
            copy of the model's data (0.89 GB for a 300-joint chain): the count is
            cut to what fits in the memory left (:mod:`rrt_pin.core.memory`).

    Returns:
        Efforts, shape (N, nv) — (nv,) for a single sample, as ``pin.rnea`` —
        [N·m for revolute joints, N for prismatic ones]. For the chapter's arm
        the columns are (T01x, T12y, F23z).

    Raises:
        InputError: bad shapes, non-finite values (in or out: the first bad sample
            and joint named), an unknown backend, or a backend that does not
            compute this robot or is not installed; ``num_threads`` not from 1 to
            :func:`rrt_pin.core.cpus.max_threads`.
        MemoryLimitError: not even one copy of the model's data fits in the
            memory left (the need and the limit named).
    """
    if qd is None or qdd is None:
        q, qd, qdd = _motion(model, q, qd, qdd)
    if isinstance(model, Robot):  # the default (auto) by the one policy
        count = float(np.shape(q)[0]) if np.ndim(q) > 1 else 1.0
        backend = backends.decide(model, backend, "inverse", None, count).name
    b = backends.get("pinocchio" if backend is None else backend, "inverse")
    bare_model("inverse_dynamics", model)
    params_given("inverse_dynamics", params)
    _check_model_and_params(model, params, b.name)
    if num_threads is not None:
        num_threads = _num_threads(num_threads)
    robot = model if isinstance(model, Robot) else None
    return b.entry("inverse_runs")(b, model, robot, params, q, qd, qdd, num_threads)


def pinocchio_runs(
    b: Any,
    model: Any,
    robot: Robot | None,
    params: Any,
    q: Any,
    qd: Any,
    qdd: Any,
    num_threads: int | None,
) -> np.ndarray:  # noqa: ARG001  (every backend's ``inverse_runs`` takes the same)
    """The Pinocchio backend: ``pin.rneaInParallel`` over the samples (any model)."""
    if model is None:
        raise InputError("backend='pinocchio' needs a Robot or a Pinocchio model")
    if robot is not None:
        pin_model, nq = robot.model, robot.nv
    else:
        pin_model, nq = model, model.nq
    # Pinocchio turns a non-finite input into non-finite efforts: the inputs are
    # searched (and the bad one named) only when the efforts are not all finite.
    (q, qd, qdd), single = _samples_unchecked(q, qd, qdd, nq, pin_model.nv)
    configuration = robot.configuration if robot is not None else None
    tau = _rnea_batch(pin_model, q, qd, qdd, num_threads, configuration)
    if not np.isfinite(tau).all():
        _refuse_nonfinite((q, qd, qdd), tau, robot)
    return tau[0] if single else tau


def symbolic_runs(
    b: Any,
    model: Any,
    robot: Robot | None,
    params: Any,
    q: Any,
    qd: Any,
    qdd: Any,
    num_threads: int | None,
) -> np.ndarray:  # noqa: ARG001  (every backend's ``inverse_runs`` takes the same)
    """The chapter arm's closed form in numpy (:mod:`rrt_pin.dynamics.kernel`)."""
    params, q, qd, qdd, single = arm_samples(b.name, model, robot, params, q, qd, qdd, True)
    tau = np.asarray(kernel.inverse_dynamics(q, qd, qdd, params), dtype=float)
    _check_finite(tau, CHAPTER_COLUMNS[3])
    return tau[0] if single else tau


def arm_samples(
    backend: str,
    model: Any,
    robot: Robot | None,
    params: Any,
    q: Any,
    qd: Any,
    qdd: Any,
    finite: bool,
) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray, bool]:
    """The arm's Params and samples (N, 3) for a closed-form kernel, and whether one sample.

    ``finite``: refuse non-finite samples here (machine code flags them itself, then
    they are named as here: no numpy pass over the arrays).

    Raises:
        InputError: a robot or a model that is not the chapter's arm, bad samples.
    """
    if robot is not None:
        if not robot.supports(backend):
            raise InputError(
                f"backend={backend!r} computes the chapter's RRT arm only; {robot.name} needs "
                "backend='pinocchio'"
            )
        params = robot.params
    if params is None:
        raise InputError(f"backend={backend!r} needs the chapter's arm (its Params)")
    if model is not None and robot is None and (model.nq, model.nv) != (3, 3):
        raise InputError(
            f"backend={backend!r} is the RRT arm's kernel, but {model.nq=} and {model.nv=}; "
            "use backend='pinocchio' for other models"
        )
    named = (("q", q, "rad or m"), ("qd", qd, "rad/s or m/s"), ("qdd", qdd, "rad/s² or m/s²"))
    (q, single), (qd, _), (qdd, _) = (
        validate.samples(n, v, 3, u, finite=finite) for n, v, u in named
    )
    _same_count(q, qd, qdd)
    return params, q, qd, qdd, single


def _motion(model: Any, q: Any, qd: Any, qdd: Any) -> tuple[Any, Any, Any]:
    """The three arrays of a motion given as ``q`` (qd and qdd None)."""
    if qd is not None or qdd is not None:
        raise InputError("inverse_dynamics() needs qd and qdd with q, or a motion as q alone")
    if isinstance(q, np.ndarray) or not (hasattr(q, "qdd") or hasattr(q, "columns")):
        raise InputError(
            "inverse_dynamics() needs q, qd and qdd, or a motion (a SampledMotion, a "
            f"Trajectory or a data frame) as q; got {type(q).__name__} alone"
        )
    if hasattr(q, "qdd"):
        return q.q, q.qd, q.qdd
    if not isinstance(model, Robot):
        raise InputError("inverse_dynamics() of a data frame needs a Robot (its column names)")
    from rrt_pin.dynamics.sampled import motion_from_frame  # CSV and spline code: only here

    motion = motion_from_frame(q, model)
    return motion.q, motion.qd, motion.qdd


def generated_runs(
    b: Any, model: Any, robot: Any, q: Any, qd: Any, qdd: Any, num_threads: int | None
) -> np.ndarray:
    """The ``compiled`` backend on a robot or model without Params: its generated RNEA.

    An unsupported joint is refused (named) when the kernel is generated.
    """
    import pinocchio as pin

    if robot is None and not isinstance(model, pin.Model):
        raise InputError(f"model must be a Robot or a pinocchio.Model, not {type(model).__name__}")
    pin_model = robot.model if robot is not None else model
    nq = robot.nv if robot is not None else pin_model.nq
    # The kernel flags non-finite inputs and efforts itself (then they are named as below).
    (q, qd, qdd), single = _samples_unchecked(q, qd, qdd, nq, pin_model.nv)
    b.require()
    if num_threads is not None and num_threads > 1:  # a default never exceeds the free CPUs
        num_threads = memory.threads_that_fit(
            num_threads,
            memory.thread_cost(),
            allocating=True,
            what=f"inverse dynamics of a {pin_model.nv}-joint model",
            name="num_threads",
        )
    configuration = q if robot is None else robot.configuration(q)
    tau, finite = b.entry("inverse_generated")(pin_model, configuration, qd, qdd, num_threads)
    if not finite:
        _refuse_nonfinite((q, qd, qdd), tau, robot)
    return tau[0] if single else tau


def _check_model_and_params(model: Any, params: Any, backend: str) -> None:
    """Refuse a model of another type, and ``params`` that the backend would not use.

    ``params`` name the chapter's arm. With a Robot, or a model on the Pinocchio
    backend, they must be that arm's own (compared on
    :data:`rrt_pin.robot.params.PLANT_FIELDS`), else they would be silently ignored
    (Pinocchio computes the model given; a Robot brings its own parameters).

    Raises:
        ArgumentTypeError: ``model`` is not None, a Robot or a pinocchio.Model, or
            ``params`` is not a Params.
        InputError: ``params`` differ from the arm of the model given.
    """
    import sys

    pin = sys.modules.get("pinocchio")  # not imported: ``model`` cannot be one of its models
    if model is not None and not isinstance(model, Robot):
        if pin is None or not isinstance(model, pin.Model):
            raise ArgumentTypeError(
                "model",
                "model must be a rrt_pin.Robot, a pinocchio.Model, or None with params= (the "
                f"chapter's arm), not {type(model).__name__}",
            )
    if params is None:
        return
    params = check_params(params)
    if model is None or (not isinstance(model, Robot) and backend != "pinocchio"):
        return  # the kernels compute the arm of ``params`` (checked against the model's size)
    own = model.params if isinstance(model, Robot) else None
    if own is None and backend == "symbolic":
        return  # refused below: the kernel computes the chapter's arm only
    if own is not None:
        diff = plant_difference(params, own)
        why = f"differ from the robot's own ({diff})" if diff else None
    else:
        pin_model = model.model if isinstance(model, Robot) else model
        from rrt_pin.robot.model import chapter_model

        why = None if bool(pin_model == chapter_model(params)) else "are not the model's arm"
    if why:
        raise InputError(
            f"params= would be ignored: they {why}, and backend={backend!r} computes the "
            "model given; pass rrt_pin.robot.robots.chapter_arm(params), or leave params out"
        )


#: The inputs' names and units, in order.
_INPUTS = (("q", "rad or m"), ("qd", "rad/s or m/s"), ("qdd", "rad/s² or m/s²"))


def _samples_unchecked(
    q: Any, qd: Any, qdd: Any, nq: int, nv: int
) -> tuple[tuple[np.ndarray, np.ndarray, np.ndarray], bool]:
    """(q, qd, qdd) as (N, nq), (N, nv), (N, nv) arrays, not searched for non-finite values.

    For engines that turn a non-finite input into a non-finite effort (then
    :func:`_refuse_nonfinite` names it). Also whether a single sample was given.
    """
    checked = [
        validate.samples(name, value, width, unit, finite=False)
        for (name, unit), value, width in zip(_INPUTS, (q, qd, qdd), (nq, nv, nv), strict=True)
    ]
    q, qd, qdd = (a for a, _ in checked)
    _same_count(q, qd, qdd)
    return (q, qd, qdd), checked[0][1]


def _refuse_nonfinite(arrays: tuple[np.ndarray, ...], tau: np.ndarray, robot: Any) -> None:
    """Efforts not all finite: name the first non-finite input, else the overflowing effort."""
    for (name, unit), a in zip(_INPUTS, arrays, strict=True):
        validate.samples(name, a, a.shape[1], unit)
    _check_finite(tau, robot.effort_names if robot is not None else None)


def _check_finite(tau: np.ndarray, names: tuple[str, ...] | None) -> None:
    """Refuse non-finite efforts (finite inputs beyond any sensible range overflow)."""
    bad = ~np.isfinite(tau)
    if bad.any():
        i, k = (int(x) for x in np.argwhere(bad)[0])
        name = names[k] if names is not None else f"joint {k}"
        raise InputError(
            f"the efforts overflow: {name} = {float(tau[i, k])!r} at sample {i} "
            "(positions, velocities, accelerations or parameters beyond any sensible range)"
        )


def _same_count(*arrays: np.ndarray) -> None:
    counts = {a.shape[0] for a in arrays}
    if len(counts) != 1:
        shapes = ", ".join(
            f"{n}.shape={a.shape}" for n, a in zip(("q", "qd", "qdd"), arrays, strict=True)
        )
        raise InputError(f"sample counts differ: {shapes}")


def _rnea_batch(
    model: pin.Model,
    q: np.ndarray,
    qd: np.ndarray,
    qdd: np.ndarray,
    num_threads: int | None,
    configuration: Any = None,
) -> np.ndarray:
    """RNEA over a batch with ``pin.rneaInParallel``, in chunks of at most :data:`CHUNK`.

    Pinocchio wants one sample per column: (nq, n) and (nv, n) arrays in
    column-major order, which the transposes of C-ordered (n, ·) arrays are, so
    the inputs are not copied. ``configuration`` maps a chunk of joint coordinates
    to Pinocchio configurations (continuous joints); default: ``q`` already is.
    Default threads: the CPUs free now, none with fewer than 256 samples.
    """
    import pinocchio as pin

    n = q.shape[0]
    tau = np.empty((n, model.nv))
    if n == 0:
        return tau
    adaptive = num_threads is None
    if num_threads is None:
        num_threads = default_num_threads()
    num_threads = _num_threads(num_threads)
    threads = int(max(1, min(num_threads, n // _MIN_SAMPLES_PER_THREAD)))
    if adaptive and threads > 1:
        # A thread on a core another job holds makes the whole (statically split) call
        # wait for it: use only the CPUs that are free now.
        threads = min(threads, cpus.threads_for(n, _MIN_SAMPLES_PER_THREAD))
    kept = _POOLS.get(model)
    if kept is None or not kept.fits(model, threads):
        threads = _threads_that_fit(model, threads, None if adaptive else "num_threads")
    entry = _pool(model, threads)
    if not entry.lock.acquire(blocking=False):
        threads = _threads_that_fit(model, threads, None if adaptive else "num_threads")
        entry = _Pool(model, threads)  # another thread is using the kept pool
        entry.lock.acquire()
    try:
        pool, scratch = entry.pool, entry.scratch
        chunk = scratch.shape[1]
        for start in range(0, n, chunk):
            stop = min(n, start + chunk)
            qc = q[start:stop] if configuration is None else configuration(q[start:stop])
            out = scratch[:, : stop - start]
            pin.rneaInParallel(
                threads, pool, np.ascontiguousarray(qc).T, qd[start:stop].T, qdd[start:stop].T, out
            )
            tau[start:stop] = out.T
    finally:
        entry.lock.release()
    return tau
