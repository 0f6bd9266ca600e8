"""Keyframes of an animation as plain data: times, configurations, link placements.

Pure functions of their inputs (numpy and Pinocchio only, no meshcat): the
browser transport in :mod:`rrt_pin.viewer.server` only sends what these build.
Times in seconds [s], lengths in metres [m], transforms as 4×4 homogeneous
matrices in the world frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core import text
from rrt_pin.core.errors import InputError
from rrt_pin.core.text import argument

if TYPE_CHECKING:
    import pinocchio as pin

#: Most keyframes an animation may have (the browser holds them all).
MAX_KEYFRAMES = 100_000

__all__ = [
    "MAX_KEYFRAMES",
    "Keyframes",
    "frame_placements",
    "keyframe_times",
    "keyframes",
    "resample",
]


@dataclass(frozen=True)
class Keyframes:
    """Link placements sampled at the animation's frame rate.

    Attributes:
        t: animation times [s], shape (N,), starting at 0 and ``1/fps`` apart
            (the last interval may be shorter so that the end time is kept).
        q: configurations at those times, shape (N, nq) (Pinocchio's q).
        frames: names of the animated link frames.
        transforms: world placement of each frame at each time, shape
            (N, len(frames), 4, 4) [m].
        fps: frame rate [1/s].
    """

    t: np.ndarray
    q: np.ndarray
    frames: tuple[str, ...]
    transforms: np.ndarray
    fps: float

    @property
    def duration(self) -> float:
        """Length of the animation [s]."""
        return float(self.t[-1])


def _count(n: float) -> str:
    """A count as a person reads it: "1,501", or "3e+301" when it is astronomical."""
    return f"{math.ceil(n):,}" if n < 1e15 else f"{n:.3g}"


def _check_fps(fps: float) -> float:
    if isinstance(fps, bool) or not isinstance(fps, (int, float)) or not math.isfinite(fps):
        raise InputError(f"fps={fps!r} must be a finite number [1/s]")
    if fps <= 0.0:
        raise InputError(f"fps={fps!r} must be > 0 [1/s]")
    return float(fps)


def keyframe_times(duration: float, fps: float) -> np.ndarray:
    """Animation times 0, 1/fps, 2/fps, …, duration [s], both ends included.

    15 s at 30 fps gives 451 times. When ``duration·fps`` is not a whole
    number the last interval is shorter; a zero duration gives the single
    time 0.

    Raises:
        InputError: ``duration`` is negative or not finite, ``fps`` is not
            a finite positive number, or there would be more than
            MAX_KEYFRAMES keyframes.
    """
    fps = _check_fps(fps)
    if not isinstance(duration, (int, float)) or not math.isfinite(duration) or duration < 0.0:
        raise InputError(f"duration={duration!r} must be a finite number >= 0 [s]")
    steps = duration * fps
    if steps + 1 > MAX_KEYFRAMES:
        raise InputError(
            f"{duration:g} s at fps={fps:g} would be {_count(steps + 1)} keyframes; "
            f"at most {MAX_KEYFRAMES:,}: lower {argument('fps')} or shorten the motion"
        )
    n = round(steps)
    if abs(steps - n) <= 1e-9 * max(1.0, steps):
        # A whole number of frames: k/fps exactly, the last one snapped to duration.
        t = np.arange(n + 1, dtype=float) / fps
        t[-1] = duration
        return t
    t = np.arange(math.ceil(steps) + 1, dtype=float) / fps
    t[-1] = duration
    return t


def resample(t: np.ndarray, q: np.ndarray, fps: float) -> tuple[np.ndarray, np.ndarray]:
    """Resample a sampled trajectory to ``fps`` by linear interpolation.

    Args:
        t: sample times [s], shape (M,), strictly increasing, finite.
        q: samples, shape (M, n) (one column per coordinate, SI units).
        fps: frame rate of the result [1/s].

    Returns:
        ``(times, values)``: the absolute times ``t[0] + keyframe_times(...)``
        [s], shape (N,), and the interpolated samples, shape (N, n). A sample
        time that is also a keyframe time is reproduced exactly.

    Raises:
        InputError: shapes disagree, a value is not finite, or ``t`` is not
            strictly increasing.
    """
    t = np.asarray(t, dtype=float)
    q = np.asarray(q, dtype=float)
    if t.ndim != 1 or t.size == 0:
        raise InputError(f"{t.shape=} must be a non-empty 1-D array of times [s]")
    if q.ndim != 2 or q.shape[0] != t.size:
        raise InputError(f"{q.shape=} must be (len(t), n) with {t.size=}")
    if not np.isfinite(t).all():
        i = int(np.argmax(~np.isfinite(t)))
        raise InputError(f"t[{i}]={float(t[i])} is not finite [s]")
    if not np.isfinite(q).all():
        r, c = (int(i) for i in np.argwhere(~np.isfinite(q))[0])
        raise InputError(f"q[{r}, {c}]={float(q[r, c])} is not finite (at t[{r}]={t[r]:.6g} s)")
    steps = np.diff(t)
    if (steps <= 0.0).any():
        k = int(np.argmax(steps <= 0.0))
        later, earlier = _distinct(float(t[k + 1]), float(t[k]))
        raise InputError(
            f"t must increase strictly, but t[{k + 1}]={later} s follows t[{k}]={earlier} s"
        )
    times = t[0] + keyframe_times(float(t[-1] - t[0]), fps)
    times[-1] = t[-1]
    values = np.column_stack([np.interp(times, t, q[:, j]) for j in range(q.shape[1])])
    return times, values.reshape(times.size, q.shape[1])


def _distinct(a: float, b: float) -> tuple[str, str]:
    """``a`` and ``b`` with 6 significant digits, or as many more as tell them apart."""
    for digits in (6, 9, 12, 17):
        shown = f"{a:.{digits}g}", f"{b:.{digits}g}"
        if shown[0] != shown[1] or a == b:
            return shown
    return shown


def frame_placements(model: pin.Model, q: np.ndarray, frame_ids: list[int]) -> np.ndarray:
    """World placements of the given frames for each configuration.

    Args:
        model: the Pinocchio model.
        q: configurations, shape (N, nq).
        frame_ids: indices into ``model.frames``.

    Returns:
        Array (N, len(frame_ids), 4, 4) of homogeneous transforms [m], from
        ``pin.forwardKinematics`` and ``pin.updateFramePlacements``.
    """
    import pinocchio as pin

    q = np.asarray(q, dtype=float)
    if q.ndim != 2 or q.shape[1] != model.nq:
        raise InputError(f"{q.shape=} must be (N, {model.nq=})")
    data = model.createData()
    out = np.empty((q.shape[0], len(frame_ids), 4, 4))
    for k, qk in enumerate(q):
        pin.forwardKinematics(model, data, qk)
        pin.updateFramePlacements(model, data)
        for i, f in enumerate(frame_ids):
            out[k, i] = data.oMf[f].homogeneous
    return out


def keyframes(
    model: pin.Model, t: np.ndarray, q: np.ndarray, frames: tuple[str, ...], fps: float
) -> Keyframes:
    """The keyframes of configurations already sampled at the frame rate.

    Args:
        model: the Pinocchio model.
        t: times [s], shape (N,), spaced ``1/fps`` (see :func:`keyframe_times`);
            shifted so that the animation starts at 0.
        q: configurations, shape (N, nq).
        frames: names of the frames to animate (each a frame of ``model``).
        fps: the frame rate the times were sampled at [1/s].

    Raises:
        InputError: a frame name is unknown or the times are unusable.
    """
    t = np.asarray(t, dtype=float)
    if t.ndim != 1 or t.size == 0 or not np.isfinite(t).all():
        raise InputError(f"{t.shape=}: times must be a non-empty finite 1-D array [s]")
    names = [f.name for f in model.frames]
    missing = [f for f in frames if f not in names]
    if missing:
        raise InputError(f"no frame {missing[0]!r} in the model; frames: {text.names(names)}")
    ids = [model.getFrameId(f) for f in frames]
    fps = _check_fps(fps)
    q = np.array(q, dtype=float)
    t = t - t[0]
    transforms = frame_placements(model, q, ids)
    for arr in (t, q, transforms):
        arr.flags.writeable = False
    return Keyframes(t=t, q=q, frames=tuple(frames), transforms=transforms, fps=fps)
