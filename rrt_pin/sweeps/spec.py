"""A sweep spec: the base run, what varies, what to keep; and the values of every variant.

A spec is a TOML file (or the same dict in Python)::

    [sweep]
    task = "simulate"      # or "inverse"
    # robot = "ur5"       # another robot by name (rrt_pin.robots), or
    # urdf = "arm.urdf"    # by its URDF (default: the chapter's RRT arm)
    tf = 15.0              # [s]
    dt = 0.01              # interval of the samples the metrics are computed from [s]
    count = 1000           # random samples (with random axes)
    seed = 1
    chunk = 8192           # variants per chunk (one Parquet file each)

    [base]                 # fixed values: the chapter's symbols (or q0, qf, kp, kd for a URDF)
    m3 = 40.0

    [vary]
    m3 = [30, 40, 50]                       # grid: these values
    gamma01 = { linspace = [200, 400, 5] }  # grid: start, stop, number
    beta01 = { logspace = [2, 3, 4] }       # grid: 10**2 … 10**3, 4 values
    I3x = { uniform = [4.0, 6.0] }          # random: low, high
    q10 = { normal = [0.17, 0.05] }         # random: mean, standard deviation
    gamma23 = { lhs = [40.0, 60.0] }        # random: Latin hypercube over all lhs axes

    [keep]
    metrics = ["final_error", "settling_time"]   # default: all of the task's (the arm: not limits)
    trajectories = [0, 17]                       # dense runs of these variants

Variants are the Cartesian product of the grid axes (first axis slowest) times
``count`` random samples: variant ``i`` is grid point ``i // count`` with
sample ``i % count``. Random samples are drawn once from ``seed``, so a
variant's values never depend on chunking or workers. Names: any of the
chapter's symbols for the arm; ``q0_<k>``, ``qd0_<k>``, ``qf_<k>``, ``kp_<k>``,
``kd_<k>`` (k = 1 … n joints) for a URDF. SI units.

Sizes are counted before anything is made: a spec asking for more than
:data:`MAX_VARIANTS` variants (or :data:`MAX_CHUNKS` chunks) is refused from
its axes' sizes alone, and a chunk computes its variants' grid values from
their indices, never the whole grid.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rrt_pin.core import memory
from rrt_pin.core.errors import InputError, SpecError
from rrt_pin.io._read import check_int64, load_toml
from rrt_pin.robot import robots
from rrt_pin.simulate.metrics import TEXT_COLUMNS, for_task

__all__ = [
    "MAX_SPEC_BYTES",
    "MAX_VARIANTS",
    "METRICS",
    "TEXT_COLUMNS",
    "Spec",
    "load_spec",
    "spec_from_dict",
]

#: Metrics by task: name -> what it is (from the registry, :data:`rrt_pin.simulate.metrics.METRICS`).
METRICS: dict[str, dict[str, str]] = {task: for_task(task) for task in ("simulate", "inverse")}
#: Metrics a sweep of the chapter's arm leaves out unless asked: its URDF states no
#: binding limit (the columns would be 0).
ARM_UNASKED = ("limits",)
_SECTIONS = ("sweep", "base", "vary", "keep")
_SWEEP_KEYS = (
    "task",
    "robot",
    "urdf",
    "tf",
    "dt",
    "count",
    "seed",
    "chunk",
    "method",
    "rtol",
    "atol",
)
_GRID = ("linspace", "logspace")
_RANDOM = ("uniform", "normal", "lhs")
#: Variants per chunk unless the spec says (a second or so of one core's work).
DEFAULT_CHUNK = 8192
#: Largest number of variants a spec may ask for.
MAX_VARIANTS = 100_000_000
#: Largest number of chunks (each is a file and a manifest entry).
MAX_CHUNKS = 100_000
#: Largest spec file [bytes].
MAX_SPEC_BYTES = 1 << 20
#: What each section must be, for messages.
_SECTION_KINDS = {
    "sweep": "a table of options (task, tf, dt, count …)",
    "base": "a table of name = value",
    "vary": "a table of name = values or { kind = [...] }",
    "keep": "a table (metrics = [...], trajectories = [...])",
}
_URDF_PREFIXES = ("q0", "qd0", "qf", "kp", "kd")


@dataclass(frozen=True)
class Axis:
    """One varied name: a grid of values, or a random distribution.

    Attributes:
        name: the varied symbol.
        kind: ``values``, ``linspace``, ``logspace``, ``uniform``, ``normal`` or ``lhs``.
        args: the values (grid) or the distribution's two numbers.
    """

    name: str
    kind: str
    args: tuple[float, ...]

    @property
    def random(self) -> bool:
        """Whether the axis is drawn at random."""
        return self.kind in _RANDOM

    @property
    def size(self) -> int:
        """The number of grid values, counted without making them (1 for a random axis)."""
        if self.random:
            return 1
        if self.kind == "values":
            return len(self.args)
        return int(self.args[2])

    def grid(self) -> np.ndarray:
        """The grid's values (all of them: for small grids; see :meth:`take`)."""
        if self.kind == "values":
            return np.array(self.args)
        a, b, n = self.args
        if self.kind == "linspace":
            return np.linspace(a, b, int(n))
        return np.logspace(a, b, int(n))

    def take(self, k: np.ndarray) -> np.ndarray:
        """The grid values at indices ``k``, bit for bit those of :meth:`grid`, made alone.

        ``np.linspace``'s arithmetic (``k·step + start``, the end set exactly; ``k / div ·
        delta`` where the step underflows) on the indices asked for only.
        """
        k = np.asarray(k)
        if self.kind == "values":
            return np.array(self.args)[k]
        a, b, n = self.args
        n = int(n)
        start, stop = np.float64(a), np.float64(b)
        y = k.astype(np.float64)
        if n > 1:
            div = n - 1
            delta = np.subtract(stop, start, dtype=np.float64)
            step = delta / div
            y = y / div * delta if step == 0 else y * step
            y += start
            y[k == n - 1] = stop
        else:
            y = y * np.subtract(stop, start, dtype=np.float64) + start
        return y if self.kind == "linspace" else np.power(np.float64(10.0), y)

    def ends(self) -> tuple[float, float]:
        """The smallest and largest values a grid or a bounded distribution reaches."""
        if self.kind == "values":
            return min(self.args), max(self.args)
        if self.kind in ("linspace", "uniform", "lhs"):
            return min(self.args[:2]), max(self.args[:2])
        if self.kind == "logspace":
            return 10.0 ** min(self.args[:2]), 10.0 ** max(self.args[:2])
        raise ValueError(f"a {self.kind} axis has no ends")


