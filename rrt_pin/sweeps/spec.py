"""A sweep spec: the base run, what varies, what to keep; and the values of every variant.

A spec is a TOML file (or the same dict in Python)::

    [sweep]
    task = "simulate"      # or "inverse"
    # urdf = "arm.urdf"    # another robot (default: the chapter's RRT arm)
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
    metrics = ["final_error", "settling_time"]   # default: all of the task's
    trajectories = [0, 17]                       # dense runs of these variants

Variants are the Cartesian product of the grid axes (first axis slowest) times
``count`` random samples: variant ``i`` is grid point ``i // count`` with
sample ``i % count``. Random samples are drawn once from ``seed``, so a
variant's values never depend on chunking or workers. Names: any of the
chapter's symbols for the arm; ``q0_<k>``, ``qd0_<k>``, ``qf_<k>``, ``kp_<k>``,
``kd_<k>`` (k = 1 … n joints) for a URDF. SI units.
"""

from __future__ import annotations

import hashlib
import json
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from rrt_pin.errors import SceneError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["METRICS", "Spec", "load_spec"]

#: Metrics by task: name -> what it is (units in the column names' docs).
METRICS: dict[str, dict[str, str]] = {
    "simulate": {
        "final_error": "|q(tf) − qf| per joint [rad or m]",
        "settling_time": "2 % settling time per joint [s] (NaN: not settled)",
        "peak_effort": "peak |effort| per joint [N·m or N] and when [s]",
        "excursion": "max |q(t) − q(0)| per joint [rad or m]",
        "control_energy": "∫ Σ|τ·q̇| dt [J]",
        "evaluations": "dynamics evaluations",
        "diverged": "whether the run diverged, when [s] and in which coordinate",
    },
    "inverse": {
        "peak_effort": "peak |effort| per joint [N·m or N] and when [s]",
        "control_energy": "∫ Σ|τ·q̇| dt [J]",
    },
}
_SECTIONS = ("sweep", "base", "vary", "keep")
_SWEEP_KEYS = ("task", "urdf", "tf", "dt", "count", "seed", "chunk", "method", "rtol", "atol")
_GRID = ("linspace", "logspace")
_RANDOM = ("uniform", "normal", "lhs")
#: Variants per chunk unless the spec says (a second or so of one core's work).
DEFAULT_CHUNK = 8192
#: Largest number of variants a spec may ask for.
MAX_VARIANTS = 100_000_000
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

    def grid(self) -> np.ndarray:
        """The grid's values."""
        if self.kind == "values":
            return np.array(self.args)
        a, b, n = self.args
        if self.kind == "linspace":
            return np.linspace(a, b, int(n))
        return np.logspace(a, b, int(n))


