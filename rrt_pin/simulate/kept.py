"""What a batch keeps of each variant: every output time, the last one, or metrics.

The Pinocchio backend computes whole trajectories; :func:`reduced` then keeps what
``keep`` asks for, measuring the metrics and the limit events from every sample first.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.simulate.metrics import GROUPS, batch_metrics
from rrt_pin.simulate.physical_runs import demanded

if TYPE_CHECKING:
    from rrt_pin.simulate.physical_runs import RunPhysics
    from rrt_pin.simulate.results import BatchResult

__all__ = ["reduced", "targets"]


def targets(laws: Sequence[Any]) -> np.ndarray:
    """Each law's target qf (B, nv), for ``keep="metrics"``."""
    found = [getattr(law, "qf", None) for law in laws]
    if any(qf is None for qf in found):
        raise InputError(
            "keep='metrics' measures each variant against its controller's target qf: "
            "every controller needs one (or keep='final')"
        )
    return np.array(found, dtype=float)


def reduced(
    full: BatchResult,
    keep: str,
    qf: np.ndarray | None,
    efforts: bool,
    limits: Callable[[BatchResult], Any] | None = None,
    physics: RunPhysics | None = None,
    laws: Sequence[Any] = (),
) -> BatchResult:
    """A batch with every output time reduced to what ``keep`` asks for.

    ``limits(full)``: the variants' limit events, measured before the samples go.
    ``physics``, ``laws``: the run's physical model and laws, for the ``limits`` metrics
    (the stated limits, the laws' demands); None: no limit stated.
    """
    events = limits(full) if limits is not None else full.limits
    if keep == "trajectories":
        if limits is None and (efforts or full.tau is None):
            return full
        return replace(full, limits=events, tau=full.tau if efforts else None)
    metrics = None
    if keep == "metrics":
        stated = demand = None
        if physics is not None:
            stated = physics.stated
            if full.tau is not None:
                applied = physics.applied
                demand = demanded(full.t, full.q, full.qd, full.tau, laws, applied)
        with np.errstate(invalid="ignore"):
            metrics = batch_metrics(
                GROUPS, full.t, full.q, full.qd, full.tau, qf, full.q_names, full.tau_names,
                stated=stated, demanded=demand,
            )  # fmt: skip
    return replace(
        full,
        t=full.t[-1:],
        q=full.q[:, -1:],
        qd=full.qd[:, -1:],
        tau=full.tau[:, -1:] if efforts and full.tau is not None else None,
        keep=keep,
        metrics=metrics,
        limits=events,
    )