@dataclass(frozen=True)
class Spec:
    """A validated sweep spec (see the module's docstring).

    Attributes:
        task: ``simulate`` or ``inverse``.
        robot: the robot's name in :mod:`rrt_pin.robot.robots` (None or ``rrt``: the
            chapter's arm, unless ``urdf`` is given).
        urdf: the robot's URDF, or None.
        tf: end time [s].
        dt: sample interval of the metrics [s].
        count: random samples per grid point (1 without random axes).
        seed: seed of the random samples.
        chunk: variants per chunk.
        method, rtol, atol: integration options (None: the backend's defaults).
        base: fixed values by name.
        axes: the varied names.
        metrics: the metric groups kept.
        trajectories: variant indices whose dense runs are kept.
        source: the spec as given (for the hash and the manifest).
    """

    task: str = "simulate"
    robot: str | None = None
    urdf: str | None = None
    tf: float = 15.0
    dt: float = 0.01
    count: int = 1
    seed: int = 0
    chunk: int = DEFAULT_CHUNK
    method: str | None = None
    rtol: float | None = None
    atol: float | None = None
    base: dict[str, float] = field(default_factory=dict)
    axes: tuple[Axis, ...] = ()
    metrics: tuple[str, ...] = ()
    trajectories: tuple[int, ...] = ()
    source: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    # ------------------------------------------------------------------ sizes
    @property
    def grid_axes(self) -> tuple[Axis, ...]:
        """The grid axes, in the spec's order."""
        return tuple(a for a in self.axes if not a.random)

    @property
    def random_axes(self) -> tuple[Axis, ...]:
        """The random axes, in the spec's order."""
        return tuple(a for a in self.axes if a.random)

    @property
    def grid_shape(self) -> tuple[int, ...]:
        """The number of values of each grid axis."""
        return tuple(a.size for a in self.grid_axes)

    @property
    def variants(self) -> int:
        """How many variants the spec describes (a Python int: never overflows)."""
        return math.prod(self.grid_shape) * self.count

    @property
    def chunks(self) -> list[tuple[int, int]]:
        """(start, stop) of every chunk, in order."""
        n = self.variants
        return [(s, min(s + self.chunk, n)) for s in range(0, n, self.chunk)]

    @property
    def chapter_arm(self) -> bool:
        """Whether the sweep's robot is the chapter's arm (its Params are what vary)."""
        return robots.names_chapter_arm(self.urdf, self.robot)

    def urdf_file(self) -> str:
        """The URDF of a robot other than the chapter's arm (given, or found by its name).

        Raises:
            SpecError: the robot's URDF cannot be found (example-robot-data missing).
        """
        try:
            return self.urdf or str(robots.urdf_path(str(self.robot)))
        except InputError as e:
            raise SpecError(f"[sweep] robot: {e}") from e

    def digest(self) -> str:
        """A hash of what the sweep computes (the chunk size excluded: it changes no result).

        The order of the [vary] names counts: it orders the variants.
        """
        src = {k: self.source[k] for k in _SECTIONS if k in self.source and k != "sweep"}
        sweep = self.source.get("sweep", {})
        src["sweep"] = {k: sweep[k] for k in sorted(sweep) if k != "chunk"}
        text = json.dumps(src, default=str)
        return hashlib.sha256(text.encode("utf-8")).hexdigest()[:16]

    # ------------------------------------------------------------------ values
    def random_table(self) -> dict[str, np.ndarray]:
        """The random samples of every random axis, ``count`` each (drawn once from the seed)."""
        rng = np.random.default_rng(self.seed)
        out: dict[str, np.ndarray] = {}
        lhs = [a for a in self.random_axes if a.kind == "lhs"]
        columns = len(self.random_axes) + len(lhs)  # lhs: its unit cube, then the values
        memory.check_bytes(
            8 * self.count * columns,
            f"drawing the random samples of {self.count:,} variants",
            f"{len(self.random_axes)} random axes of {memory.describe(8 * self.count)} each"
            + (", and the Latin hypercube they come from" if lhs else ""),
        )
        if lhs:
            from scipy.stats import qmc

            unit = qmc.LatinHypercube(d=len(lhs), seed=rng).random(self.count)
            for k, a in enumerate(lhs):
                lo, hi = a.args
                out[a.name] = lo + (hi - lo) * unit[:, k]
        for a in self.random_axes:
            if a.kind == "uniform":
                out[a.name] = rng.uniform(a.args[0], a.args[1], self.count)
            elif a.kind == "normal":
                out[a.name] = rng.normal(a.args[0], a.args[1], self.count)
        return out

    def values(
        self, start: int, stop: int, random: Mapping[str, np.ndarray] | None = None
    ) -> dict[str, np.ndarray]:
        """The varied values of variants ``start`` … ``stop − 1``, by name.

        Args:
            start: first variant index.
            stop: one past the last.
            random: the random samples of exactly these variants, by name
                (:meth:`random_rows`); drawn from the seed when None.
        """
        index = np.arange(start, stop)
        out: dict[str, np.ndarray] = {}
        grid_axes = self.grid_axes
        if grid_axes:
            point = np.unravel_index(index // self.count, self.grid_shape)
            for a, k in zip(grid_axes, point, strict=True):
                out[a.name] = a.take(k)
        if self.random_axes:
            rows = self.random_rows(self.random_table(), start, stop) if random is None else random
            for a in self.random_axes:
                out[a.name] = np.asarray(rows[a.name], dtype=float)
        return out

    def random_rows(
        self, table: Mapping[str, np.ndarray], start: int, stop: int
    ) -> dict[str, np.ndarray]:
        """The random samples that variants ``start`` … ``stop − 1`` use, from the full table."""
        rows = np.arange(start, stop) % self.count
        return {name: np.ascontiguousarray(np.asarray(col)[rows]) for name, col in table.items()}


def _show(value: Any, limit: int = 60) -> str:
    """``repr(value)``, cut to ``limit`` characters (a message stays one short line)."""
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 1] + "…"


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SpecError(f"{where}={_show(value)} must be a number")
    try:
        x = float(value)
    except OverflowError:  # an int beyond float's range (a dict spec's)
        x = math.inf
    if not math.isfinite(x):
        raise SpecError(f"{where}={_show(value)} must be finite")
    return x