@dataclass(frozen=True)
class Spec:
    """A validated sweep spec (see the module's docstring).

    Attributes:
        task: ``simulate`` or ``inverse``.
        urdf: the robot's URDF, or None for the chapter's arm.
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
        return tuple(a.grid().size for a in self.grid_axes)

    @property
    def variants(self) -> int:
        """How many variants the spec describes."""
        return math.prod(self.grid_shape) * self.count

    @property
    def chunks(self) -> list[tuple[int, int]]:
        """(start, stop) of every chunk, in order."""
        n = self.variants
        return [(s, min(s + self.chunk, n)) for s in range(0, n, self.chunk)]

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
                out[a.name] = a.grid()[k]
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


def _number(where: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{where}={value!r} must be a number")
    x = float(value)
    if not math.isfinite(x):
        raise SceneError(f"{where}={value!r} must be finite")
    return x


def _axis(name: str, value: Any) -> Axis:
    where = f"[vary] {name}"
    if isinstance(value, list):
        if not value:
            raise SceneError(f"{where} is an empty list of values")
        return Axis(name, "values", tuple(_number(f"{where}[{i}]", v) for i, v in enumerate(value)))
    if not isinstance(value, dict) or len(value) != 1:
        raise SceneError(
            f"{where}={value!r}: expected a list of values or one of "
            f"{{ {', '.join(_GRID + _RANDOM)} = [...] }}"
        )
    ((kind, args),) = value.items()
    if kind not in _GRID + _RANDOM:
        raise SceneError(f"{where}: unknown kind {kind!r}; valid: {', '.join(_GRID + _RANDOM)}")
    if not isinstance(args, list):
        raise SceneError(f"{where}: {kind} needs a list, not {args!r}")
    want = 3 if kind in _GRID else 2
    if len(args) != want:
        raise SceneError(f"{where}: {kind} takes {want} numbers, not {len(args)}")
    nums = tuple(_number(f"{where}.{kind}[{i}]", v) for i, v in enumerate(args))
    if kind in _GRID:
        n = nums[2]
        if n != int(n) or n < 1:
            raise SceneError(
                f"{where}: {kind} needs a whole number of values >= 1, not {args[2]!r}"
            )
        if kind == "logspace" and max(abs(nums[0]), abs(nums[1])) > 300:
            raise SceneError(f"{where}: logspace exponents beyond ±300 overflow")
    elif kind in ("uniform", "lhs") and not nums[0] < nums[1]:
        raise SceneError(f"{where}: {kind} needs low < high, not {list(args)!r}")
    elif kind == "normal" and nums[1] < 0:
        raise SceneError(f"{where}: normal needs a standard deviation >= 0, not {args[1]!r}")
    return Axis(name, kind, nums)


def _urdf_names(n: int) -> list[str]:
    return [f"{p}_{k}" for p in _URDF_PREFIXES for k in range(1, n + 1)]


def spec_from_dict(data: Mapping[str, Any], where: str = "spec") -> Spec:
    """A validated :class:`Spec` from the TOML's dict.

    Raises:
        SceneError: an unknown section, key, name or metric; an empty range; a
            negative count; values that make a parameter invalid (e.g. a
            negative mass), each in one line naming it.
    """
    data = dict(data)
    unknown = sorted(set(data) - set(_SECTIONS))
    if unknown:
        raise SceneError(f"{where}: unknown section [{unknown[0]}]; valid: {', '.join(_SECTIONS)}")
    sweep = dict(data.get("sweep", {}))
    bad = sorted(set(sweep) - set(_SWEEP_KEYS))
    if bad:
        raise SceneError(
            f"{where}: unknown key {bad[0]!r} in [sweep]; valid: {', '.join(_SWEEP_KEYS)}"
        )
    task = sweep.get("task", "simulate")
    if task not in METRICS:
        raise SceneError(f"{where}: task={task!r} is not one of {', '.join(METRICS)}")
    urdf = sweep.get("urdf")
    if urdf is not None and (not isinstance(urdf, str) or not urdf):
        raise SceneError(f"{where}: urdf={urdf!r} must be a path")
    tf = _number("tf", sweep.get("tf", 15.0))
    dt = _number("dt", sweep.get("dt", 0.01))
    if tf <= 0 or dt <= 0 or dt > tf:
        raise SceneError(f"{where}: tf={tf!r} and dt={dt!r} must satisfy 0 < dt <= tf [s]")
    if tf / dt > 1_000_000:
        raise SceneError(f"{where}: tf/dt = {tf / dt:.3g} samples per variant is over 1e6")
    ints = {}
    for key, default, low in (("count", None, 1), ("seed", 0, 0), ("chunk", DEFAULT_CHUNK, 1)):
        value = sweep.get(key, default)
        if value is None:
            continue
        if isinstance(value, bool) or not isinstance(value, int) or value < low:
            raise SceneError(f"{where}: {key}={value!r} must be an integer >= {low}")
        ints[key] = value
    axes = tuple(_axis(name, value) for name, value in dict(data.get("vary", {})).items())
    random = any(a.random for a in axes)
    if random and "count" not in ints:
        raise SceneError(f"{where}: random axes need count = N in [sweep]")
    if not random and "count" in ints:
        raise SceneError(f"{where}: count applies to random axes ([vary] has none)")
    keep = dict(data.get("keep", {}))
    bad = sorted(set(keep) - {"metrics", "trajectories"})
    if bad:
        raise SceneError(f"{where}: unknown key {bad[0]!r} in [keep]; valid: metrics, trajectories")
    metrics = keep.get("metrics", list(METRICS[task]))
    if not isinstance(metrics, list) or not metrics:
        raise SceneError(f"{where}: [keep] metrics must be a non-empty list")
    for m in metrics:
        if m not in METRICS[task]:
            raise SceneError(
                f"{where}: metric {m!r} is not one of task {task}'s: {', '.join(METRICS[task])}"
            )
    trajectories = keep.get("trajectories", [])
    if not isinstance(trajectories, list) or any(
        isinstance(i, bool) or not isinstance(i, int) or i < 0 for i in trajectories
    ):
        raise SceneError(f"{where}: [keep] trajectories must be a list of variant indices >= 0")
    base = {}
    for name, value in dict(data.get("base", {})).items():
        base[name] = (
            [_number(f"[base] {name}", v) for v in value]
            if isinstance(value, list)
            else _number(f"[base] {name}", value)
        )
    for key in ("rtol", "atol"):
        if key in sweep:
            value = _number(key, sweep[key])
            if not 0 < value < 1:
                raise SceneError(f"{where}: {key}={value!r} must lie in (0, 1)")
    spec = Spec(
        task=task,
        urdf=urdf,
        tf=tf,
        dt=dt,
        count=ints.get("count", 1),
        seed=ints["seed"],
        chunk=ints["chunk"],
        method=sweep.get("method"),
        rtol=sweep.get("rtol"),
        atol=sweep.get("atol"),
        base=base,
        axes=axes,
        metrics=tuple(metrics),
        trajectories=tuple(trajectories),
        source=json.loads(json.dumps(data, default=str)),
    )
    if spec.variants > MAX_VARIANTS:
        raise SceneError(f"{where}: {spec.variants} variants is over the limit of {MAX_VARIANTS}")
    for i in spec.trajectories:
        if i >= spec.variants:
            raise SceneError(f"{where}: trajectory of variant {i}, but there are {spec.variants}")
    return spec


def load_spec(path: str | Path) -> Spec:
    """Read and validate a sweep spec (TOML).

    Raises:
        SceneError: the file cannot be read, is not TOML, or is not a valid spec.
    """
    path = Path(path)
    try:
        raw = path.read_bytes()
    except OSError as e:
        raise SceneError(f"cannot read sweep spec {str(path)!r}: {e.strerror or e}") from e
    if len(raw) > 1_000_000:
        raise SceneError(f"sweep spec {str(path)!r} is over 1 MB")
    try:
        data = tomllib.loads(raw.decode("utf-8").removeprefix("\ufeff"))
    except (UnicodeDecodeError, tomllib.TOMLDecodeError) as e:
        raise SceneError(f"sweep spec {str(path)!r} is not valid TOML: {e}") from e
    return spec_from_dict(data, where=f"sweep spec {str(path)!r}")
