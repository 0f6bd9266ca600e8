"""Numbers that summarise a run: settling times, distance to the target, peaks, limits.

Pure functions of arrays (SI units), shared by the CLI's summaries and the library.
The ``limits`` group measures a run against its robot's stated limits as
:mod:`rrt_pin.simulate.crossings` measures a single run's limit events (the same
function), so that a batch's row and a run's ``result.limits`` agree.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from rrt_pin.core import backends
from rrt_pin.robot.limits import Physical
from rrt_pin.simulate import codes
from rrt_pin.simulate.crossings import measure

__all__ = [
    "GROUPS",
    "METRICS",
    "SETTLING_BAND",
    "TEXT_COLUMNS",
    "Column",
    "Metric",
    "batch_metrics",
    "column_names",
    "column_units",
    "for_task",
    "limit_columns",
    "metric_columns",
    "settling_times",
]


@dataclass(frozen=True)
class Column:
    """One kind of column a metric writes.

    Attributes:
        prefix: the column's name, or its prefix before ``_<coordinate or effort>``.
        per: ``"coordinate"`` (one column per joint coordinate), ``"effort"`` (per
            effort) or ``"run"`` (one column).
        unit: its unit; None: the unit of its coordinate or effort (rad or m, N·m or N).
        offset: the name of its first value's offset in a compiled metrics row
            (:mod:`rrt_pin.simulate.codes`), None when the compiled pass does not make it.
        text: a column of text (nothing to plot).
    """

    prefix: str
    per: str
    unit: str | None
    offset: str | None = None
    text: bool = False

    def names(self, q_names: Iterable[str], effort_names: Iterable[str]) -> list[str]:
        """The column names for a robot's coordinates and efforts."""
        if self.per == "coordinate":
            return [f"{self.prefix}_{n}" for n in q_names]
        if self.per == "effort":
            return [f"{self.prefix}_{n}" for n in effort_names]
        return [self.prefix]


@dataclass(frozen=True)
class Metric:
    """A number (or a group of numbers) that summarises a run: one registry line each.

    Attributes:
        name: the name users keep (``[keep] metrics = [...]``).
        summary: what it is, with units, for help texts.
        tasks: the sweep tasks that have it (``"simulate"``, ``"inverse"``).
        columns: the columns it writes.
        from_samples: :func:`batch_metrics` computes it from sampled runs (the others
            come from the integrator: evaluations, failures).
    """

    name: str
    summary: str
    tasks: tuple[str, ...]
    columns: tuple[Column, ...]
    from_samples: bool = True


_BOTH = ("simulate", "inverse")
#: Every metric, by name: the sweep spec's choices, the columns, their units and the
#: sweep's help all derive from here.
METRICS: dict[str, Metric] = {
    m.name: m
    for m in (
        Metric("final_error", "|q(tf) − qf| per joint [rad or m]", ("simulate",),
               (Column("final_error", "coordinate", None, "METRIC_FINAL"),)),
        Metric("settling_time", "2 % settling time per joint [s] (NaN: not settled)",
               ("simulate",), (Column("settling_time", "coordinate", "s", "METRIC_SETTLE"),)),
        Metric("peak_effort", "peak |effort| per joint [N·m or N] and when [s]", _BOTH,
               (Column("peak_effort", "effort", None, "METRIC_PEAK"),
                Column("peak_effort_time", "effort", "s", "METRIC_PEAK_TIME"))),
        Metric("excursion", "max |q(t) − q(0)| per joint [rad or m]", ("simulate",),
               (Column("excursion", "coordinate", None, "METRIC_EXCURSION"),)),
        Metric("control_energy", "∫ Σ|τ·q̇| dt [J]", _BOTH,
               (Column("control_energy", "run", "J", "METRIC_ENERGY"),)),
        Metric("limits", "the largest distance past the URDF's position limits per joint "
               "[rad or m], the time the law's demand exceeded its effort limit [s] (0: "
               "inside, or no limit stated) and the peak demanded effort [N·m or N]", _BOTH,
               (Column("limit_violation", "coordinate", None, "METRIC_LIMIT"),
                Column("saturation_time", "effort", "s", "METRIC_SATURATION"),
                Column("peak_demand", "effort", None, "METRIC_DEMAND"))),
        Metric("evaluations", "dynamics evaluations", ("simulate",),
               (Column("evaluations", "run", ""),), from_samples=False),
        Metric("diverged", "whether the variant failed, when [s], in which coordinate, and "
               "why (a diverged run, invalid parameters, efforts that overflow)", _BOTH,
               (Column("diverged", "run", ""), Column("diverged_time", "run", "s"),
                Column("diverged_coordinate", "run", "", text=True),
                Column("diverged_reason", "run", "", text=True)), from_samples=False),
    )
}  # fmt: skip

