"""One chunk of a sweep: the variants' values, their runs through the fastest batch path, metrics.

:func:`run_chunk` is what a worker runs: an importable function of picklable
arguments (the spec as a dict, the variant range, the random samples of that
range), returning plain numpy columns. The chapter's arm runs through the
compiled batch (each variant with its own step control, so a variant's result
never depends on the chunk it is in); any other URDF through Pinocchio's batch,
in blocks of :data:`BLOCK` variants aligned on the variant index (so, again,
the chunk size changes no result).
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from rrt_pin.core import backends, text
from rrt_pin.core.errors import DivergenceError, InputError, RrtPinError, SpecError
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.kernel import PARAM_ORDER
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.limits import physical_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import codes, simulate, simulate_batch
from rrt_pin.simulate.control import ChapterController, PDGravityController
from rrt_pin.simulate.metrics import GROUPS, batch_metrics, column_names, metric_columns
from rrt_pin.simulate.options import resolve
from rrt_pin.simulate.physical_runs import demanded
from rrt_pin.sweeps.spec import Spec, spec_from_dict

__all__ = ["BLOCK", "Plan", "metric_names", "plan", "run_chunk"]

#: Variants per Pinocchio batch (a URDF sweep's chunk is a multiple of it).
BLOCK = 64
_PREFIXES = ("q0", "qd0", "qf", "kp", "kd")


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
    """What every chunk of one spec shares: the robot, the options, the base values.

    Attributes:
        spec: the spec.
        robot: the robot (the chapter's arm built from the base parameters, or the URDF).
        names: the names the spec may vary.
        base: the base value of every name (the arm: every Params field).
        backend: ``compiled`` or ``pinocchio``.
        method, rtol, atol, step: the resolved integration options.
        t: the sample times of the metrics [s].
    """

    spec: Spec
    robot: Any
    names: tuple[str, ...]
    base: dict[str, float]
    backend: str
    method: str
    rtol: float | None
    atol: float | None
    step: float | None
    t: np.ndarray


def _arm_base(spec: Spec) -> tuple[Any, dict[str, float]]:

    names = [f.name for f in fields(Params)]
    for name in spec.base:
        if name not in names:
            raise SpecError(f"[base] {name}: unknown parameter; valid: {text.names(names, 20)}")
    try:
        params = Params(**spec.base)
    except RrtPinError as e:
        raise SpecError(f"[base]: {e}") from e
    return params, {n: getattr(params, n) for n in names}


@functools.lru_cache(maxsize=4)
def _plan(digest: str, source_json: str) -> Plan:
    import json

    spec = spec_from_dict(json.loads(source_json))

    if spec.chapter_arm:
        params, base = _arm_base(spec)
        robot = chapter_arm(params)
        names = tuple(base)
        backend = "compiled" if backends.get("compiled").available() else "pinocchio"
    else:
        robot = Robot.from_urdf(spec.urdf_file(), g=float(spec.base.get("g", 9.81)))
        n = robot.nv
        names = tuple(f"{p}_{k}" for p in _PREFIXES for k in range(1, n + 1))
        base = {name: math.nan for name in names}
        base.update({f"qd0_{k}": 0.0 for k in range(1, n + 1)})
        for key, value in spec.base.items():
            if key == "g":
                continue
            if key not in _PREFIXES:
                raise SpecError(f"[base] {key}: a URDF sweep takes g, {', '.join(_PREFIXES)}")
            values = [value] * n if not isinstance(value, list) else value
            if len(values) != n:
                raise SpecError(
                    f"[base] {key} has {len(values)} values; {robot.name} has {n} joints"
                )
            base.update({f"{key}_{k + 1}": float(v) for k, v in enumerate(values)})
        backend = "pinocchio"
        fast = backends.get("compiled")
        if spec.task == "simulate" and fast.available() and robot.supports(fast.name, "simulate"):
            runs = spec.method is None or backends._method_runs(spec.method, fast.name)
            backend = fast.name if runs else backend  # its generated integrators
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
    if spec.task == "inverse" and spec.chapter_arm:
        backend = "compiled" if backends.get("compiled").available() else "symbolic"
    t = time_grid(spec.tf, spec.dt)
    method = rtol = atol = step = None
    if spec.task == "simulate":
        try:
            options = resolve(
                t, backend=backend, method=spec.method, rtol=spec.rtol, atol=spec.atol,
                batch=True,
            )  # fmt: skip
        except RrtPinError as e:
            raise SpecError(f"[sweep]: {e}") from e
        method, rtol, atol, step = options.method.name, options.rtol, options.atol, options.step
    return Plan(spec, robot, names, base, backend, method, rtol, atol, step, t)


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

    return _plan(spec.digest(), json.dumps(spec.source))


# --------------------------------------------------------------------------- the arm
_POSITIVE = ("L1", "L2", "m1", "m2", "m3", "Tp")
_GAINS = ("beta01", "gamma01", "beta12", "gamma12", "beta23", "gamma23")
_BODIES = (("I1x", "I1y", "I1z"), ("I2x", "I2y", "I2z"), ("I3x", "I3y", "I3z"))


def arm_table(p: Plan, values: dict[str, np.ndarray], count: int) -> tuple[dict, np.ndarray, list]:
    """Every Params field of ``count`` variants, and which are invalid (with why).

    Rod inertias left at their defaults follow the varied masses and lengths, as in
    :class:`~rrt_pin.robot.params.Params`.
    """
    explicit = set(p.spec.base) | set(values)
    table = {n: np.broadcast_to(values.get(n, p.base[n]), (count,)).astype(float) for n in p.base}
    for rod, m, L in (("1", "m1", "L1"), ("2", "m2", "L2")):
        for axis in ("x", "y"):
            name = f"I{rod}{axis}"
            if name not in explicit:
                with np.errstate(over="ignore", invalid="ignore"):
                    table[name] = table[m] * table[L] ** 2 / 3.0
    bad = np.zeros(count, dtype=bool)
    why: list[str | None] = [None] * count

    def mark(mask: np.ndarray, text: str) -> None:
        for i in np.flatnonzero(mask & ~bad):
            why[i] = text
        bad[:] |= mask

    for name, col in table.items():
        mark(~np.isfinite(col), f"{name} is not finite")
    for name in _POSITIVE:
        mark(table[name] <= 0, f"{name} must be > 0")
    for name in _GAINS:
        mark(table[name] < 0, f"{name} must be >= 0")
    for body in _BODIES:
        moments = [table[n] for n in body]
        total = moments[0] + moments[1] + moments[2]
        for i, n in enumerate(body):
            mark(moments[i] < 0, f"{n} must be >= 0")
            mark(
                moments[i] > total - moments[i] + 1e-12 * total,
                f"{n} breaks the triangle inequality",
            )
    return table, bad, why


#: Variants integrated and measured at a time (their dense samples stay a few MB).
SUB_BLOCK = 128


def _arm_simulate(p: Plan, values: dict[str, np.ndarray], count: int, rows: list[int]) -> dict:

    table, bad, why = arm_table(p, values, count)
    P = np.column_stack([table[n] for n in PARAM_ORDER])
    C = np.column_stack(
        [table[n] for n in ("gamma01", "gamma12", "gamma23", "beta01", "beta12", "beta23")]
        + [table[n] for n in ("q1f", "q2f", "q3f")]
        + [P]
    )
    Y0 = np.column_stack([table[n] for n in ("q10", "q20", "q30", "qd10", "qd20", "qd30")])
    qf = np.column_stack([table[n] for n in ("q1f", "q2f", "q3f")])
    if p.backend != "compiled":
        return _arm_one_by_one(p, table, bad, why, qf, count, rows)
    from rrt_pin.compiled.lanes import failure, integrate_arrays

    P[bad], C[bad], Y0[bad] = P[~bad][:1] if (~bad).any() else P[bad], 0.0, 0.0
    kinds = np.full(count, codes.KIND_CHAPTER_FOLDED, dtype=np.int64)
    kinds[bad] = codes.KIND_NONE  # integrated harmlessly, then reported as invalid
    T = p.t.size
    buffers = None
    parts, failures, evals, keep = [], [None] * count, np.zeros(count), {}
    for a in range(0, count, SUB_BLOCK):
        b = min(a + SUB_BLOCK, count)
        # A block with no trajectory to keep has its metrics computed as its samples are
        # made (the same numbers, no (B, T, 9) arrays); see integrate_arrays's keep.
        lean = not any(a <= r < b for r in rows)
        if not lean and buffers is None:
            n = min(SUB_BLOCK, count)
            buffers = (np.empty((n, T, 6)), np.empty((n, T, 3)))
        y, tau, metrics, info, reached, _ = integrate_arrays(
            P[a:b], kinds[a:b], C[a:b], Y0[a:b], p.t, p.method, p.rtol, p.atol, p.step,
            out=None if lean else buffers, keep="metrics" if lean else "trajectories",
            qf=qf[a:b], detail=True,
        )  # fmt: skip
        evals[a:b] = info[:, 2]
        for k in np.flatnonzero(info[:, 0]):
            failures[a + k] = failure(info[k], reached[k], p.method, p.step)
        part = _finish(p, y[..., :3], y[..., 3:], tau, qf[a:b], evals[a:b], bad[a:b], why[a:b],
                       failures[a:b], metrics)  # fmt: skip
        parts.append(part["columns"])
        for k in (r for r in rows if a <= r < b):
            keep[k] = (y[k - a, :, :3].copy(), y[k - a, :, 3:].copy(), tau[k - a].copy())
    return {"columns": _concat(parts), "keep": keep}


def _concat(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {name: np.concatenate([part[name] for part in parts]) for name in parts[0]}


def _arm_one_by_one(p, table, bad, why, qf, count, rows):  # noqa: ANN001, ANN202
    """Without numba: one Pinocchio run per variant (each variant is its own model)."""
    n, T = 3, p.t.size
    q, qd, tau = np.full((count, T, n), np.nan), np.full((count, T, n), np.nan), None
    tau = np.full((count, T, n), np.nan)
    failures, evals = [None] * count, np.full(count, np.nan)
    for i in np.flatnonzero(~bad):
        params = Params(**{k: float(table[k][i]) for k in p.base})
        law = ChapterController(kp=params.kp, kd=params.kd, qf=params.qf, params=params)
        try:
            run = simulate(chapter_arm(params), law, params.q0, params.qd0, p.t,
                           method=p.method, rtol=p.rtol, atol=p.atol, step=p.step,
                           backend=p.backend, estimate_error=False)  # fmt: skip
        except DivergenceError as e:
            failures[i] = e
            continue
        q[i], qd[i], tau[i], evals[i] = run.q, run.qd, run.tau, run.n_evals
    part = _finish(p, q, qd, tau, qf, evals, bad, why, failures)
    keep = {k: (q[k], qd[k], tau[k]) for k in rows}
    return {"columns": part["columns"], "keep": keep}


def _urdf_simulate(p: Plan, values: dict, start: int, count: int, rows: list[int]) -> dict:

    robot, n = p.robot, p.robot.nv
    cols = {k: np.column_stack([np.broadcast_to(values.get(f"{k}_{j}", p.base[f"{k}_{j}"]),
                                                (count,)) for j in range(1, n + 1)])
            for k in _PREFIXES}  # fmt: skip
    bad = (cols["kp"] < 0).any(axis=1) | (cols["kd"] < 0).any(axis=1)
    why = ["a gain is negative" if b else None for b in bad]
    evals = np.full(count, np.nan)
    failures: list[DivergenceError | None] = [None] * count
    laws = [
        PDGravityController(kp=cols["kp"][i], kd=cols["kd"][i], qf=cols["qf"][i],
                            model=robot.model, robot=robot) if not bad[i] else None
        for i in range(count)
    ]  # fmt: skip
    options = {"method": p.method, "rtol": p.rtol, "atol": p.atol, "step": p.step,
               "backend": p.backend, "estimate_error": False}  # fmt: skip
    if p.backend == "compiled":
        return _urdf_metrics(p, cols, laws, bad, why, evals, failures, rows, options)
    q = np.full((count, p.t.size, n), np.nan)
    qd, tau = q.copy(), q.copy()
    # efforts only where a metric (or a kept trajectory) needs them
    efforts = bool({"peak_effort", "control_energy", "limits"} & set(p.spec.metrics)) or bool(rows)
    edges = sorted({0, count, *range((-start) % BLOCK, count, BLOCK)})
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        idx = [i for i in range(a, b) if not bad[i]]
        if not idx:
            continue
        try:
            run = simulate_batch(robot, [laws[i] for i in idx], cols["q0"][idx], cols["qd0"][idx],
                                 p.t, threads=1, efforts=efforts, **options)  # fmt: skip
            q[idx], qd[idx] = run.q, run.qd
            if efforts:
                tau[idx] = run.tau
            evals[idx] = run.n_evals
        except DivergenceError:  # find which: each variant on its own
            for i in idx:
                try:
                    one = simulate(robot, laws[i], cols["q0"][i], cols["qd0"][i], p.t, **options)
                except DivergenceError as e:
                    failures[i] = e
                    continue
                q[i], qd[i], tau[i], evals[i] = one.q, one.qd, one.tau, one.n_evals
    demand = None
    if efforts and "limits" in p.spec.metrics:  # the laws' efforts before saturation
        applied = physical_model(robot)  # a sweep applies the URDF's limits
        demand = demanded(p.t, q, qd, tau, laws, applied)
    part = _finish(p, q, qd, tau, cols["qf"], evals, bad, why, failures, demand=demand)
    return {"columns": part["columns"], "keep": {k: (q[k], qd[k], tau[k]) for k in rows}}


def _urdf_metrics(
    p: Plan, cols: dict, laws: list, bad: np.ndarray, why: list, evals: np.ndarray,
    failures: list, rows: list[int], options: dict,
) -> dict:  # fmt: skip
    """A URDF chunk on the compiled backend: each variant's metrics, its failure recorded.

    ``simulate_batch(..., keep="metrics", failures="record")``: the variants side by side in
    the generated integrators' lanes, metrics made as the samples are, no trajectory
    kept; a variant's numbers do not depend on the others, so neither on the chunks.
    The trajectories the spec keeps are run again alone.
    """
    robot, count = p.robot, len(laws)
    idx = [i for i in range(count) if not bad[i]]
    names = column_names(
        [g for g in p.spec.metrics if g in GROUPS], robot.q_names, robot.effort_names
    )
    columns = {name: np.full(count, np.nan) for name in names}
    if idx:
        run = simulate_batch(robot, [laws[i] for i in idx], cols["q0"][idx], cols["qd0"][idx],
                             p.t, keep="metrics", threads=1, failures="record", **options)  # fmt: skip
        for name in names:
            columns[name][idx] = run.metrics[name]
        evals[idx] = run.evaluations
        for j, i in enumerate(idx):
            failures[i] = run.failures[j]
    kept = {}
    for k in rows:  # only these: a chunk's trajectories would be (count, T, nv) each
        kept[k] = tuple(np.full((p.t.size, robot.nv), np.nan) for _ in range(3))
        if failures[k] is None and not bad[k]:
            one = simulate(robot, laws[k], cols["q0"][k], cols["qd0"][k], p.t, **options)
            kept[k] = (one.q, one.qd, one.tau)
    none = np.empty((count, 0, robot.nv))  # the columns are given: no samples needed
    part = _finish(p, none, none, none, cols["qf"], evals, bad, why, failures, columns=columns)
    return {"columns": part["columns"], "keep": kept}


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


def _inverse(p: Plan, values: dict[str, np.ndarray], count: int, rows: list[int]) -> dict:

    robot = p.robot
    n = robot.nv
    q = np.full((count, p.t.size, n), np.nan)
    qd, tau = q.copy(), q.copy()
    failures: list = [None] * count
    if p.spec.chapter_arm:
        table, bad, why = arm_table(p, values, count)
        for i in np.flatnonzero(~bad):
            params = Params(**{k: float(table[k][i]) for k in p.base})
            traj = rest_to_rest(params.q0, params.qf, params.Tp, p.t)
            q[i], qd[i] = traj.q, traj.qd
            try:
                tau[i] = inverse_dynamics(chapter_arm(params), traj.q, traj.qd, traj.qdd,
                                          backend=p.backend)  # fmt: skip
            except InputError as e:  # efforts that overflow: this variant fails, not the sweep
                failures[i] = _Failure(math.nan, "efforts", str(e))
        qf = np.column_stack([table[k] for k in ("q1f", "q2f", "q3f")])
    else:
        cols = {k: np.column_stack([np.broadcast_to(values.get(f"{k}_{j}", p.base[f"{k}_{j}"]),
                                                    (count,)) for j in range(1, n + 1)])
                for k in ("q0", "qf")}  # fmt: skip
        bad, why = np.zeros(count, dtype=bool), [None] * count
        Tp = float(p.spec.base.get("Tp", p.spec.tf))
        for i in range(count):
            traj = rest_to_rest(cols["q0"][i], cols["qf"][i], Tp, p.t)
            q[i], qd[i] = traj.q, traj.qd
            try:
                tau[i] = inverse_dynamics(robot, traj.q, traj.qd, traj.qdd, num_threads=1,
                                          backend=p.backend)  # fmt: skip
            except InputError as e:
                failures[i] = _Failure(math.nan, "efforts", str(e))
        qf = cols["qf"]
    part = _finish(p, q, qd, tau, qf, np.full(count, np.nan), bad, why, failures)
    return {"columns": part["columns"], "keep": {k: (q[k], qd[k], tau[k]) for k in rows}}


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
    if spec.task == "inverse":
        result = _inverse(p, values, count, rows)
    elif spec.chapter_arm:
        result = _arm_simulate(p, values, count, rows)
    else:
        result = _urdf_simulate(p, values, start, count, rows)
    return {
        "index": np.arange(start, stop),
        "values": values,
        "columns": result["columns"],
        "trajectories": {start + k: (p.t, *v) for k, v in result["keep"].items()},
        "seconds": time.perf_counter() - began,
    }