def _axis(name: str, value: Any) -> Axis:
    where = f"[vary] {name}"
    if isinstance(value, list):
        if not value:
            raise SpecError(f"{where} is an empty list of values")
        return Axis(name, "values", tuple(_number(f"{where}[{i}]", v) for i, v in enumerate(value)))
    if not isinstance(value, dict) or len(value) != 1:
        raise SpecError(
            f"{where}={value!r}: expected a list of values or one of "
            f"{{ {', '.join(_GRID + _RANDOM)} = [...] }}"
        )
    ((kind, args),) = value.items()
    if kind not in _GRID + _RANDOM:
        raise SpecError(f"{where}: unknown kind {kind!r}; valid: {', '.join(_GRID + _RANDOM)}")
    if not isinstance(args, list):
        raise SpecError(f"{where}: {kind} needs a list, not {args!r}")
    want = 3 if kind in _GRID else 2
    if len(args) != want:
        raise SpecError(f"{where}: {kind} takes {want} numbers, not {len(args)}")
    nums = tuple(_number(f"{where}.{kind}[{i}]", v) for i, v in enumerate(args))
    if kind in _GRID:
        n = nums[2]
        if n != int(n) or n < 1:
            raise SpecError(f"{where}: {kind} needs a whole number of values >= 1, not {args[2]!r}")
        if kind == "logspace" and max(abs(nums[0]), abs(nums[1])) > 300:
            raise SpecError(f"{where}: logspace exponents beyond ±300 overflow")
    elif kind in ("uniform", "lhs") and not nums[0] < nums[1]:
        raise SpecError(f"{where}: {kind} needs low < high, not {list(args)!r}")
    elif kind == "normal" and nums[1] < 0:
        raise SpecError(f"{where}: normal needs a standard deviation >= 0, not {args[1]!r}")
    return Axis(name, kind, nums)


