"""How much memory a run may still take, and what its per-thread copies need, before allocating.

A Pinocchio ``Data`` of an n-joint model holds four n×n×n tensors of second-order
derivatives: one copy of a 300-joint chain's takes 0.89 GB, of a 1,000-joint
chain's 32 GB, and ``pin.ModelPool`` makes one a thread (and one more while it is
built). :func:`data_bytes` estimates a copy from the model's size
(:data:`DATA_BYTES`, fitted to the resident memory of chains of 1 to 400 joints),
and :func:`threads_that_fit` caps a thread count to what the limits leave:

* the memory the machine has available (``MemAvailable`` of ``/proc/meminfo``);
* the room under this process's cgroup ``memory.max`` (v2) or ``memory.limit_in_bytes`` (v1);
* the address space left under ``RLIMIT_AS`` (``ulimit -v``, ``prlimit --as``), which
  also counts each thread's reserved stack and malloc arena, touched or not.

When not even one thread's copy fits, :class:`~rrt_pin.core.errors.MemoryLimitError`
names the need and the limit. Only part of each limit is planned for (less
:data:`HEADROOM`): the rest is left for what the estimate does not count (Python
objects, outputs, BLAS buffers).
"""

from __future__ import annotations

import logging
import os
import resource
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rrt_pin.core.errors import MemoryLimitError

__all__ = [
    "DATA_BYTES",
    "HEADROOM",
    "RESERVE",
    "Cost",
    "Limit",
    "arenas",
    "check_data",
    "data_bytes",
    "describe",
    "limits",
    "thread_cost",
    "threads_that_fit",
]

#: Bytes of one Pinocchio ``Data`` (and its share of a ``ModelPool``) for nv degrees of
#: freedom: coefficients of nv³, nv², nv, 1. Fitted to chains of 1 to 400 revolute joints
#: (Pinocchio 4.1, resident memory of 2,000 to 1 copies each); the fit is 0 to 27 % above
#: every measurement. The nv³ term is the four nv×nv×nv tensors of second-order derivatives.
DATA_BYTES = (32, 300, 12_000, 24_000)
#: Resident memory of a thread (its stack's touched pages, thread-local state) [bytes],
#: measured ~65 kB a thread for OpenMP's and for the compiled batches' threads.
THREAD_RESIDENT = 128 << 10
#: A thread's malloc arena, reserved (not touched) by glibc for each of the first
#: 8 × CPUs threads that allocate [bytes].
ARENA = 64 << 20
#: What a run leaves free of each limit: this share of it, and at least :data:`RESERVE`
#: or half of it, whichever is less.
HEADROOM = 0.1
#: What a run leaves free of a limit of more than twice this [bytes] (numpy's BLAS
#: alone reserves tens of MB a thread when it first multiplies matrices).
RESERVE = 256 << 20
#: A need no limit is checked for [bytes]: a Python process with numpy and Pinocchio
#: loaded already holds more, so reading /proc and the cgroup for it would
#: cost more than the run of a small model.
SMALL = 64 << 20
_logger = logging.getLogger("rrt_pin")


@dataclass(frozen=True)
class Cost:
    """Memory a part of a run needs [bytes].

    Attributes:
        resident: memory it touches (counted against every limit).
        reserved: address space it only reserves (thread stacks, malloc arenas;
            counted against ``RLIMIT_AS`` only).
    """

    resident: int = 0
    reserved: int = 0

    def __add__(self, other: Cost) -> Cost:
        return Cost(self.resident + other.resident, self.reserved + other.reserved)

    def __mul__(self, k: int) -> Cost:
        return Cost(self.resident * k, self.reserved * k)


