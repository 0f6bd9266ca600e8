"""``rrt_pin.sweep``: run every chunk of a spec on Dask, store it, summarise it.

Without a scheduler address a :class:`distributed.LocalCluster` runs the
chunks: one worker in this process with a thread per core, since the compiled
batch and the metrics release the GIL (``scripts/bench_sweep.py`` measures it
against worker processes and a plain process pool; ``workers=1`` runs the
chunks in this process without Dask); with ``scheduler="tcp://host:port"`` the
same chunks go to that cluster, whose workers need only ``pip install
rrt-pin[sweep]``. Dask schedules, retries a chunk whose worker died, and moves
the data; results come back to this process, which writes each chunk as one
Parquet file (atomically) and records it in the manifest, so an interrupted
sweep resumes where it stopped.
"""

from __future__ import annotations

import heapq
import logging
import math
import numbers
import os
import sys
import time
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rrt_pin.errors import InputError, RrtPinError, SceneError
from rrt_pin.sweeps.spec import Spec, load_spec, spec_from_dict
from rrt_pin.text import duration

__all__ = ["SweepResult", "sweep"]

#: Chunks in flight per worker (enough to keep workers busy, few enough to keep memory flat).
IN_FLIGHT = 2
#: Worst variants listed in the summary.
WORST = 3
#: How long to try reaching a scheduler before saying it cannot be reached.
CONNECT_TIMEOUT = "5s"


@dataclass
class SweepResult:
    """What a sweep did and where it is.

    Attributes:
        out: the output folder.
        variants: variants in the spec.
        chunks: chunks in the spec.
        computed: chunks computed by this call (the others were done already).
        wall_time: duration of the call [s].
        computed_variants: variants in the chunks computed by this call.
        settled: variants (of those computed) whose every joint settled (2 % band)
            without diverging; None when the metrics do not include settling times.
        diverged: variants (of those computed) that diverged (or had invalid
            parameters); None when the task does not integrate (inverse dynamics).
        worst: (value, variant, varied values) of the largest final errors.
        metric: the metric the worst cases are ranked by.
    """

    out: Path
    variants: int
    chunks: int
    computed: int
    wall_time: float
    computed_variants: int = 0
    settled: int | None = None
    diverged: int | None = None
    worst: list[tuple[float, int, dict[str, float]]] = field(default_factory=list)
    metric: str = ""

    def table(self) -> Any:
        """Every variant's row (pyarrow Table, sorted by variant)."""
        from rrt_pin.sweeps.store import Store

        return Store(self.out).read()

    def summary(self) -> str:
        """One screen: counts, rate, the worst cases and their parameters.

        The rate is this call's: the variants it computed over its duration (after
        ``resume`` the chunks done before are not counted).
        """
        rate = self.computed_variants / self.wall_time if self.wall_time > 0 else math.nan
        lines = [f"sweep of {self.variants} variants in {self.chunks} chunks -> {self.out}/"]
        if not self.computed:
            lines.append("  nothing to compute: every chunk was done")
        elif self.computed == self.chunks:
            lines.append(
                f"  computed {self.computed} chunks in {duration(self.wall_time)} "
                f"({rate:,.0f} variants/s)"
            )
        else:
            lines.append(
                f"  computed {self.computed} of {self.chunks} chunks ({self.computed_variants:,} "
                f"variants) in {duration(self.wall_time)} ({rate:,.0f} variants/s in this run)"
            )
        counts = []
        if self.settled is not None:
            counts.append(f"settled (every joint, 2 %): {self.settled}")
        if self.diverged is not None:
            counts.append(f"diverged: {self.diverged}")
        if self.computed == self.chunks and counts:
            lines.append("  " + "; ".join(counts))
        for value, index, values in self.worst:
            params = ", ".join(f"{k}={v:.6g}" for k, v in values.items())
            lines.append(f"  worst {self.metric} = {value:.3g}: variant {index} ({params})")
        return "\n".join(lines) + "\n"


