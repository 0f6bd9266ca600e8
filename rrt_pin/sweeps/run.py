"""``rrt_pin.sweep``: run every chunk of a spec on Dask, store it, summarise it.

Without a scheduler address a :class:`distributed.LocalCluster` runs the
chunks: one worker in this process with a thread per core, since the compiled
batch and the metrics release the GIL (``scripts/bench/sweep.py`` measures it
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

from rrt_pin.core import cpus
from rrt_pin.core.errors import ArgumentTypeError, ClusterError, InputError, SpecError
from rrt_pin.core.extras import MissingExtra
from rrt_pin.core.text import duration
from rrt_pin.simulate.metrics import column_units
from rrt_pin.sweeps.spec import Spec, load_spec, spec_from_dict

__all__ = ["SweepResult", "sweep"]

#: Chunks in flight per worker (enough to keep workers busy, few enough to keep memory flat).
IN_FLIGHT = 2
#: Worst variants listed in the summary.
WORST = 3
#: How long to wait for a scheduler: the connection and Dask's handshake, together [s].
CONNECT_TIMEOUT = 5.0
#: How long a sweep waits while its cluster has no worker before it stops (default) [s].
WORKER_TIMEOUT = 60.0
#: How often a sweep waiting for chunks looks whether its cluster still has workers [s].
POLL = 1.0
#: Transports a scheduler elsewhere may be reached by.
_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")


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
    if isinstance(spec, (str, os.PathLike)) and not isinstance(spec, bytes):
        if not os.fspath(spec):
            raise SpecError("spec='' must name a TOML file")
        return load_spec(spec)

    raise ArgumentTypeError(
        "spec",
        f"spec= must be a Spec, a dict or a TOML file's path, not {type(spec).__name__}",
    )


def _check_extremes(spec: Spec) -> None:
    """Refuse, before any work, a range whose ends make a parameter invalid (a negative mass)."""
    from rrt_pin.sweeps.compute import plan

    family = plan(spec).family
    for a in spec.axes:
        family.check_ends(spec, a.name, _ends(spec, a))


def _ends(spec: Spec, axis: Any) -> np.ndarray:
    """The smallest and largest values an axis reaches (a grid's without making it)."""
    if axis.kind != "normal":
        return np.array(axis.ends())
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
    out = {"variant": ""}
    out.update(column_units(spec.metrics, robot.q_names, robot.effort_names, robot.units))
    out.update(plan(spec).family.units(spec))
    return out


def _reach(address: str, timeout: float) -> None:
    """Connect to ``address`` and finish Dask's handshake within ``timeout`` seconds, or say why.

    ``Client(timeout=)`` bounds the TCP connection only: a port that accepts and says
    nothing would hold it forever. Here the whole exchange has one deadline.

    Raises:
        ClusterError: one line naming the address and what went wrong.
    """
    import asyncio

    from distributed.comm import connect
    from distributed.comm.core import CommClosedError
    from distributed.security import Security

    def fail(why: str) -> ClusterError:
        return ClusterError(address, f"cannot reach the Dask scheduler {address!r}: {why}", timeout)

    scheme = address.split("://", 1)[0] if "://" in address else "tcp"
    if scheme not in _SCHEMES:
        raise fail(f"not an address like tcp://host:port (schemes: {', '.join(_SCHEMES)})")
    try:
        args = Security().get_connection_args("client")
    except Exception as e:  # a TLS configuration that does not load
        raise fail(f"Dask's TLS settings do not load: {_one_line(e)}") from None

    async def probe() -> None:
        # the connection's own deadline comes first: a port that refuses is told apart
        comm = await connect(address, timeout=0.8 * timeout, **args)
        await comm.close()

    try:
        asyncio.run(asyncio.wait_for(probe(), timeout))
    except TimeoutError as e:
        if str(e).startswith("Timed out trying to connect"):
            raise fail(f"no connection within {timeout:g} s") from None
        raise fail(
            f"it accepted the connection but gave no Dask handshake within {timeout:g} s "
            "(is it a Dask scheduler's port?)"
        ) from None
    except CommClosedError:
        raise fail("it closed the connection without a Dask handshake") from None
    except OSError as e:
        if str(e).startswith("Timed out trying to connect"):
            raise fail(f"no connection within {timeout:g} s") from None
        raise fail(_one_line(e)) from None
    except ValueError as e:
        if "address" in str(e) or "port" in str(e) or "scheme" in str(e):
            raise fail(f"not an address like tcp://host:port ({_one_line(e)})") from None
        raise fail(f"it answered, but not in Dask's protocol ({_one_line(e)})") from None
    except (TypeError, ImportError) as e:
        if scheme == "tls":
            raise fail(
                "tls:// needs Dask's TLS settings (distributed.comm.tls: ca-file, and the "
                "client's cert and key)"
            ) from None
        if scheme == "ucx":
            raise fail(
                "the ucx:// transport is not available here (UCX and its Dask package)"
            ) from None
        raise fail(f"the {scheme}:// transport cannot be used ({_one_line(e)})") from None
    except MemoryError:  # garbage read as the sizes of Dask's frames
        raise fail("it answered, but not in Dask's protocol (frames of absurd sizes)") from None
    except Exception as e:  # garbage read as Dask's messages: bad msgpack …
        raise fail(f"it answered, but not in Dask's protocol ({_one_line(e)})") from None


def _one_line(e: BaseException, limit: int = 120) -> str:
    """An exception as a short line: its type when it has no message."""
    text = " ".join(str(e).split()) or type(e).__name__
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _client(scheduler: str | None, workers: int) -> tuple[Any, Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError as e:
        raise MissingExtra("distributed", "sweep", "sweeps") from e
    for name in ("distributed", "tornado", "bokeh", "asyncio"):  # Dask's chatter stays quiet
        if logging.getLogger(name).getEffectiveLevel() < logging.ERROR:
            logging.getLogger(name).setLevel(logging.ERROR)
    if scheduler is not None:
        _reach(scheduler, CONNECT_TIMEOUT)
        try:
            return Client(scheduler, timeout=CONNECT_TIMEOUT), None
        except Exception as e:  # reached a moment ago: whatever broke since, one line
            raise ClusterError(
                scheduler, f"cannot reach the Dask scheduler {scheduler!r}: {_one_line(e)}"
            ) from None
    # One worker with a thread per core: the compiled batch and the metrics release the GIL,
    # so threads need no copies between processes; measured in scripts/bench/sweep.py.
    cluster = LocalCluster(
        n_workers=1,
        threads_per_worker=workers,
        processes=False,
        dashboard_address=None,
        silence_logs=logging.ERROR,
    )
    return Client(cluster), cluster


def _workers(client: Any, address: str) -> int:
    """How many workers the cluster has now."""
    if client.status in ("closing", "closed"):
        raise ClusterError(address, f"lost the Dask scheduler {address!r}: the sweep stopped")
    try:
        return len(client.nthreads())
    except Exception as e:  # the scheduler went away while we asked
        raise ClusterError(
            address, f"lost the Dask scheduler {address!r}: {_one_line(e)}"
        ) from None


def _in_process(
    spec: Spec, jobs: Iterator[tuple[int, int, int, dict]]
) -> Iterator[tuple[int, dict]]:
    from rrt_pin.sweeps.compute import run_chunk

    for k, start, stop, rows in jobs:
        yield k, run_chunk(spec.source, start, stop, rows)


def _on_dask(client: Any, spec: Spec, jobs: Iterator[tuple[int, int, int, dict]],
             workers: int, address: str, worker_timeout: float) -> Iterator[tuple[int, dict]]:  # fmt: skip
    """Chunks on the cluster, yielded as they finish.

    While nothing finishes, the cluster is looked at every :data:`POLL` seconds: with no
    worker for ``worker_timeout`` seconds (all lost, or none ever came) the sweep stops
    with a :class:`ClusterError`; the chunks yielded so far are stored by then.
    """
    import itertools
    import uuid
    from concurrent.futures import CancelledError  # what a lost future raises

    from distributed import wait

    from rrt_pin.sweeps.compute import run_chunk

    queue = iter(jobs)
    run = uuid.uuid4().hex[:12]  # keys unique to this call: a scheduler may serve many sweeps
    pending: dict[int, tuple[int, int, int, dict]] = {}
    attempts: dict[int, int] = {}
    running: list[Any] = []

    def submit(job: tuple[int, int, int, dict]) -> None:
        k, start, stop, rows = job
        pending[k] = job
        attempts[k] = attempts.get(k, 0) + 1
        future = client.submit(
            run_chunk, spec.source, start, stop, rows,
            key=f"rrt-pin-sweep-{run}-chunk-{k}-{attempts[k]}", retries=3, pure=False,
        )  # fmt: skip
        future.chunk = k
        running.append(future)

    for job in itertools.islice(queue, IN_FLIGHT * workers):
        submit(job)
    alone_since: float | None = None  # since when the cluster has had no worker
    while running:
        try:
            done = wait(
                running, timeout=min(POLL, worker_timeout), return_when="FIRST_COMPLETED"
            ).done
        except TimeoutError:
            done = set()
        if not done:
            if _workers(client, address):
                alone_since = None
            elif alone_since is None:
                alone_since = time.monotonic()
            elif time.monotonic() - alone_since >= worker_timeout:
                raise ClusterError(
                    address,
                    f"the Dask cluster {address!r} has had no worker for {worker_timeout:g} s: "
                    "the sweep stopped; the chunks done are kept (resume the sweep to continue)",
                    worker_timeout,
                )
            continue
        alone_since = None
        for future in [f for f in running if f in done]:
            running.remove(future)
            k = future.chunk
            try:
                result = future.result()
            except CancelledError:
                # the result died with its worker between computing and gathering: again
                if attempts[k] > 3:
                    raise ClusterError(
                        address, f"chunk {k} was lost {attempts[k]} times on {address!r}"
                    ) from None
                submit(pending[k])
                continue
            except Exception as e:
                if type(e).__name__ != "KilledWorker":
                    raise
                raise ClusterError(
                    address, f"chunk {k} killed every worker that ran it on {address!r}: "
                    f"{_one_line(e)}",
                ) from None  # fmt: skip
            future.release()
            del pending[k]
            nxt = next(queue, None)
            if nxt is not None:
                submit(nxt)
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
    worker_timeout: float = WORKER_TIMEOUT,
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
        worker_timeout: how long the sweep waits while the cluster has no worker before
            it stops [s]; the chunks stored by then stay, and ``resume`` continues.

    Returns:
        A :class:`SweepResult` (counts, worst cases, ``.table()`` of every row).

    Raises:
        SpecError: a bad spec (unknown name, empty range, a range that makes a
            parameter invalid …).
        InputError: ``out`` is empty or not a path, holds another sweep or other
            files, is being written by another run, cannot be written, or (``resume``)
            holds another spec's sweep or a stray file in ``chunks/``; the scheduler
            is unreachable; or the extra ``sweep`` is not installed. A chunk that
            fails its check on ``resume`` is recomputed, with a warning.
        ClusterError: the scheduler cannot be reached, or gives no Dask handshake,
            within :data:`CONNECT_TIMEOUT` s; the cluster has had no worker for
            ``worker_timeout`` s; a chunk killed every worker that ran it.
        ArgumentTypeError: ``spec`` is not a Spec, a dict or a path.
    """
    from rrt_pin.sweeps.compute import block, plan
    from rrt_pin.sweeps.store import Store, folder_path

    out = folder_path(out)  # None, a list or "" refused before any work
    start_time = time.perf_counter()
    spec = _spec(spec)
    size = block(plan(spec))
    if size is not None and spec.chunk % size:
        from dataclasses import replace

        spec = replace(spec, chunk=size * math.ceil(spec.chunk / size))
    _check_extremes(spec)
    if workers is not None:  # numpy integers too; never a bool, a float or a string
        if isinstance(workers, (bool, np.bool_)) or not isinstance(workers, numbers.Integral):
            raise InputError(f"workers must be an integer >= 1, not {type(workers).__name__}")
        if int(workers) < 1:
            raise InputError(f"workers={int(workers)} must be an integer >= 1")
        workers = int(workers)
    if (isinstance(worker_timeout, bool) or not isinstance(worker_timeout, (int, float))
            or not 0 < worker_timeout < math.inf):  # fmt: skip
        raise InputError(f"worker_timeout={worker_timeout!r} must be a number > 0 [s]")

    n_workers = workers or cpus.available()
    p = plan(spec)
    robot = p.robot
    manifest = {
        "spec": spec.source,
        "spec_hash": spec.digest(),
        "backend": p.backend,  # a resumed sweep runs on the same one
        "backend_reason": p.reason,
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
            address = scheduler or cluster.scheduler_address
            stream = _on_dask(client, spec, jobs, n_workers, address, float(worker_timeout))
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
