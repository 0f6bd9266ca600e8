"""What a run crossed: its limit events, measured from the samples at the output times.

A pure function of arrays: :func:`limit_events` (one run) and :func:`batch_limit_events`
(B variants) compare the sampled states and the law's demanded efforts with a robot's
stated limits (:class:`~rrt_pin.robot.limits.Physical`), whether or not the run enforced
them. Between two samples nothing is seen: a crossing shorter than an output interval
may be missed, and times are those of the first sample past a limit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from rrt_pin.robot.limits import Physical
from rrt_pin.simulate.extremes import extremes
from rrt_pin.simulate.extremes import peak as extremes_peak

__all__ = [
    "KINDS",
    "LimitEvent",
    "batch_limit_events",
    "deepest",
    "limit_events",
    "measure",
    "quiet",
]

#: The kinds of limit events.
KINDS = ("position", "effort", "velocity")

_UNITS = {
    "position": {"rad": "rad", "m": "m"},
    "effort": {"rad": "N·m", "m": "N"},
    "velocity": {"rad": "rad/s", "m": "m/s"},
}


@dataclass(frozen=True)
class LimitEvent:
    """A joint coordinate past one of its limits at some output samples.

    Attributes:
        joint: the joint's name.
        kind: ``"position"``, ``"effort"`` or ``"velocity"``.
        first_time: the first output time past the limit [s].
        extent: position: the deepest penetration past the limit [rad or m]; effort:
            the peak demanded |effort| (the law's, before saturation) [N·m or N];
            velocity: the peak |q̇| [rad/s or m/s].
        count: separate crossings (runs of consecutive samples past the limit).
        saturated_time: effort: the time the law's demand exceeded the limit [s]
            (trapezoidal over the samples; the time spent saturated when enforced);
            else None.
        unit: the unit of ``extent``.
    """

    joint: str
    kind: str
    first_time: float
    extent: float
    count: int
    saturated_time: float | None = None
    unit: str = ""

    def as_dict(self) -> dict:
        """The event as JSON-ready data."""
        return {
            "joint": self.joint,
            "kind": self.kind,
            "first_time": self.first_time,
            "extent": self.extent,
            "unit": self.unit,
            "count": self.count,
            "saturated_time": self.saturated_time,
        }


def deepest(q: np.ndarray, p: Physical) -> np.ndarray:
    """The deepest penetration past the position limits per coordinate, 0 when none.

    ``q`` of shape (B, T, nv) [rad or m]; returns (B, nv).
    """
    with np.errstate(invalid="ignore"):
        depth = np.maximum(p.lower - q, q - p.upper)
    return np.maximum(np.nan_to_num(depth, nan=0.0, neginf=0.0).max(axis=1), 0.0)


def _no_mask(shape: tuple[int, ...]) -> np.ndarray:
    """An all-False mask of ``shape`` that allocates nothing (read-only)."""
    return np.broadcast_to(np.False_, shape)


def measure(
    t: np.ndarray, q: np.ndarray, qd: np.ndarray, demanded: np.ndarray | None, p: Physical
) -> dict[str, dict[str, np.ndarray]]:
    """Per kind, the arrays of every event: mask (B, T, nv) past the limit, extent (B, nv).

    Also ``crossed`` (B, nv): the coordinates with some sample past the limit.
    ``demanded``: the law's efforts before saturation (None: no effort events).

    Extremes first: each kind's extent comes from the samples' min and max, and its mask
    is made only when some coordinate goes past (else an all-False view): the same
    values as sample by sample (rounding is monotonic), NaN samples included.
    """
    out: dict[str, dict[str, np.ndarray]] = {}
    with np.errstate(invalid="ignore"):
        lo, hi = extremes(q)
        depth = np.maximum(p.lower - lo, hi - p.upper)
        if np.isnan(depth).any():  # NaN samples: the maximum over the others
            past = (q < p.lower) | (q > p.upper)
            depth, crossed = deepest(q, p), past.any(axis=1)
        else:
            depth = np.maximum(np.nan_to_num(depth, neginf=0.0), 0.0)
            crossed = depth > 0.0
            past = (q < p.lower) | (q > p.upper) if crossed.any() else _no_mask(q.shape)
    out["position"] = {"mask": past, "extent": depth, "crossed": crossed}
    if demanded is not None:
        peak = extremes_peak(demanded)
        if (~(peak <= p.effort)).any():  # some demand past its limit, or NaN samples
            over = np.abs(demanded) > p.effort
            s = over.astype(float)
            dt = np.diff(t)
            time = (0.5 * (s[:, 1:] + s[:, :-1]) * dt[None, :, None]).sum(axis=1)
            hit = over.any(axis=1)
        else:
            over, time = _no_mask(demanded.shape), np.zeros(peak.shape)
            hit = np.zeros(peak.shape, dtype=bool)
        out["effort"] = {"mask": over, "extent": peak, "time": time, "crossed": hit}
    speed = extremes_peak(qd)
    with np.errstate(invalid="ignore"):
        if (~(speed <= p.velocity)).any():
            fast = np.abs(qd) > p.velocity
            hit = fast.any(axis=1)
        else:
            fast, hit = _no_mask(qd.shape), np.zeros(speed.shape, dtype=bool)
    out["velocity"] = {"mask": fast, "extent": speed, "crossed": hit}
    return out


def _events(
    t: np.ndarray,
    measured: dict[str, dict[str, np.ndarray]],
    b: int,
    joints: Sequence[str],
    units: Sequence[str],
) -> tuple[LimitEvent, ...]:
    events = []
    for kind in KINDS:
        m = measured.get(kind)
        if m is None:
            continue
        mask = m["mask"][b]
        for k in np.flatnonzero(m["crossed"][b]):
            column = mask[:, k]
            first = int(np.argmax(column))
            starts = int(column[0]) + int(np.count_nonzero(column[1:] & ~column[:-1]))
            events.append(
                LimitEvent(
                    joint=joints[k],
                    kind=kind,
                    first_time=float(t[first]),
                    extent=float(m["extent"][b, k]),
                    count=starts,
                    saturated_time=float(m["time"][b, k]) if kind == "effort" else None,
                    unit=_UNITS[kind].get(units[k], ""),
                )
            )
    events.sort(key=lambda e: (e.first_time, KINDS.index(e.kind)))
    return tuple(events)


def quiet(q: np.ndarray, qd: np.ndarray, demanded: np.ndarray | None, p: Physical) -> bool:
    """Whether one run (shapes (T, nv)) has no sample past a limit and no NaN sample.

    One pass: the samples of q, q̇ and the demand copied side by side, one row a
    coordinate, then each row's min and max; the same comparisons as :func:`measure`
    (a sample is past a limit where :func:`measure` says so, and NaN is never quiet).
    """
    arrays = (q, qd) if demanded is None else (q, qd, demanded)
    if q.shape[0] == 0:
        return False  # measure's answer (an error: no samples)
    n = q.shape[1]
    rows = np.empty((n * len(arrays), q.shape[0]))
    for i, a in enumerate(arrays):
        rows[i * n : (i + 1) * n] = a.T
    lo, hi = rows.min(axis=1), rows.max(axis=1)
    if np.isnan(lo).any() or np.isnan(hi).any():
        return False
    peak = np.maximum(-lo[n:], hi[n:])  # |q̇|, then |demand|
    limits = np.concatenate([p.velocity, p.effort]) if demanded is not None else p.velocity
    return bool((lo[:n] >= p.lower).all() and (hi[:n] <= p.upper).all() and (peak <= limits).all())


def limit_events(
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    demanded: np.ndarray | None,
    p: Physical,
    joints: Sequence[str],
    units: Sequence[str],
) -> tuple[LimitEvent, ...]:
    """The limit events of one run sampled at ``t`` (shapes (T, nv)), by first time.

    A run that stays within every limit (:func:`quiet`, the common case) has none, found
    in one pass over its samples; else :func:`measure` finds them.

    Args:
        t: output times (T,) [s].
        q: coordinates [rad or m].
        qd: velocities [rad/s or m/s].
        demanded: the law's efforts before saturation [N·m or N] (None: no effort events).
        p: the limits (the robot's stated ones).
        joints: each coordinate's joint name (nv,).
        units: each coordinate's unit, ``rad`` or ``m`` (nv,).
    """
    if quiet(q, qd, demanded, p):
        return ()
    d = None if demanded is None else demanded[None]
    return _events(t, measure(t, q[None], qd[None], d, p), 0, joints, units)


def batch_limit_events(
    t: np.ndarray,
    q: np.ndarray,
    qd: np.ndarray,
    demanded: np.ndarray | None,
    p: Physical,
    joints: Sequence[str],
    units: Sequence[str],
) -> list[tuple[LimitEvent, ...]]:
    """Each variant's limit events (shapes (B, T, nv)); as :func:`limit_events`."""
    measured = measure(t, q, qd, demanded, p)
    return [_events(t, measured, b, joints, units) for b in range(q.shape[0])]