#: The metric groups :func:`batch_metrics` computes.
GROUPS = tuple(name for name, m in METRICS.items() if m.from_samples)
#: Metric columns of text (not numbers: nothing to plot).
TEXT_COLUMNS = tuple(c.prefix for m in METRICS.values() for c in m.columns if c.text)


def for_task(task: str) -> dict[str, str]:
    """The metrics of a sweep task, name -> summary, in registry order."""
    return {name: m.summary for name, m in METRICS.items() if task in m.tasks}


def column_names(
    groups: Iterable[str], q_names: Iterable[str], effort_names: Iterable[str]
) -> list[str]:
    """The columns the metric ``groups`` write for a robot, in registry order per group."""
    q_names, effort_names = tuple(q_names), tuple(effort_names)
    return [
        name
        for group in groups
        for column in METRICS[group].columns
        for name in column.names(q_names, effort_names)
    ]


def column_units(
    groups: Iterable[str],
    q_names: Iterable[str],
    effort_names: Iterable[str],
    units: Mapping[str, str],
) -> dict[str, str]:
    """The unit of each column of the metric ``groups``; ``units``: the robot's, by name."""
    out: dict[str, str] = {}
    q_names, effort_names = tuple(q_names), tuple(effort_names)
    for group in groups:
        for column in METRICS[group].columns:
            owners = {"coordinate": q_names, "effort": effort_names}.get(column.per, ("",))
            for owner, name in zip(owners, column.names(q_names, effort_names), strict=True):
                out[name] = column.unit if column.unit is not None else units[owner]
    return out


#: The share of the initial distance to qf inside which a joint counts as settled.
SETTLING_BAND = 0.02


def settling_times(
    t: np.ndarray, q: np.ndarray, q0: Any, qf: Any, band: float = SETTLING_BAND
) -> list[float | None]:
    """Per joint, the first sample time [s] after which |q − qf| stays within ``band``·|q0 − qf|.

    A joint that starts at its target uses ``band`` times its largest excursion.
    None: still outside the band at the last sample.
    """
    dist = np.abs(np.asarray(q) - np.asarray(qf))
    out: list[float | None] = []
    for k in range(dist.shape[1]):
        scale = abs(float(q0[k]) - float(qf[k])) or float(dist[:, k].max())
        outside = np.flatnonzero(dist[:, k] > band * scale)
        if outside.size == 0:
            out.append(float(t[0]))
        elif outside[-1] == t.size - 1:
            out.append(None)
        else:
            out.append(float(t[outside[-1] + 1]))
    return out


def _last_true(mask: np.ndarray) -> np.ndarray:
    """Index of the last True along axis 1 of (B, T, n), or -1 where there is none."""
    T = mask.shape[1]
    rev = mask[:, ::-1]
    last = T - 1 - np.argmax(rev, axis=1)
    return np.where(rev.any(axis=1), last, -1)


def batch_metrics(
    groups: tuple[str, ...],
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    tau: np.ndarray | None,
    qf: np.ndarray | None,
    q_names: tuple[str, ...],
    effort_names: tuple[str, ...],
    band: float = SETTLING_BAND,
    compiled: bool = False,
    *,
    stated: Physical | None = None,
    demanded: np.ndarray | None = None,
) -> dict[str, np.ndarray]:
    """Per-variant metrics of B runs sampled at ``t`` (shapes (B, T, n)), as named columns.

    Groups (see :data:`METRICS`): ``final_error`` (|q(tf) − qf|),
    ``settling_time`` (as :func:`settling_times`; NaN when not settled), ``peak_effort``
    (peak |τ| and its time), ``excursion`` (max |q(t) − q(0)|), ``control_energy``
    (∫ Σ|τ·q̇| dt by the trapezoidal rule [J]), ``limits`` (:func:`limit_columns`).
    Units as the coordinates and efforts.
    ``compiled``: one pass in machine code (numba; the same numbers, a few times faster).
    ``stated``: the robot's stated limits, whether the runs enforced them or not
    (:func:`rrt_pin.robot.limits.physical_model` with every switch on; None: none stated,
    the ``limits`` columns are 0); ``demanded``: the laws' efforts before saturation
    (B, T, n) [N·m or N] (None: ``tau``, right when no effort was saturated).
    """
    if compiled and tau is not None and qf is not None and q.shape[2] == 3:
        out = _compiled_metrics(groups, t, q, qd, tau, qf, q_names, effort_names, band)
        if "limits" in groups and stated is not None:  # the kernel's row: no limit stated
            efforts = tau if demanded is None else demanded
            out.update(limit_columns(t, q, qd, efforts, stated, q_names, effort_names))
        return out
    out: dict[str, np.ndarray] = {}
    n = q.shape[2]
    if "final_error" in groups:
        err = np.abs(q[:, -1, :] - qf)
        for k in range(n):
            out[f"final_error_{q_names[k]}"] = err[:, k]
    if "settling_time" in groups:
        dist = np.abs(q - qf[:, None, :])
        scale = np.abs(q[:, 0, :] - qf)
        scale = np.where(scale > 0, scale, dist.max(axis=1))
        last = _last_true(dist > band * scale[:, None, :])
        T = t.size
        when = np.where(last == T - 1, np.nan, t[np.clip(last + 1, 0, T - 1)])
        when = np.where(last == -1, t[0], when)
        for k in range(n):
            out[f"settling_time_{q_names[k]}"] = when[:, k]
    if "peak_effort" in groups and tau is not None:
        mag = np.abs(tau)
        i = np.argmax(mag, axis=1)
        peak = np.take_along_axis(mag, i[:, None, :], axis=1)[:, 0, :]
        for k in range(n):
            out[f"peak_effort_{effort_names[k]}"] = peak[:, k]
            out[f"peak_effort_time_{effort_names[k]}"] = t[i[:, k]]
    if "excursion" in groups:
        exc = np.abs(q - q[:, :1, :]).max(axis=1)
        for k in range(n):
            out[f"excursion_{q_names[k]}"] = exc[:, k]
    if "control_energy" in groups and tau is not None:
        power = np.abs(tau * qd).sum(axis=2)
        out["control_energy"] = (0.5 * (power[:, 1:] + power[:, :-1]) * np.diff(t)).sum(axis=1)
    if "limits" in groups:
        efforts = tau if demanded is None else demanded
        out.update(limit_columns(t, q, qd, efforts, stated, q_names, effort_names))
    return out


