"""Numbers that summarise a run: settling times, distance to the target, peaks.

Pure functions of arrays (SI units), shared by the CLI's summaries and the library.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["GROUPS", "SETTLING_BAND", "batch_metrics", "metric_columns", "settling_times"]

#: The metric groups :func:`batch_metrics` computes.
GROUPS = ("final_error", "settling_time", "peak_effort", "excursion", "control_energy")

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
) -> dict[str, np.ndarray]:
    """Per-variant metrics of B runs sampled at ``t`` (shapes (B, T, n)), as named columns.

    Groups (see :data:`rrt_pin.sweeps.spec.METRICS`): ``final_error`` (|q(tf) − qf|),
    ``settling_time`` (as :func:`settling_times`; NaN when not settled), ``peak_effort``
    (peak |τ| and its time), ``excursion`` (max |q(t) − q(0)|), ``control_energy``
    (∫ Σ|τ·q̇| dt by the trapezoidal rule [J]). Units as the coordinates and efforts.
    ``compiled``: one pass in machine code (numba; the same numbers, a few times faster).
    """
    if compiled and tau is not None and qf is not None and q.shape[2] == 3:
        return _compiled_metrics(groups, t, q, qd, tau, qf, q_names, effort_names, band)
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
    return out


def _compiled_metrics(groups, t, q, qd, tau, qf, q_names, effort_names, band):  # noqa: ANN001, ANN202
    from rrt_pin.compiled import _jit_metrics

    return metric_columns(groups, _jit_metrics.run(t, q, qd, tau, qf, band), q_names, effort_names)


def metric_columns(
    groups: tuple[str, ...],
    rows: np.ndarray,
    q_names: tuple[str, ...],
    effort_names: tuple[str, ...],
) -> dict[str, np.ndarray]:
    """The named columns of :func:`batch_metrics` from compiled metrics rows (B, METRIC_WIDTH).

    ``rows`` laid out as the ``METRIC_*`` offsets of :mod:`rrt_pin.compiled.codes` say.
    """
    from rrt_pin.compiled import codes

    out: dict[str, np.ndarray] = {}
    for group, starts, names, prefixes in (
        ("final_error", (codes.METRIC_FINAL,), q_names, ("final_error",)),
        ("settling_time", (codes.METRIC_SETTLE,), q_names, ("settling_time",)),
        ("peak_effort", (codes.METRIC_PEAK, codes.METRIC_PEAK_TIME), effort_names,
         ("peak_effort", "peak_effort_time")),
        ("excursion", (codes.METRIC_EXCURSION,), q_names, ("excursion",)),
    ):  # fmt: skip
        if group in groups:
            for k in range(3):
                for start, prefix in zip(starts, prefixes, strict=True):
                    out[f"{prefix}_{names[k]}"] = rows[:, start + k]
    if "control_energy" in groups:
        out["control_energy"] = rows[:, codes.METRIC_ENERGY]
    return out
