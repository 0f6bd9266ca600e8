"""One chunk of a sweep: the variants' values, their runs through the library's batch, metrics.

:func:`run_chunk` is what a worker runs: an importable function of picklable
arguments (the spec as a dict, the variant range, the random samples of that
range), returning plain numpy columns. The robot's family
(:mod:`rrt_pin.sweeps.variants`) turns the values into runs; every robot then goes
through :func:`rrt_pin.simulate.simulate_batch` (``keep="metrics"``,
``failures="record"``) or :func:`rrt_pin.dynamics.inverse.inverse_dynamics`, on the
backend ``$RRT_PIN_BACKEND`` names, else the one :func:`rrt_pin.core.backends.choose`
picks for a job that may build its code (the same in every process). A variant's numbers never depend on the chunk it is in:
a backend whose variants are independent runs the chunk as one batch; another in
blocks of :data:`BLOCK` variants aligned on the variant index.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from rrt_pin.core import backends, text
from rrt_pin.core.errors import DivergenceError, InputError, RrtPinError, SpecError
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.limits import physical_model
from rrt_pin.robot.robot import Robot
from rrt_pin.simulate import simulate, simulate_batch
from rrt_pin.simulate.metrics import GROUPS, batch_metrics, column_names, metric_columns
from rrt_pin.simulate.options import resolve
from rrt_pin.sweeps.spec import Spec, spec_from_dict
from rrt_pin.sweeps.variants import ChapterFamily, JointFamily, Variants, family_for

__all__ = ["BLOCK", "Plan", "block", "metric_names", "plan", "run_chunk"]

#: Variants per batch on a backend whose variants are not independent (a chunk is a
#: multiple of it there).
BLOCK = 64


@dataclass(frozen=True)
class _Failure:
    """A variant that failed without a time of divergence (inverse dynamics that overflow).

    Attributes:
        t: when [s] (NaN: not in time).
        coordinate: where ("" when the reason says it).
        reason: why, one line.
    """

    t: float
    coordinate: str
    reason: str

    def __str__(self) -> str:
        return self.reason


@dataclass(frozen=True, eq=False)
class Plan:
    """What every chunk of one spec shares: the robot, its family, the options, the base values.

    Attributes:
        spec: the spec.
        robot: the robot (the chapter's arm built from the base parameters, or the URDF).
        family: what varies and how a variant runs (:mod:`rrt_pin.sweeps.variants`).
        names: the names the spec may vary.
        base: the base value of every name (NaN: none; a run needs it varied).
        backend: the backend's name, and why it was chosen.
        method, rtol, atol, step: the resolved integration options.
        t: the sample times of the metrics [s].
    """

    spec: Spec
    robot: Robot
    family: ChapterFamily | JointFamily
    names: tuple[str, ...]
    base: dict[str, float]
    backend: str
    reason: str
    method: str | None
    rtol: float | None
    atol: float | None
    step: float | None
    t: np.ndarray


@functools.lru_cache(maxsize=4)
def _plan(digest: str, source_json: str, default: str) -> Plan:  # noqa: ARG001  (a key)
    import json

    spec = spec_from_dict(json.loads(source_json))
    family = family_for(spec)
    robot, names, base = family.start(spec)
    for axis in spec.axes:
        if axis.name not in names:
            raise SpecError(f"[vary] {axis.name}: unknown name; valid: {text.names(names, 20)}")
    needed = ("q0", "qf", "kp", "kd") if spec.task == "simulate" else ("q0", "qf")
    varied = {a.name for a in spec.axes}
    missing = [
        n for n, v in base.items()
        if math.isnan(v) and n not in varied and n.rsplit("_", 1)[0] in needed
    ]  # fmt: skip
    if missing:
        raise SpecError(f"[base] needs {missing[0].rsplit('_', 1)[0]} for {robot.name}")
    t = time_grid(spec.tf, spec.dt)
    work = spec.variants * (spec.tf if spec.task == "simulate" else t.size)
    # $RRT_PIN_BACKEND, else auto; every process of the sweep chooses alike
    choice = backends.decide(robot, None, spec.task, spec.method, work, batch=True, build=True)
    method = rtol = atol = step = None
    if spec.task == "simulate":
        try:
            options = resolve(
                t, backend=choice.name, method=spec.method, rtol=spec.rtol, atol=spec.atol,
                batch=True,
            )  # fmt: skip
        except RrtPinError as e:
            raise SpecError(f"[sweep]: {e}") from e
        method, rtol, atol, step = options.method.name, options.rtol, options.atol, options.step
    return Plan(spec, robot, family, names, base, choice.name, choice.reason, method, rtol,
                atol, step, t)  # fmt: skip


def metric_names(p: Plan) -> tuple[str, ...]:
    """The metric columns every chunk of the plan's spec has (text ones included)."""
    return tuple(column_names(p.spec.metrics, p.robot.q_names, p.robot.effort_names))


def plan(spec: Spec) -> Plan:
    """The shared part of every chunk (cached per process).

    Raises:
        SpecError: a name the robot does not have, a missing base value, or
            options the backend cannot run.
    """
    import json

    try:
        default = backends.default()
    except InputError as e:
        raise SpecError(str(e)) from e
    return _plan(spec.digest(), json.dumps(spec.source), default)


def block(p: Plan) -> int | None:
    """The variants a batch holds so that none depends on the chunk it is in (None: any).

    A backend whose variants are independent runs the chunk as one batch; variants
    with parameters of their own, on a backend that cannot batch them, run one by one
    (each its own robot); otherwise batches of :data:`BLOCK`, aligned on the variant index.
    """
    backend = backends.get(p.backend)
    if backend.independent_variants:
        return None
    own = p.spec.task == "simulate" and isinstance(p.family, ChapterFamily)
    return 1 if own and not backend.variant_params else BLOCK


def _blocks(p: Plan, v: Variants, start: int, count: int) -> list[list[int]]:
    """The chunk's valid variants (offsets), in the batches they run in."""
    size = block(p)
    edges = [0, count] if size is None else sorted({0, count, *range((-start) % size, count, size)})
    out = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        idx = [i for i in range(a, b) if not v.bad[i]]
        if idx:
            out.append(idx)
    return out


def _simulate(p: Plan, v: Variants, start: int, count: int, rows: list[int]) -> dict:
    """Each variant's metrics from ``simulate_batch(keep="metrics", failures="record")``.

    The trajectories the spec keeps are run again alone (a chunk's would be (count, T,
    nv) arrays each).
    """
    robot = p.robot
    names = column_names(
        [g for g in p.spec.metrics if g in GROUPS], robot.q_names, robot.effort_names
    )
    columns = {name: np.full(count, np.nan) for name in names}
    evals = np.full(count, np.nan)
    failures: list[Any] = [None] * count
    options = {"method": p.method, "rtol": p.rtol, "atol": p.atol, "step": p.step,
               "backend": p.backend, "estimate_error": False}  # fmt: skip
    alone = block(p) == 1  # each variant its own robot
    for idx in _blocks(p, v, start, count):
        shared = v.robot(idx[0], robot) if alone else robot
        own = None if alone or v.params is None else [v.params[i] for i in idx]
        run = simulate_batch(
            shared, [v.laws[i] for i in idx], v.q0[idx], v.qd0[idx], p.t, keep="metrics",
            threads=1, failures="record", params=own, **options,
        )  # fmt: skip
        for name in names:
            columns[name][idx] = run.metrics[name]
        evals[idx] = run.n_evals if run.evaluations is None else run.evaluations
        for j, i in enumerate(idx):
            failures[i] = run.failures[j]
    kept = {}
    for k in rows:
        kept[k] = tuple(np.full((p.t.size, robot.nv), np.nan) for _ in range(3))
        if failures[k] is None and not v.bad[k]:
            one = simulate(v.robot(k, robot), v.laws[k], v.q0[k], v.qd0[k], p.t, **options)
            kept[k] = (one.q, one.qd, one.tau)
    none = np.empty((count, 0, robot.nv))  # the columns are given: no samples needed
    part = _finish(p, none, none, none, v.qf, evals, v.bad, v.why, failures, columns=columns)
    return {"columns": part["columns"], "keep": kept}


def _inverse(p: Plan, v: Variants, count: int, rows: list[int]) -> dict:
    """Each variant's rest-to-rest motion and its efforts, then their metrics."""
    robot = p.robot
    q = np.full((count, p.t.size, robot.nv), np.nan)
    qd, tau = q.copy(), q.copy()
    failures: list = [None] * count
    for i in np.flatnonzero(~v.bad):
        traj = rest_to_rest(v.q0[i], v.qf[i], float(v.Tp[i]), p.t)
        q[i], qd[i] = traj.q, traj.qd
        try:
            tau[i] = inverse_dynamics(v.robot(i, robot), traj.q, traj.qd, traj.qdd,
                                      num_threads=1, backend=p.backend)  # fmt: skip
        except InputError as e:  # efforts that overflow: this variant fails, not the sweep
            failures[i] = _Failure(math.nan, "efforts", str(e))
    part = _finish(p, q, qd, tau, v.qf, np.full(count, np.nan), v.bad, v.why, failures)
    return {"columns": part["columns"], "keep": {k: (q[k], qd[k], tau[k]) for k in rows}}


def _finish(
    p: Plan,
    q: np.ndarray,
    qd: np.ndarray,
    tau: np.ndarray,
    qf: np.ndarray,
    evals: np.ndarray,
    bad: np.ndarray,
    why: list,
    failures: list,
    metrics: np.ndarray | None = None,
    columns: dict[str, np.ndarray] | None = None,
    demand: np.ndarray | None = None,
) -> dict[str, Any]:
    """The block's columns: metrics, evaluations and failures.

    The metrics are ``columns`` when given, else from ``metrics`` rows when the
    compiled loop made them, else from the samples q, qd, tau (``demand``: the laws'
    efforts before saturation, for the ``limits`` group; None: tau), measured against
    the robot's stated limits.
    """
    robot = p.robot
    groups = p.spec.metrics
    if columns is not None:
        columns = {name: col.copy() for name, col in columns.items()}
    elif metrics is not None:
        columns = metric_columns(groups, metrics, robot.q_names, robot.effort_names)
        columns = {name: col.copy() for name, col in columns.items()}
    else:
        stated = physical_model(robot) if "limits" in groups else None
        with np.errstate(invalid="ignore"):
            columns = batch_metrics(
                groups, p.t, q, qd, tau, qf, robot.q_names, robot.effort_names,
                compiled=p.backend == "compiled", stated=stated, demanded=demand,
            )  # fmt: skip
    failed = np.array([f is not None for f in failures], dtype=bool) | bad
    if "evaluations" in groups:
        columns["evaluations"] = np.where(bad, np.nan, evals)
    if "diverged" in groups:
        columns["diverged"] = failed
        columns["diverged_time"] = np.array(
            [f.t if f is not None else np.nan for f in failures], dtype=float
        )
        columns["diverged_coordinate"] = np.array(
            [f.coordinate if f is not None else ("parameters" if bad[i] else "")
             for i, f in enumerate(failures)], dtype=object
        )  # fmt: skip
        columns["diverged_reason"] = np.array(
            [_reason(f) if f is not None else (why[i] or "") for i, f in enumerate(failures)],
            dtype=object,
        )
    for name, col in columns.items():  # a failed variant has no metric
        if col.dtype == float and name not in ("diverged_time",):
            col[failed] = np.nan
    return {"columns": columns}


def _reason(failure: DivergenceError | _Failure) -> str:
    """Why a variant failed: the message after "simulation diverged at … in q2: "."""
    if isinstance(failure, _Failure):
        return failure.reason
    return str(failure).split(": ", 1)[-1]


def run_chunk(
    source: dict[str, Any], start: int, stop: int, random: dict[str, np.ndarray] | None = None
) -> dict[str, Any]:
    """Run variants ``start`` … ``stop − 1`` of the spec ``source`` (a dict, as in the TOML).

    Args:
        source: the spec's dict.
        start: first variant index.
        stop: one past the last.
        random: this range's random samples by name (:meth:`Spec.random_rows`);
            drawn here from the seed when None.

    Returns:
        ``{"index", "values", "columns", "trajectories", "seconds"}``: the variant
        indices, their varied values and metric columns (numpy arrays), the dense
        runs of the variants the spec keeps (``{index: (t, q, qd, tau)}``), and the
        chunk's compute time [s].
    """
    import time

    began = time.perf_counter()
    spec = spec_from_dict(source)
    p = plan(spec)
    count = stop - start
    values = spec.values(start, stop, random)
    rows = [i - start for i in spec.trajectories if start <= i < stop]
    v = p.family.build(p.base, spec, p.robot, values, count, laws=spec.task == "simulate")
    if spec.task == "inverse":
        result = _inverse(p, v, count, rows)
    else:
        result = _simulate(p, v, start, count, rows)
    return {
        "index": np.arange(start, stop),
        "values": values,
        "columns": result["columns"],
        "trajectories": {start + k: (p.t, *v) for k, v in result["keep"].items()},
        "seconds": time.perf_counter() - began,
    }