def _urdf_names(n: int) -> list[str]:
    return [f"{p}_{k}" for p in _URDF_PREFIXES for k in range(1, n + 1)]


def _plain(value: Any, where: str, name: str, depth: int = 0) -> Any:
    """``value`` in TOML's types, integers beyond 64 bits refused.

    Numpy scalars and arrays become Python numbers and lists, tuples lists,
    mappings dicts.
    """
    if depth > 32:
        raise SpecError(f"{where}: {name} is nested too deeply")
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, Mapping):
        out = {}
        for key, item in value.items():
            if not isinstance(key, str):
                raise SpecError(f"{where}: {name} has the key {_show(key)}; keys are names")
            out[key] = _plain(item, where, f"{name}.{key}" if name else key, depth + 1)
        return out
    if isinstance(value, (list, tuple)):
        return [_plain(v, where, f"{name}[{i}]", depth + 1) for i, v in enumerate(value)]
    check_int64(where, name, value, SpecError)
    return value


def _kind(value: Any) -> str:
    if isinstance(value, list):
        return "an array of tables" if value and isinstance(value[0], dict) else "an array"
    if isinstance(value, str):
        return f"the string {_show(value)}"
    return f"{type(value).__name__} {_show(value)}"


def _section(data: dict[str, Any], name: str, where: str) -> dict[str, Any]:
    value = data.get(name, {})
    if not isinstance(value, dict):
        raise SpecError(f"{where}: [{name}] must be {_SECTION_KINDS[name]}, not {_kind(value)}")
    return value


