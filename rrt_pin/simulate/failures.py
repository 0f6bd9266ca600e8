"""Batches that record their variants' failures instead of raising the first.

``simulate_batch(..., failures="record")``: a sweep of a million variants wants each
variant's outcome, not the first failure. The compiled backend's generated integrators
record them as they run; elsewhere a batch that fails is run again one variant at a
time (:func:`one_at_a_time`), and each failure kept beside the others' results.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

import numpy as np

from rrt_pin.core.errors import DivergenceError

__all__ = ["FAILURES", "one_at_a_time"]

#: What ``simulate_batch`` does when a variant fails: raise it, or record it and go on.
FAILURES = ("raise", "record")


def one_at_a_time(run: Callable[[int], Any], count: int, rows: int, nv: int) -> Any:
    """The batch of ``count`` variants from ``run(i)``, the batch of variant i alone.

    A variant whose run raises :class:`~rrt_pin.core.errors.DivergenceError` gets NaN
    states, efforts and metrics, and its error in ``result.failures``.

    Args:
        run: variant index -> its :class:`~rrt_pin.simulate.results.BatchResult` of one.
        count: the variants.
        rows: output times kept a variant (T, or 1 for ``keep="final"``/``"metrics"``).
        nv: joint coordinates.
    """
    parts: list[Any] = []
    failed: list[DivergenceError | None] = []
    for i in range(count):
        try:
            parts.append(run(i))
            failed.append(None)
        except DivergenceError as e:
            parts.append(None)
            failed.append(e)
    done = [p for p in parts if p is not None]
    if not done:
        raise failed[0]  # type: ignore[misc]  (no variant to take the result's form from)
    first = done[0]

    def stack(name: str) -> np.ndarray | None:
        if getattr(first, name) is None:
            return None
        out = np.full((count, rows, nv), np.nan)
        for i, p in enumerate(parts):
            if p is not None:
                out[i] = getattr(p, name)[0]
        return out

    metrics = None
    if first.metrics is not None:
        metrics = {name: np.full(count, np.nan) for name in first.metrics}
        for i, p in enumerate(parts):
            if p is not None:
                for name, column in p.metrics.items():
                    metrics[name][i] = column[0]
    return dataclasses.replace(
        first,
        q=stack("q"),
        qd=stack("qd"),
        tau=stack("tau"),
        n_evals=sum(p.n_evals for p in done),
        wall_time=sum(p.wall_time for p in done),
        metrics=metrics,
        failures=tuple(failed),
    )
