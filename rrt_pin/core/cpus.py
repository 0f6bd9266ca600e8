"""How many CPUs a run may use, and how many of them other jobs hold right now.

Machines are shared: a statically split parallel call (OpenMP's default
schedule, one chunk a thread) waits for its slowest thread, and a thread on a
core another process is using gets half of it. So the default thread count of
every parallel path is :func:`free`: the CPUs this process may run on, less
those other processes are running on at the call. An explicit thread count is
kept, up to :func:`max_threads` (256, or 4 a CPU on larger machines): every thread
reserves a stack (8 MiB) and may copy the model's data, so a count far beyond the
CPUs only costs memory (``threads=10**6`` once took 23 GB).
"""

from __future__ import annotations

import os
import time

from rrt_pin.core import validate
from rrt_pin.core.errors import InputError

__all__ = [
    "MAX_THREADS",
    "available",
    "busy",
    "check_threads",
    "free",
    "max_threads",
    "threads_for",
]


def available() -> int:
    """The CPUs this process may run on (at least 1), capped by ``OMP_NUM_THREADS`` if set."""
    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        cpus = os.cpu_count() or 1
    try:
        cap = int(os.environ.get("OMP_NUM_THREADS", "").split(",")[0])
    except ValueError:
        cap = cpus
    return max(1, min(cpus, cap if cap > 0 else cpus))


#: The most threads one call may start, on machines of up to 64 CPUs (see :func:`max_threads`).
MAX_THREADS = 256


def max_threads() -> int:
    """The most threads one call may start: :data:`MAX_THREADS`, or 4 per CPU if more."""
    return max(MAX_THREADS, 4 * (os.cpu_count() or 1))


def check_threads(name: str, value: object) -> int:
    """``value`` as a thread count: an integer from 1 to :func:`max_threads`.

    Args:
        name: the argument, for the message (``"threads"``, ``"num_threads"``).
        value: what was given.

    Raises:
        InputError: not an integer, below 1, or more than :func:`max_threads`.
    """
    count = validate.positive_int(name, value)
    most = max_threads()
    if count > most:
        raise InputError(
            f"{name}={count}: at most {most} threads (each reserves a stack and may copy "
            f"the model's data; this machine has {os.cpu_count() or 1} CPUs)"
        )
    return count


def busy() -> int:
    """Tasks of other processes running right now (Linux's /proc), 0 when unknown.

    ``/proc/loadavg`` counts every running task; this process's own (this thread,
    OpenMP workers still spinning after a parallel call) are taken off.
    """
    try:
        with open("/proc/loadavg", encoding="ascii") as fh:
            running = int(fh.read().split()[3].split("/")[0])
        if running <= 1:  # this thread alone (the common case: no need to look further)
            return 0
        own = 0
        for task in os.listdir("/proc/self/task"):
            with open(f"/proc/self/task/{task}/stat", encoding="ascii", errors="replace") as fh:
                own += fh.read().rsplit(")", 1)[1].split()[0] == "R"
    except (OSError, ValueError, IndexError):
        return 0
    return max(0, running - max(own, 1))


#: Seconds a reading of :func:`free` is reused: back-to-back parallel calls do not each
#: read /proc, and a job starting beside them is seen within this time [s].
FRESH = 0.02
_last = (-1.0, 0)


def free() -> int:
    """The CPUs available to this process that no other process is running on now (≥ 1).

    A busy reading is confirmed by a second one (an OpenMP worker of this process
    that stops spinning between the two files read looks like another job once in
    ~40 readings); a reading is reused for :data:`FRESH` seconds.
    """
    global _last
    cpus = available()
    if cpus == 1:
        return 1
    now = time.monotonic()
    if 0.0 <= now - _last[0] < FRESH:
        return _last[1]
    others = busy()
    if others:
        others = min(others, busy())
    _last = (now, max(1, cpus - others))
    return _last[1]


def threads_for(items: int, min_per_thread: int, shared: bool = False) -> int:
    """The default thread count for ``items`` units of work (at least 1).

    The free CPUs, but no thread with fewer than ``min_per_thread`` items. ``shared``:
    the threads take the items from one counter as they finish (no static split), so a
    thread on a core another process holds never holds the others up and still adds
    its share: every CPU this process may use (:func:`available`), busy or not — measured
    (``scripts/bench/batch_threads.py --busy``), a second thread beside a busy core pays.
    """
    most = max(1, items // max(1, min_per_thread))
    if most == 1:
        return 1
    return max(1, min(most, available() if shared else free()))