def _count_text(n: int) -> str:
    """A count for a message: exact up to 15 digits, else its power of ten."""
    if n < 10**15:
        return f"{n:,}"
    if n < 10**300:
        return f"about {float(n):.2g}"
    return f"about 1e+{int(n.bit_length() * math.log10(2))}"


def spec_from_dict(data: Mapping[str, Any], where: str = "spec") -> Spec:
    """A validated :class:`Spec` from the TOML's dict.

    Values may be numpy scalars or arrays (taken as numbers and lists).

    Raises:
        SpecError: a section that is not a table, an unknown section, key,
            name or metric; an empty range; a negative count; more variants or
            chunks than allowed (counted before anything is made); values that
            make a parameter invalid (e.g. a negative mass), each in one line
            naming it.
    """
    if not isinstance(data, Mapping):
        raise SpecError(f"{where}: a spec is a table of sections, not {_kind(data)}")
    try:
        data = _plain(data, where, "")
    except RecursionError:
        raise SpecError(f"{where}: nested too deeply") from None
    unknown = sorted(set(data) - set(_SECTIONS))
    if unknown:
        raise SpecError(f"{where}: unknown section [{unknown[0]}]; valid: {', '.join(_SECTIONS)}")
    sweep = _section(data, "sweep", where)
    vary = _section(data, "vary", where)
    keep = _section(data, "keep", where)
    base_in = _section(data, "base", where)
    bad = sorted(set(sweep) - set(_SWEEP_KEYS))
    if bad:
        raise SpecError(
            f"{where}: unknown key {bad[0]!r} in [sweep]; valid: {', '.join(_SWEEP_KEYS)}"
        )
    task = sweep.get("task", "simulate")
    if not isinstance(task, str) or task not in METRICS:
        raise SpecError(f"{where}: task={_show(task)} is not one of {', '.join(METRICS)}")
    urdf = sweep.get("urdf")
    if urdf is not None and (not isinstance(urdf, str) or not urdf):
        raise SpecError(f"{where}: urdf={_show(urdf)} must be a path")
    robot = sweep.get("robot")
    if robot is not None and (not isinstance(robot, str) or robot not in robots.names()):
        raise SpecError(f"{where}: robot={_show(robot)} is not one of {', '.join(robots.names())}")
    if robot is not None and urdf is not None:
        raise SpecError(f"{where}: [sweep] names a robot and a urdf: give one")
    arm = robots.names_chapter_arm(urdf, robot)
    method = sweep.get("method")
    if method is not None and (not isinstance(method, str) or not method):
        raise SpecError(f"{where}: method={_show(method)} must be a method's name")
    tf = _number("tf", sweep.get("tf", 15.0))
    dt = _number("dt", sweep.get("dt", 0.01))
    if tf <= 0 or dt <= 0 or dt > tf:
        raise SpecError(f"{where}: tf={tf:.6g} and dt={dt:.6g} must satisfy 0 < dt <= tf [s]")
    if tf / dt > 1_000_000:
        raise SpecError(f"{where}: tf/dt = {tf / dt:.3g} samples per variant is over 1e6")
    ints = {}
    for key, default, low in (("count", None, 1), ("seed", 0, 0), ("chunk", DEFAULT_CHUNK, 1)):
        value = sweep.get(key, default)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise SpecError(f"{where}: {key}={_show(value)} must be an integer >= {low}")
        ints[key] = value
    axes = tuple(_axis(name, value) for name, value in vary.items())
    random = any(a.random for a in axes)
    if random and "count" not in ints:
        raise SpecError(f"{where}: random axes need count = N in [sweep]")
    if not random and "count" in ints:
        raise SpecError(f"{where}: count applies to random axes ([vary] has none)")
    # counted as Python ints from the axes' sizes, before any value is made
    variants = math.prod(a.size for a in axes if not a.random) * ints.get("count", 1)
    if variants > MAX_VARIANTS:
        factors = [
            f"[vary] {name}: {_count_text(a.size)}"
            for name, a in zip(vary, axes, strict=True)
            if not a.random
        ]
        if random:
            factors.append(f"count {_count_text(ints['count'])}")
        sizes = f" ({' × '.join(factors)})"
        raise SpecError(
            f"{where}: {_count_text(variants)} variants{sizes} is over the limit of "
            f"{MAX_VARIANTS:,}"
        )
    chunks = -(-variants // ints["chunk"])
    if chunks > MAX_CHUNKS:
        raise SpecError(
            f"{where}: chunk={ints['chunk']} makes {chunks:,} chunks of {variants:,} variants, "
            f"over the limit of {MAX_CHUNKS:,}; use a larger chunk"
        )
    bad = sorted(set(keep) - {"metrics", "trajectories"})
    if bad:
        raise SpecError(f"{where}: unknown key {bad[0]!r} in [keep]; valid: metrics, trajectories")
    default = [m for m in METRICS[task] if not (arm and m in ARM_UNASKED)]
    metrics = keep.get("metrics", default)
    if not isinstance(metrics, list) or not metrics:
        raise SpecError(f"{where}: [keep] metrics must be a non-empty list")
    for m in metrics:
        if not isinstance(m, str) or m not in METRICS[task]:
            raise SpecError(
                f"{where}: metric {_show(m)} is not one of task {task}'s: "
                f"{', '.join(METRICS[task])}"
            )
    trajectories = keep.get("trajectories", [])
    if not isinstance(trajectories, list) or any(
        isinstance(i, bool) or not isinstance(i, int) or i < 0 for i in trajectories
    ):
        raise SpecError(f"{where}: [keep] trajectories must be a list of variant indices >= 0")
    for i in trajectories:
        if i >= variants:
            raise SpecError(f"{where}: trajectory of variant {i}, but there are {variants}")
    base = {}
    for name, value in base_in.items():
        if isinstance(value, list):
            if arm or name not in _URDF_PREFIXES:
                lists = f"a URDF's {', '.join(_URDF_PREFIXES)}" if not arm else "a URDF sweep"
                raise SpecError(
                    f"{where}: [base] {name} = {_show(value)} must be a number "
                    f"(lists of values per joint are for {lists})"
                )
            base[name] = [_number(f"[base] {name}[{i}]", v) for i, v in enumerate(value)]
        else:
            base[name] = _number(f"[base] {name}", value)
    for key in ("rtol", "atol"):
        if key in sweep:
            value = _number(key, sweep[key])
            if not 0 < value < 1:
                raise SpecError(f"{where}: {key}={value:.6g} must lie in (0, 1)")
    return Spec(
        task=task,
        robot=robot,
        urdf=urdf,
        tf=tf,
        dt=dt,
        count=ints.get("count", 1),
        seed=ints["seed"],
        chunk=ints["chunk"],
        method=method,
        rtol=sweep.get("rtol"),
        atol=sweep.get("atol"),
        base=base,
        axes=axes,
        metrics=tuple(metrics),
        trajectories=tuple(trajectories),
        source=json.loads(json.dumps(data)),
    )


def load_spec(path: str | Path) -> Spec:
    """Read and validate a sweep spec (TOML, UTF-8, at most 1 MB).

    Read as run files are (:func:`rrt_pin.io._read.load_toml`): a device, a folder or a
    FIFO nobody writes to is refused without blocking, nesting and 64-bit integers
    are guarded.

    Raises:
        SpecError: the file cannot be read, is not TOML, or is not a valid spec.
    """
    data = load_toml(path, cap=MAX_SPEC_BYTES, what="sweep spec", error=SpecError)
    return spec_from_dict(data, where=f"sweep spec {str(path)!r}")