@dataclass(frozen=True)
class Limit:
    """A limit on the memory this process may still take.

    Attributes:
        room: bytes left under it.
        name: what it is, as a user would look it up (``MemAvailable``, ``ulimit -v``...).
        address_space: whether reserved address space counts too (``RLIMIT_AS``).
    """

    room: int
    name: str
    address_space: bool = False

    def usable(self) -> int:
        """The bytes a run plans for: :attr:`room` less its headroom (see :data:`HEADROOM`)."""
        return self.room - max(int(self.room * HEADROOM), min(RESERVE, self.room // 2))

    def takes(self, cost: Cost) -> int:
        """The bytes ``cost`` counts against this limit."""
        return cost.resident + (cost.reserved if self.address_space else 0)


def describe(n: float) -> str:
    """A byte count for a message: ``"32.3 GB"``, ``"512 MB"`` (3 significant digits)."""
    for unit, size in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{int(n)} B"


def data_bytes(model: Any) -> int:
    """Estimated bytes of one ``Data`` of a Pinocchio ``model`` (see :data:`DATA_BYTES`)."""
    nv = int(model.nv)
    linear = max(nv, int(model.njoints) - 1, int(model.nq))
    a, b, c, d = DATA_BYTES
    return a * nv**3 + b * nv**2 + c * linear + d


def thread_cost() -> Cost:
    """What one more thread takes: its touched pages and its reserved stack."""
    return Cost(THREAD_RESIDENT, _stack_bytes())


def arenas(threads: int) -> Cost:
    """The malloc arenas ``threads`` threads that allocate (numba's do) may reserve.

    glibc gives each of the first 8 × CPUs such threads an arena of :data:`ARENA`
    bytes of address space (touched only as used).
    """
    return Cost(0, ARENA * min(max(0, threads), 8 * (os.cpu_count() or 1)))


def _stack_bytes() -> int:
    """The stack a new thread reserves: ``OMP_STACKSIZE``, else ``RLIMIT_STACK`` (8 MiB)."""
    size = os.environ.get("OMP_STACKSIZE", "").strip().upper()
    if size:
        scale = {"B": 1, "K": 1 << 10, "M": 1 << 20, "G": 1 << 30}
        unit = size[-1] if size[-1] in scale else "K"
        try:
            return int(float(size.rstrip("BKMG")) * scale[unit])
        except ValueError:
            pass
    soft = resource.getrlimit(resource.RLIMIT_STACK)[0]
    if soft == resource.RLIM_INFINITY or soft <= 0:
        return 8 << 20
    return int(soft)


def _meminfo() -> dict[str, int]:
    """``/proc/meminfo`` [bytes], {} when unreadable."""
    out = {}
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                key, _, value = line.partition(":")
                parts = value.split()
                if parts:
                    out[key] = int(parts[0]) * (1024 if parts[1:] == ["kB"] else 1)
    except (OSError, ValueError, IndexError):
        return {}
    return out


def _vm_size() -> int | None:
    """This process's address space in use (``VmSize``) [bytes], None when unknown."""
    try:
        with open("/proc/self/status", encoding="ascii", errors="replace") as fh:
            for line in fh:
                if line.startswith("VmSize:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    return None


def _read_int(path: Path) -> int | None:
    try:
        text = path.read_text(encoding="ascii").strip()
    except OSError:
        return None
    if text == "max":
        return None
    try:
        value = int(text)
    except ValueError:
        return None
    return value if value < (1 << 62) else None  # v1 writes "unlimited" as ~2**63


def _inactive_file(stat: Path, key: str) -> int:
    """Reclaimable page cache of a cgroup (its memory.stat ``key``) [bytes]."""
    try:
        for line in stat.read_text(encoding="ascii").splitlines():
            name, _, value = line.partition(" ")
            if name == key:
                return int(value)
    except (OSError, ValueError):
        pass
    return 0


def _cgroup_room() -> int | None:
    """Bytes left under this process's cgroup memory limit (v2 or v1), None without one."""
    try:
        lines = Path("/proc/self/cgroup").read_text(encoding="ascii").splitlines()
    except OSError:
        return None
    rooms = []
    for line in lines:
        _, controllers, path = line.split(":", 2) if line.count(":") >= 2 else ("", "", "")
        if controllers == "":  # v2: the limit of the group or of any parent
            base, files = Path("/sys/fs/cgroup"), ("memory.max", "memory.current", "inactive_file")
        elif "memory" in controllers.split(","):
            base = Path("/sys/fs/cgroup/memory")
            files = ("memory.limit_in_bytes", "memory.usage_in_bytes", "total_inactive_file")
        else:
            continue
        group = base / path.lstrip("/")
        if not group.is_dir():  # a cgroup namespace: its root is the mount
            group = base
        while True:
            limit = _read_int(group / files[0])
            if limit is not None:
                used = _read_int(group / files[1]) or 0
                used -= _inactive_file(group / "memory.stat", files[2])
                rooms.append(max(0, limit - max(0, used)))
            if group == base or group.parent == group:
                break
            group = group.parent
    return min(rooms) if rooms else None


def limits() -> list[Limit]:
    """The limits on the memory this process may still take (Linux; [] when none is known)."""
    out = []
    available = _meminfo().get("MemAvailable")
    if available is not None:
        out.append(Limit(available, "MemAvailable"))
    cgroup = _cgroup_room()
    if cgroup is not None:
        out.append(Limit(cgroup, "the cgroup's memory limit"))
    soft = resource.getrlimit(resource.RLIMIT_AS)[0]
    if soft != resource.RLIM_INFINITY and soft > 0:
        used = _vm_size() or 0
        out.append(Limit(max(0, soft - used), "ulimit -v (RLIMIT_AS)", address_space=True))
    return out


def check_bytes(need: int, what: str, each: str) -> None:
    """Refuse before allocating ``need`` bytes that would not fit in memory.

    Args:
        need: the bytes about to be allocated [bytes].
        what: the work, for messages ("the random samples of 100,000,000 variants").
        each: what the bytes are, for messages ("3 axes of 800 MB").

    Raises:
        MemoryLimitError: naming the need and the limit.
    """
    threads_that_fit(1, Cost(need), what=what, each=each)


def check_data(model: Any, what: str) -> None:
    """Refuse before making one ``Data`` of ``model`` that would not fit in memory.

    Raises:
        MemoryLimitError: naming the need and the limit.
    """
    data = data_bytes(model)
    threads_that_fit(1, Cost(data), what=what, each=f"{describe(data)} for Pinocchio's Data")


def threads_that_fit(
    threads: int,
    per_thread: Cost,
    *,
    fixed: Cost = Cost(),
    allocating: bool = False,
    what: str,
    each: str = "a thread",
    name: str | None = None,
) -> int:
    """The most of ``threads`` threads whose memory fits every limit (at least 1).

    Args:
        threads: the threads wanted.
        per_thread: what each thread takes (its copies, its stack).
        fixed: what the call takes whatever the threads.
        allocating: the threads other than the caller's allocate (numba's do): each
            may reserve a malloc arena (:func:`arenas`).
        what: the work, for messages ("inverse dynamics of a 300-joint model").
        each: what one thread's part is, for messages ("one copy of Pinocchio's Data").
        name: the argument that asked for ``threads`` (``"threads"``), None when
            they are a default: a cut of an asked count is then said on the
            ``rrt_pin`` logger at WARNING (a default's at INFO).

    Raises:
        MemoryLimitError: not even one thread fits (names the need and the limit).
    """

    def cost(k: int) -> Cost:
        return fixed + per_thread * k + (arenas(k - 1) if allocating else Cost())

    whole = cost(threads)
    if whole.resident + whole.reserved <= SMALL:
        return threads  # far below any limit a Python process runs under: nothing read
    found = limits()
    found.sort(key=lambda limit: limit.usable() - limit.takes(cost(1)))  # the tightest first
    for limit in found:
        one = limit.takes(cost(1))
        if one > limit.usable():
            raise MemoryLimitError(
                f"{what} needs {describe(one)} ({each}), more than the "
                f"{describe(limit.usable())} it may use: {describe(limit.room)} left under "
                f"{limit.name}",
                need=one,
                limit=limit.room,
                source=limit.name,
            )
    fit, binding = threads, None
    for limit in found:
        if limit.takes(cost(fit)) <= limit.usable():
            continue
        low, high = 1, fit  # cost(low) fits, cost(high) does not
        while high - low > 1:
            mid = (low + high) // 2
            low, high = (mid, high) if limit.takes(cost(mid)) <= limit.usable() else (low, mid)
        fit, binding = low, limit
    if binding is not None:
        asked = f"{name}={threads}" if name is not None else f"{threads} threads"
        _logger.log(
            logging.WARNING if name is not None else logging.INFO,
            "%s: %s would need %s, more than the %s left under %s; using %d threads",
            what,
            asked,
            describe(binding.takes(cost(threads))),
            describe(binding.room),
            binding.name,
            fit,
        )
    return fit