def _spec(spec: Spec | str | Path | Mapping[str, Any]) -> Spec:
    if isinstance(spec, Spec):
        return spec
    if isinstance(spec, Mapping):
        return spec_from_dict(spec)
    return load_spec(spec)


def _check_extremes(spec: Spec) -> None:
    """Refuse, before any work, a range whose ends make a parameter invalid (a negative mass)."""
    from rrt_pin.params import Params
    from rrt_pin.sweeps.compute import plan

    p = plan(spec)
    if spec.urdf is not None:
        for a in spec.axes:
            low = float(np.min(_ends(spec, a)))
            if a.name.startswith(("kp", "kd")) and low < 0:
                raise SceneError(f"[vary] {a.name} reaches {low:g}: a gain must be >= 0")
        return
    base = dict(spec.base)
    for a in spec.axes:
        for value in _ends(spec, a):
            try:
                Params(**{**base, a.name: float(value)})
            except RrtPinError as e:
                raise SceneError(f"[vary] {a.name} reaches {float(value):g}: {e}") from e
    del p


def _ends(spec: Spec, axis: Any) -> np.ndarray:
    if not axis.random:
        grid = axis.grid()
        return np.array([grid.min(), grid.max()])
    if axis.kind in ("uniform", "lhs"):
        return np.array(axis.args)
    col = spec.random_table()[axis.name]
    return np.array([col.min(), col.max()])


class _Worst:
    """The largest values of one metric, with their variants (a small heap)."""

    def __init__(self, size: int) -> None:
        self.size, self.heap = size, []

    def add(self, values: np.ndarray, index: np.ndarray, varied: Mapping[str, np.ndarray]) -> None:
        finite = np.flatnonzero(np.isfinite(values))
        for k in finite[np.argsort(values[finite])[-self.size :]]:
            item = (float(values[k]), int(index[k]), {n: float(c[k]) for n, c in varied.items()})
            if len(self.heap) < self.size:
                heapq.heappush(self.heap, item)
            else:
                heapq.heappushpop(self.heap, item)

    def items(self) -> list[tuple[float, int, dict[str, float]]]:
        return sorted(self.heap, reverse=True)


def _units(spec: Spec) -> dict[str, str]:
    from rrt_pin.sweeps.compute import plan

    robot = plan(spec).robot
    units = dict(robot.units)
    out = {"variant": "", "control_energy": "J", "evaluations": "", "diverged_time": "s"}
    for name in robot.q_names:
        for prefix in ("final_error", "excursion"):
            out[f"{prefix}_{name}"] = units[name]
        out[f"settling_time_{name}"] = "s"
    for name in robot.effort_names:
        out[f"peak_effort_{name}"] = units[name]
        out[f"peak_effort_time_{name}"] = "s"
    if spec.urdf is None:
        from rrt_pin.params import PARAM_DOCS

        for name, doc in PARAM_DOCS.items():
            out[name] = doc.rsplit("[", 1)[-1].split("]")[0] if "[" in doc else ""
    else:
        for a in spec.axes:
            out[a.name] = ""
    return out


