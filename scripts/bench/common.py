"""What the benchmarks share: timing sides in one interleaved run, and the verdict words.

Every benchmark here times both sides of a comparison in the same process, round by
round (:func:`interleaved`), and prints the ratio of their medians: the machine's
noise then hits both sides alike. Nothing here imports rrt_pin.
"""

from __future__ import annotations

import statistics
import time
from collections.abc import Callable


def interleaved(
    funcs: dict[str, Callable[[], object]],
    repeat: int,
    inner: int = 5,
    rounds: dict[str, list[float]] | None = None,
) -> dict[str, float]:
    """Median wall time [s] of each callable over ``repeat`` rounds of ``inner`` back-to-back calls.

    Rounds alternate the sides, so that machine noise hits them alike; within a
    round a side runs several times in a row and its first call is not counted,
    so that each is timed in its steady state, not just after another side has
    evicted its caches (which penalizes sub-millisecond sides the most).
    """
    times: dict[str, list[float]] = {k: [] for k in funcs}
    for _ in range(repeat):
        for name, f in funcs.items():
            for i in range(inner + 1):
                start = time.perf_counter()
                f()
                if i:
                    times[name].append(time.perf_counter() - start)
    if rounds is not None:  # every timed call, in order: with inner=1 one a round per side
        rounds.update(times)
    return {k: statistics.median(v) for k, v in times.items()}


def verdict(ok: bool) -> str:
    return "met" if ok else "MISSED"