def limit_columns(
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    demanded: np.ndarray | None,
    stated: Physical | None,
    q_names: tuple[str, ...],
    effort_names: tuple[str, ...],
) -> dict[str, np.ndarray]:
    """The ``limits`` group of B runs sampled at ``t`` (shapes (B, T, n)), as named columns.

    ``limit_violation_<q>`` [rad or m]: the largest distance past the position limits
    over the samples (0 inside; continuous joints and limits not given: 0);
    ``saturation_time_<effort>`` [s]: the time the demanded |effort| exceeded the effort
    limit, trapezoidal over the samples; ``peak_demand_<effort>`` [N·m or N]: the largest
    demanded |effort| (the law's, before saturation). All as
    :func:`rrt_pin.simulate.crossings.measure` makes a position event's extent and an
    effort event's ``saturated_time`` and extent.

    Args:
        t: sample times (T,) [s].
        q: coordinates [rad or m].
        qd: velocities [rad/s or m/s].
        demanded: the laws' efforts before saturation [N·m or N] (None: no efforts, no
            ``saturation_time`` columns).
        stated: the limits measured against (None: none, every column 0).
        q_names: the coordinates' names.
        effort_names: the efforts' names.
    """
    B, n = q.shape[0], q.shape[2]
    out: dict[str, np.ndarray] = {}
    if stated is None:
        depth = np.zeros((B, n))
        time = None if demanded is None else np.zeros((B, n))
        peak = None if demanded is None else np.abs(demanded).max(axis=1)
    else:
        with np.errstate(invalid="ignore"):
            found = measure(t, q, qd, demanded, stated)
        depth = found["position"]["extent"]
        time = found["effort"]["time"] if demanded is not None else None
        peak = found["effort"]["extent"] if demanded is not None else None
    for k in range(n):
        out[f"limit_violation_{q_names[k]}"] = depth[:, k]
    if time is not None:
        for k in range(n):
            out[f"saturation_time_{effort_names[k]}"] = time[:, k]
            out[f"peak_demand_{effort_names[k]}"] = peak[:, k]
    return out


def _compiled_metrics(groups, t, q, qd, tau, qf, q_names, effort_names, band):  # noqa: ANN001, ANN202
    rows = backends.get("compiled").entry("metrics")(t, q, qd, tau, qf, band)
    return metric_columns(groups, rows, q_names, effort_names)


def metric_columns(
    groups: tuple[str, ...],
    rows: np.ndarray,
    q_names: tuple[str, ...],
    effort_names: tuple[str, ...],
    width: int = 3,
) -> dict[str, np.ndarray]:
    """The named columns of :func:`batch_metrics` from compiled metrics rows (B, METRIC_WIDTH).

    ``rows`` laid out as the ``METRIC_*`` offsets of :mod:`rrt_pin.simulate.codes` say
    (each :class:`Column`'s ``offset``, then one value per coordinate or effort), for
    the chapter's 3 coordinates; ``width``: the coordinates of another robot's rows,
    whose offsets are the same multiples of it (:func:`rrt_pin.simulate.codes.metric_start`).
    """
    out: dict[str, np.ndarray] = {}
    for group in groups:
        for column in METRICS[group].columns:
            if column.offset is None:
                continue
            start = codes.metric_start(getattr(codes, column.offset), width)
            for k, name in enumerate(column.names(q_names, effort_names)):
                out[name] = rows[:, start + k]
    return out