def _client(scheduler: str | None, workers: int) -> tuple[Any, Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError as e:
        from rrt_pin.extras import MissingExtra

        raise MissingExtra("distributed", "sweep", "sweeps") from e
    for name in ("distributed", "tornado", "bokeh"):  # Dask's chatter stays off the terminal
        if logging.getLogger(name).getEffectiveLevel() < logging.ERROR:
            logging.getLogger(name).setLevel(logging.ERROR)
    if scheduler is not None:
        try:
            return Client(scheduler, timeout=CONNECT_TIMEOUT), None
        except (OSError, TimeoutError, ValueError) as e:
            raise InputError(f"cannot reach the Dask scheduler {scheduler!r}: {e}") from e
    # One worker with a thread per core: the compiled batch and the metrics release the GIL,
    # so threads need no copies between processes; measured in scripts/bench_sweep.py.
    cluster = LocalCluster(
        n_workers=1,
        threads_per_worker=workers,
        processes=False,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    return Client(cluster), cluster


def _in_process(
    spec: Spec, jobs: Iterator[tuple[int, int, int, dict]]
) -> Iterator[tuple[int, dict]]:
    from rrt_pin.sweeps.compute import run_chunk

    for k, start, stop, rows in jobs:
        yield k, run_chunk(spec.source, start, stop, rows)


def _on_dask(client: Any, spec: Spec, jobs: Iterator[tuple[int, int, int, dict]],
             workers: int) -> Iterator[tuple[int, dict]]:  # fmt: skip
    import uuid
    from concurrent.futures import CancelledError  # what a lost future raises

    from distributed import as_completed

    from rrt_pin.sweeps.compute import run_chunk

    queue = iter(jobs)
    run = uuid.uuid4().hex[:12]  # keys unique to this call: a scheduler may serve many sweeps
    pending: dict[int, tuple[int, int, int, dict]] = {}
    attempts: dict[int, int] = {}

    def submit(job: tuple[int, int, int, dict]) -> Any:
        k, start, stop, rows = job
        pending[k] = job
        attempts[k] = attempts.get(k, 0) + 1
        future = client.submit(
            run_chunk, spec.source, start, stop, rows,
            key=f"rrt-pin-sweep-{run}-chunk-{k}-{attempts[k]}", retries=3, pure=False,
        )  # fmt: skip
        future.chunk = k
        return future

    running = as_completed([submit(j) for _, j in zip(range(IN_FLIGHT * workers), queue,
                                                      strict=False)])  # fmt: skip
    for future in running:
        k = future.chunk
        try:
            result = future.result()
        except CancelledError:
            # the result died with its worker between computing and gathering: again
            if attempts[k] > 3:
                raise
            running.add(submit(pending[k]))
            continue
        future.release()
        del pending[k]
        nxt = next(queue, None)
        if nxt is not None:
            running.add(submit(nxt))
        yield k, result


def sweep(
    spec: Spec | str | Path | Mapping[str, Any],
    out: str | Path,
    *,
    scheduler: str | None = None,
    workers: int | None = None,
    resume: bool = False,
    progress: bool = True,
    on_chunk: Callable[[int, dict[str, Any]], object] | None = None,
) -> SweepResult:
    """Run a sweep: every variant of ``spec``, chunk by chunk, into ``out``.

    Args:
        spec: a :class:`~rrt_pin.sweeps.spec.Spec`, its dict, or a TOML file's path.
        out: the output folder (created; see :mod:`rrt_pin.sweeps.store`).
        scheduler: a Dask scheduler's address (``tcp://host:port``); None runs locally.
        workers: local worker processes (default: the CPUs available; 1: this process).
        resume: finish a sweep started in ``out`` (refused if its spec differs).
        progress: a progress bar on stderr (variants, rate, ETA).
        on_chunk: called with (chunk index, its result: ``index``, ``values``, ``columns``,
            ``seconds`` of compute) after each chunk is stored.

    Returns:
        A :class:`SweepResult` (counts, worst cases, ``.table()`` of every row).

    Raises:
        SceneError: a bad spec (unknown name, empty range, a range that makes a
            parameter invalid …).
        InputError: ``out`` is empty or not a path, holds another sweep or other
            files, is being written by another run, cannot be written, or (``resume``)
            holds another spec's sweep or a stray file in ``chunks/``; the scheduler
            is unreachable; or the extra ``sweep`` is not installed. A chunk that
            fails its check on ``resume`` is recomputed, with a warning.
    """
    from rrt_pin.sweeps.compute import BLOCK, plan
    from rrt_pin.sweeps.store import Store, folder_path

    out = folder_path(out)  # None, a list or "" refused before any work
    start_time = time.perf_counter()
    spec = _spec(spec)
    p = plan(spec)
    if spec.urdf is not None and spec.chunk % BLOCK:
        from dataclasses import replace

        spec = replace(spec, chunk=BLOCK * math.ceil(spec.chunk / BLOCK))
    _check_extremes(spec)
    if workers is not None:  # numpy integers too; never a bool, a float or a string
        if isinstance(workers, (bool, np.bool_)) or not isinstance(workers, numbers.Integral):
            raise InputError(f"workers must be an integer >= 1, not {type(workers).__name__}")
        if int(workers) < 1:
            raise InputError(f"workers={int(workers)} must be an integer >= 1")
        workers = int(workers)
    from rrt_pin import cpus

    n_workers = workers or cpus.available()
    robot = p.robot
    manifest = {
        "spec": spec.source,
        "spec_hash": spec.digest(),
        "variants": spec.variants,
        "chunk": spec.chunk,
        "chunks": len(spec.chunks),
        "columns": {"q": robot.q_names, "qd": robot.qd_names, "tau": robot.effort_names},
    }
    store = Store(out)
    store.check(manifest, resume)  # before any work or any file: one line, nothing written
    client = cluster = bar = None
    if scheduler is not None or n_workers > 1:
        client, cluster = _client(scheduler, n_workers)
    try:
        done = store.start(manifest, resume)
        table = spec.random_table() if spec.random_axes else {}
        todo = [(k, a, b) for k, (a, b) in enumerate(spec.chunks) if k not in done]
        jobs = (  # each chunk's random rows are cut when it is submitted: memory stays flat
            (k, a, b, spec.random_rows(table, a, b) if table else None) for k, a, b in todo
        )
        units = _units(spec)
        result = SweepResult(Path(out), spec.variants, len(spec.chunks), len(todo), 0.0)
        groups = spec.metrics
        worst = _Worst(WORST)
        result.metric = "max final_error" if "final_error" in groups else (
            "control_energy" if "control_energy" in groups else "")  # fmt: skip
        bar = _bar(progress, spec, done)
        if client is None:
            stream = _in_process(spec, jobs)
        else:
            stream = _on_dask(client, spec, jobs, n_workers)
        for k, chunk in stream:
            store.write_chunk(k, chunk, units)
            cols = chunk["columns"]
            result.computed_variants += len(chunk["index"])
            if "diverged" in cols:
                result.diverged = (result.diverged or 0) + int(np.count_nonzero(cols["diverged"]))
            settle = [c for n, c in cols.items() if n.startswith("settling_time_")]
            if settle:
                result.settled = (result.settled or 0) + int(
                    np.count_nonzero(np.isfinite(np.column_stack(settle)).all(axis=1))
                )
            ranked = _ranked(cols)
            if ranked is not None:
                worst.add(ranked, chunk["index"], chunk["values"])
            if bar is not None:
                bar.update(len(chunk["index"]))
            if on_chunk is not None:
                on_chunk(k, chunk)
    finally:
        store.close()  # releases the folder's lock
        if bar is not None:
            bar.close()
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    result.worst = worst.items()
    result.wall_time = time.perf_counter() - start_time
    return result


def _ranked(cols: Mapping[str, np.ndarray]) -> np.ndarray | None:
    errors = [c for n, c in cols.items() if n.startswith("final_error_")]
    if errors:
        stacked = np.column_stack(errors)
        # NaN (a diverged variant) ranks last: it has its own count in the summary
        return np.where(np.isnan(stacked), -np.inf, stacked).max(axis=1)
    return cols.get("control_energy")


def _bar(progress: bool, spec: Spec, done: set[int]) -> Any:
    if not progress:
        return None
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm comes with the sweep extra
        return None
    initial = sum(b - a for k, (a, b) in enumerate(spec.chunks) if k in done)
    return tqdm(
        total=spec.variants, initial=initial, unit="variant", unit_scale=True,
        file=sys.stderr, desc="sweep", smoothing=0.1, disable=not sys.stderr.isatty()
        and os.environ.get("RRT_PIN_PROGRESS") != "1",
    )  # fmt: skip
