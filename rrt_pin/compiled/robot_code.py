"""A robot's integrators in machine code: its generated dynamics inside the template, compiled once.

:func:`integrators_for` writes one module a robot: its generated one-sample forward
dynamics (ABA), gravity, mass matrix and bias (:mod:`rrt_pin.dynamics.forward_source`),
the ``LAW_*``, ``KEEP_*``, ``METHOD_*`` and ``STATUS_*`` codes of
:mod:`rrt_pin.simulate.codes`, and the integrators of :mod:`rrt_pin.compiled._robot_template`.
The generated functions are lowered to LLVM IR past numba's front end
(:mod:`rrt_pin.compiled._straight`: the same bits, compiled an order of magnitude
faster). The module
is named by the SHA-256 of its source and kept under ``generated/`` of the
cache directory, as the generated RNEA is (:mod:`rrt_pin.compiled.rnea`): numba's
machine code beside it, its files' SHA-256 recorded and checked before they are
read. Its entry points (``run_many``; ``run_lanes``, a batch's; ``run_adams``, Adams's
method of :mod:`rrt_pin.compiled._robot_adams`; ``run_bdf``, SciPy's BDF of
:mod:`rrt_pin.compiled._robot_bdf` with the loop's generated Jacobian) are each compiled on first use,
announced on the ``rrt_pin`` logger ("compiling ur5's integrators once (~N s)"); a later
process loads it.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import re
import threading
import time
import types
from operator import attrgetter
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rrt_pin.compiled import _models, rnea, rnea_vector, robot_entries
from rrt_pin.core import backends
from rrt_pin.core._logging import note
from rrt_pin.core.identity import IdentityCache
from rrt_pin.dynamics import forward_source
from rrt_pin.dynamics.forward_derivatives_source import closed_loop_derivatives_source
from rrt_pin.dynamics.rnea_source import check_supported
from rrt_pin.robot import limits
from rrt_pin.simulate import codes

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = ["LANES", "RobotCode", "integrators_for", "module_source"]

_TEMPLATE = Path(__file__).with_name("_robot_template.py")
_MARK = "# --- template ---\n"
_LANES = Path(__file__).with_name("_robot_lanes.py")
_LANES_MARK = "# --- lanes ---\n"
#: Parts appended from their line ``# --- name ---`` on: DOP853-RKC's tail, Adams, BDF.
_PARTS = ("rkc", "adams", "bdf")
#: A batch's variants a thread runs side by side (vectors of 8 doubles, AVX-512).
LANES = 8
#: What compiling an entry takes, roughly [s]: a constant and a share per generated
#: operation (the announcement's estimate only; fitted to UR5's and Panda's first use).
_COMPILE_S = 9.0
_COMPILE_S_PER_FLOP = 1.1e-3
#: What an entry compiles, by its name's start, for the announcement.
_WHAT = (("run_lanes", "batch lanes"), ("run_adams", "Adams integrator"),
         ("run_bdf", "BDF integrator"))  # fmt: skip
_CODES = (
    "LAW_NONE", "LAW_PD_GRAVITY", "LAW_TRACKING", "LAW_OPEN_LOOP",
    "KEEP_TRAJECTORIES", "KEEP_FINAL", "KEEP_METRICS",
    "METHOD_DOP853", "METHOD_RK4", "METHOD_SYMPLECTIC_EULER", "FIXED_STEP_FROM",
    "METHOD_BDF", "METHOD_BDF_NUMERIC", "METHOD_DOP853_RKC",
    "STATUS_OK", "STATUS_NONFINITE", "STATUS_STEP_UNDERFLOW", "STATUS_MAX_STEPS",
    "STATUS_NO_CONVERGENCE", "STATUS_EFFORT_NONFINITE",
)  # fmt: skip
_lock = threading.RLock()
_CODE: dict[str, RobotCode] = {}
_MODELS: IdentityCache[tuple[Any, RobotCode]] = IdentityCache(16)


class RobotCode:
    """One robot's compiled integrators: entry points compiled (or loaded) on first use.

    Attributes:
        name: what messages call the robot.
        nv: joint coordinates (the state has 2·nv entries).
        flops: arithmetic operations of one forward-dynamics evaluation.
        origin: how the last entry made came: ``loaded`` (numba's disk cache),
            ``compiled`` (and saved) or ``memory``.
        seconds: what importing the module and compiling (or loading) that entry took [s].

    Each entry is compiled on its first use only: a single run compiles ``run_many``, a
    batch of adaptive PD variants only ``run_lanes``.
    """

    def __init__(
        self, name: str, nv: int, flops: int, module: Any, path: Path | None, source: str
    ) -> None:
        self.name, self.nv, self.flops = name, nv, flops
        self._module, self._path, self._source = module, path, source
        self._entries: dict[str, Any] = {}
        self.origin, self.seconds = "memory", 0.0
        self._imported = time.perf_counter()  # the module's import counts in the first entry

    @property
    def run_many(self) -> Any:
        """Variants one after the other (any law, any method)."""
        return self.entry("run_many")

    @property
    def run_lanes(self) -> Any:
        """Variants side by side in :data:`LANES` lanes (PD plus gravity, RK45 or DOP853)."""
        return self.entry("run_lanes")

    def entry(self, name: str) -> Any:
        """The numba dispatcher of ``name``, compiled (or loaded) for its one signature."""
        found = self._entries.get(name)
        if found is not None:
            return found
        with _lock:
            found = self._entries.get(name)
            if found is None:
                start = min(time.perf_counter(), self._imported)
                self._imported = math.inf
                try:
                    found = self._compile(name)
                except Exception as exc:  # a damaged or unwritable numba cache
                    if self._path is None:
                        raise
                    from rrt_pin.compiled._cache import warn_once

                    warn_once(
                        f"generated integrators cache {self._path.parent}: "
                        f"{type(exc).__name__}: {exc}"[:300]
                    )
                    self._module, self._path = _in_memory(self._source), None
                    found = self._compile(name)
                self._entries[name] = found
                self.seconds = time.perf_counter() - start
        return found

    def _compile(self, name: str) -> Any:
        import numba

        sig = robot_entries.SIGNATURES[name](numba).args
        dispatcher = getattr(self._module, name)
        what = next((label for prefix, label in _WHAT if name.startswith(prefix)), "integrators")
        jac = self._source.partition("def closed_loop_jac(")[2].partition("\n\n\n")[0]
        bdf = name.startswith("run_bdf") and "_num" not in name
        flops = self.flops + (0.6 * jac.count("\n") if bdf else 0)  # + its Jacobian's
        estimate = _estimate(flops) * (1.1 if name.startswith("run_lanes") else 1.0)
        if self._path is None:
            note(f"compiling {self.name}'s {what} (~{estimate:.0f} s, not kept on disk)")
            dispatcher.compile(sig)
            dispatcher.disable_compile()
            return dispatcher
        files = rnea._numba_files(dispatcher)
        record = self._path.with_name(f"{self._path.stem}.{name}.cache.json")
        _discard_unverified(record, files)
        if not files():
            note(f"compiling {self.name}'s {what} once (~{estimate:.0f} s)")
        dispatcher.compile(sig)
        dispatcher.disable_compile()
        origin = "loaded" if sum(dispatcher.stats.cache_hits.values()) else "compiled"
        if origin == "compiled":
            _record(record, files)
        self.origin = origin
        return dispatcher


def _record(record: Path, files: Any) -> None:
    """Record the SHA-256 of numba's files of an entry just compiled."""
    tmp = record.with_name(f".{record.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    try:
        tmp.write_text(json.dumps(rnea._digests(files()), indent=1), encoding="utf-8")
        os.replace(tmp, record)
    except OSError:
        tmp.unlink(missing_ok=True)


def _discard_unverified(record: Path, files: Any) -> None:
    """Delete numba's files of an entry unless they are the ones recorded at its compilation."""
    present = files()
    if not present:
        return
    try:
        recorded = json.loads(record.read_text(encoding="utf-8"))
        if isinstance(recorded, dict) and rnea._digests(present) == recorded:
            return
    except (OSError, ValueError):
        pass
    for f in [*present, record]:
        f.unlink(missing_ok=True)


def _on_state(
    gen: forward_source.GeneratedFunction, name: str, shift: int, pd: bool = False
) -> str:
    """``gen`` as ``name(y, [tau,] out)``: q[k] read from y[k], q̇[k] from y[nv + k].

    A function of the gains (``kp``, ``kd``, ``qf``: a closed loop's Jacobian) reads them
    from ``c`` = (kp, kd, qf): ``name(y, c, out)``.

    The state is read in place (no slices, whose reference counts cost more than a
    few operations); ``shift`` moves the results' rows (q̈ into out[nv:] of ẏ). Each
    angle's sine and cosine are the polynomial ones of :mod:`rrt_pin.compiled.rnea_vector`
    (one reduction for both, no call) below their limit, libm's beyond it.
    """
    nv = gen.nv
    trig = re.compile(r"^(t\d+) = (sin|cos)\((t\d+)\)$")
    body: list[str] = []
    seen: set[str] = set()
    for line in gen.lines:
        if m := trig.match(line):
            x = m[3]
            if x not in seen:
                seen.add(x)
                body += [f"    if abs({x}) < {rnea_vector.SINCOS_LIMIT!r}:"]
                body += [f"        {s}" for s in rnea_vector.sincos_lines(x, f"s{x}", f"c{x}", x)]
                body += ["    else:", f"        s{x} = sin({x})", f"        c{x} = cos({x})"]
            body.append(f"    {m[1]} = {'s' if m[2] == 'sin' else 'c'}{x}")
            continue
        line = re.sub(r"\bq\[", "y[", line)
        line = re.sub(r"\bv\[(\d+)\]", lambda g: f"y[{nv + int(g[1])}]", line)
        for i, gain in enumerate(("kp", "kd", "qf")):
            line = re.sub(rf"\b{gain}\[(\d+)\]", lambda g, i=i: f"c[{i * nv + int(g[1])}]", line)
        if pd:  # τ_k = −kd_k·q̇_k − kp_k·(q_k − qf_k), c = (kp, kd, qf)
            line = re.sub(
                r"\btau\[(\d+)\]",
                lambda g: (
                    f"(-c[{nv + int(g[1])}] * y[{nv + int(g[1])}] - c[{g[1]}] * "
                    f"(y[{g[1]}] - c[{2 * nv + int(g[1])}]))"
                ),
                line,
            )
        body.append(f"    {line}")
    args = ["y", "tau"] if "tau" in gen.inputs else ["y"]
    if pd or "kp" in gen.inputs:
        args = ["y", "c"]
    if pd:
        body += [f"    out[{k}] = y[{nv + k}]" for k in range(nv)]
    for flat, x in enumerate(gen.outputs):
        row_col = ", ".join(map(str, divmod(flat, gen.shape[-1])))
        index = str(flat + shift) if len(gen.shape) == 1 else row_col
        body.append(f"    out[{index}] = {x}")
    return "\n".join(["@jit", f"def {name}({', '.join(args)}, out):", *body, ""])


def _lanes_source(
    group: str, kernels: list[tuple[forward_source.GeneratedFunction, str, bool]]
) -> str:
    """Kernels over :data:`LANES` states at once, one lane each, in place in one work array.

    ``w`` is one flat array of rows of :data:`LANES` values (constant offsets, no call and
    no branch in the loops, so that LLVM runs the lanes side by side), shared by the
    ``kernels`` (generated function, name, efforts from rows): rows 0 … n − 1 the states
    (q, q̇), then (kp, kd, qf) (3·nv rows; with efforts from rows, τ in the first nv), the
    sine and cosine of each angle, the largest |angle|, then each kernel's results: a
    forward dynamics' n rows of ẏ (``<NAME>_OUT``), else its nv rows. ``<group>_sincos(w)``
    fills the sines and cosines (the polynomial ones) for them all; a forward dynamics
    without efforts from rows runs the PD law of the (kp, kd, qf) rows. A lane with an
    angle at or beyond the polynomials' limit (or not finite) gets NaN.
    """
    nv, L = kernels[0][0].nv, LANES
    n = 2 * nv
    trig = re.compile(r"^(t\d+) = (sin|cos)\((t\d+)\)$")
    inputs: list[dict[str, int]] = []
    for gen, _, _ in kernels:
        found = {}
        for line in gen.lines:
            m = re.match(r"^(t\d+) = q\[(\d+)\]$", line)
            if m:
                found[m[1]] = int(m[2])
        inputs.append(found)
    angles = sorted(
        {ins[m[3]] for (gen, _, _), ins in zip(kernels, inputs, strict=True)
         for line in gen.lines if (m := trig.match(line))}
    )  # fmt: skip
    row = {("y", i): i for i in range(n)}
    row.update({("c", i): n + i for i in range(3 * nv)})
    for k in angles:
        row["sin", k] = len(row)
        row["cos", k] = len(row)
    row["amax", 0] = len(row)
    for gen, name, _ in kernels:
        size = n if "tau" in gen.inputs else len(gen.outputs)
        row.update({(name, i): len(row) + i for i in range(size)})

    def at(kind: str, i: int) -> str:
        return f"w[{row[kind, i] * L} + l]"

    def pd(k: int) -> str:
        return (
            f"(-{at('c', nv + k)} * {at('y', nv + k)} - {at('c', k)} * "
            f"({at('y', k)} - {at('c', 2 * nv + k)}))"
        )

    src = ["@jit", f"def {group}_sincos(w):", f"    for l in range({L}):"]
    for k in angles:
        src += [f"        {x}" for x in rnea_vector.sincos_lines(at("y", k), "s", "c", "p")]
        src += [f"        {at('sin', k)} = s", f"        {at('cos', k)} = c"]
    biggest = ", ".join(f"abs({at('y', k)})" for k in angles)
    src.append(f"        {at('amax', 0)} = {f'max({biggest}, 0.0)' if angles else '0.0'}")
    src.append("")
    limit = repr(rnea_vector.SINCOS_LIMIT)
    constants = [f"{group.upper()}_ROWS = {len(row)}"]
    for (gen, name, tau_rows), ins in zip(kernels, inputs, strict=True):
        src += ["", "@jit", f"def {name}(w):", f"    for l in range({L}):"]
        for line in gen.lines:
            if m := trig.match(line):
                src.append(f"        {m[1]} = {at(m[2], ins[m[3]])}")
                continue
            line = re.sub(r"\bq\[(\d+)\]", lambda g: at("y", int(g[1])), line)
            line = re.sub(r"\bv\[(\d+)\]", lambda g: at("y", nv + int(g[1])), line)
            if tau_rows:
                line = re.sub(r"\btau\[(\d+)\]", lambda g: at("c", int(g[1])), line)
            else:
                line = re.sub(r"\btau\[(\d+)\]", lambda g: pd(int(g[1])), line)
            src.append(f"        {line}")
        shift = nv if "tau" in gen.inputs else 0
        if shift:
            src += [f"        {at(name, k)} = {at('y', nv + k)}" for k in range(nv)]
        for k, x in enumerate(gen.outputs):
            src.append(
                f"        {at(name, shift + k)} = {x} if {at('amax', 0)} < {limit} else math.nan"
            )
        constants.append(f"{name.upper()}_OUT = {row[name, 0]}")
    from rrt_pin.compiled._straight import lowered_part  # where a module is written

    functions = "\n".join(src).split("\n@jit\n")  # each lowered past numba's front end
    lowered = [lowered_part(f if i == 0 else f"@jit\n{f}") for i, f in enumerate(functions)]
    return "\n".join([*lowered, "", *constants, ""])


def _phys_source(
    gravity: forward_source.GeneratedFunction, free: forward_source.GeneratedFunction
) -> str:
    """``rhs_phys(y, c, P, out)``: ẏ under PD plus gravity with the physical model applied.

    One function: the angles' sines and cosines once (polynomial below their limit, libm
    beyond), G(q) (for the saturation only), the efforts u = clip(PD + G) − G + the
    ``passive`` terms, then the forward dynamics without gravity under u (M⁻¹(u + G − b)
    is the forward dynamics under the saturated law).
    """
    nv = free.nv
    body: list[str] = []
    angles: set[int] = set()

    def lines(gen: forward_source.GeneratedFunction, prefix: str) -> list[str]:
        inputs, out = {}, []
        for line in gen.lines:
            line = re.sub(r"\bt(\d+)\b", lambda g: f"{prefix}{g[1]}", line)
            if m := re.match(rf"^({prefix}\d+) = q\[(\d+)\]$", line):
                inputs[m[1]] = int(m[2])
            if m := re.match(rf"^({prefix}\d+) = (sin|cos)\(({prefix}\d+)\)$", line):
                k = inputs[m[3]]
                if k not in angles:
                    angles.add(k)
                    out += [f"    if abs(y[{k}]) < {rnea_vector.SINCOS_LIMIT!r}:"]
                    out += [f"        {x}" for x in
                            rnea_vector.sincos_lines(f"y[{k}]", f"s_{k}", f"c_{k}", f"a{k}")]  # fmt: skip
                    out += [
                        "    else:",
                        f"        s_{k} = sin(y[{k}])",
                        f"        c_{k} = cos(y[{k}])",
                    ]
                out.append(f"    {m[1]} = {'s' if m[2] == 'sin' else 'c'}_{k}")
                continue
            line = re.sub(r"\bq\[", "y[", line)
            line = re.sub(r"\bv\[(\d+)\]", lambda g: f"y[{nv + int(g[1])}]", line)
            line = re.sub(r"\btau\[(\d+)\]", lambda g: f"u_{g[1]}", line)
            out.append(f"    {line}")
        return out

    body += lines(gravity, "g")
    for k, x in enumerate(gravity.outputs):
        x = re.sub(r"\bt(\d+)\b", lambda g: f"g{g[1]}", x)
        body += [
            f"    G_{k} = {x}",
            f"    u_{k} = (-c[{nv + k}] * y[{nv + k}] - c[{k}] * (y[{k}] - c[{2 * nv + k}])) + G_{k}",
            f"    if u_{k} > P[2, {k}]:",
            f"        u_{k} = P[2, {k}]",
            f"    elif u_{k} < -P[2, {k}]:",
            f"        u_{k} = -P[2, {k}]",
            *_passive_lines(k, nv),
        ]
    body += lines(free, "f")
    body += [f"    out[{k}] = y[{nv + k}]" for k in range(nv)]
    for k, x in enumerate(free.outputs):
        x = re.sub(r"\bt(\d+)\b", lambda g: f"f{g[1]}", x)
        body.append(f"    out[{nv + k}] = {x}")
    return "\n".join(["@jit", "def rhs_phys(y, c, P, out):", *body, ""])


def _passive_lines(k: int, nv: int) -> list[str]:
    """``u_k = (u_k − G_k) + passive(y, P, k)`` with the template's ``losses`` written out."""
    q, v = f"y[{k}]", f"y[{nv + k}]"
    lower, upper, damping, friction, stiffness, limit_damping = (
        f"P[{r}, {k}]" for r in (0, 1, 3, 4, 5, 6)
    )
    return [
        f"    p_{k} = -{damping} * {v}",
        f"    if {friction} != 0.0:",
        f"        p_{k} -= {friction} * tanh({v} / {limits.FRICTION_VELOCITY!r})",
        f"    if {q} < {lower}:",
        f"        x_{k} = {stiffness} * ({lower} - {q}) - {limit_damping} * {v}",
        f"        p_{k} += x_{k} if x_{k} > 0.0 else 0.0",
        f"    elif {q} > {upper}:",
        f"        x_{k} = {stiffness} * ({upper} - {q}) - {limit_damping} * {v}",
        f"        p_{k} += x_{k} if x_{k} < 0.0 else 0.0",
        f"    u_{k} = (u_{k} - G_{k}) + p_{k}",
    ]


def module_source(model: pin.Model) -> tuple[str, int]:
    """(the module's source, flops of one forward-dynamics evaluation) for ``model``.

    ``rhs_pd`` is ẏ with the forward dynamics without gravity: under PD plus the robot's
    own G(q), τ − b = τ_PD − C(q, q̇)·q̇, so one evaluation without gravity serves the
    dynamics and the compensation (G is then computed at the output times only).
    """
    import pinocchio as pin

    from rrt_pin.compiled._straight import lowered_part  # where a module is written, not at import

    free = pin.Model(model)
    free.gravity = pin.Motion.Zero()
    nv = int(model.nv)
    # The variant with fewer operations (on UR5 CRBA + LDLᵀ, 1,077 against ABA's 1,490
    # without gravity; on Panda ABA): their rounding differs by ~1e-13 relative, far
    # below any tolerance of an integration.
    fwd, fwd_free = (
        min((forward_source.forward_source(m, v) for v in ("aba", "crba")), key=attrgetter("flops"))
        for m in (model, free)
    )
    parts = [
        _on_state(fwd, "forward", nv),
        _on_state(fwd_free, "rhs_pd", nv, pd=True),
        _on_state(fwd_free, "forward_free", nv),
        _phys_source(forward_source.gravity_source(model), fwd_free),
        _on_state(forward_source.gravity_source(model), "gravity", 0),
        _on_state(forward_source.mass_matrix_source(model), "mass_matrix", 0),
        _on_state(forward_source.bias_source(model), "bias", 0),
        _on_state(closed_loop_derivatives_source(model), "closed_loop_jac", 0),
    ]
    parts = [lowered_part(part) for part in parts]
    template = _TEMPLATE.read_text(encoding="utf-8")
    head, mark, body = template.partition(_MARK)
    if not mark:  # pragma: no cover - the template's own marker
        raise RuntimeError(f"{_TEMPLATE} lost its line {_MARK.strip()!r}")
    body += robot_entries.copies(body, robot_entries.PD_COPIES)
    body += robot_entries.copies(body, robot_entries.RKC_COPIES)  # adaptive_rkc(_pd)
    for method in ("adaptive", "adaptive_rkc", "adams", "bdf", "bdf_num"):  # no fixed step
        general, pd = {"fixed": "no_fixed"}, {"fixed_pd": "no_fixed"}
        if method != "adaptive":
            general, pd = general | {"adaptive": method}, pd | {"adaptive_pd": f"{method}_pd"}
        body += robot_entries.law_bound(body, "run_many", general, f"run_{method}")
        body += robot_entries.law_bound(body, "run_many_pd", pd, f"run_{method}_pd")
    files = (_TEMPLATE.with_name(f"_robot_{p}.py").read_text(encoding="utf-8") for p in _PARTS)
    rkc, adams, bdf = (
        text.partition(f"# --- {p} ---\n")[2] for text, p in zip(files, _PARTS, strict=True)
    )
    lines = [
        f'"""Generated by rrt_pin.compiled.robot_code (nv={nv}): do not edit."""',
        "",
        "import math",
        "from math import cos, sin, tanh",
        "",
        "import numba",
        "import numpy as np",
        "",
        "from rrt_pin.compiled import _dop853_coefficients as dop",
        "from rrt_pin.compiled._straight import lowered",
        "",
        "",
        "def jit(f):",
        '    return numba.njit(cache=True, nogil=True, error_model="numpy")(f)',
        "",
        "",
        "def jit_inline(f):  # a few operations: inlined into every caller",
        '    return numba.njit(cache=True, nogil=True, error_model="numpy", inline="always")(f)',
        "",
        "",
        *(f"{c} = {getattr(codes, c)}" for c in _CODES),
        f"FRICTION_VELOCITY = {limits.FRICTION_VELOCITY!r}",
        "",
        "",
        *(part + "\n" for part in parts),
        body,
        rkc + robot_entries.copies(rkc, robot_entries.PD_COPIES_RKC),
        "",
        f"LANE_COUNT = {LANES}",
        _lanes_source(
            "phys",
            [
                (forward_source.gravity_source(model), "gravity_lanes", False),
                (fwd_free, "free_lanes", True),
            ],
        ),  # fmt: skip
        robot_entries.lanes(_LANES.read_text(encoding="utf-8").partition(_LANES_MARK)[2]),
        adams + robot_entries.copies(adams, robot_entries.PD_COPIES_ADAMS),
        bdf
        + robot_entries.copies(bdf, robot_entries.PD_COPIES_BDF)
        + robot_entries.copies(bdf, robot_entries.NUMERIC_COPIES_BDF),
    ]
    return "\n".join(lines), fwd.flops


def _load(source: str, digest: str, name: str, nv: int, flops: int) -> RobotCode:
    """Write and import the module (or, without a writable cache, execute it in memory)."""
    try:
        import numba  # noqa: F401
    except ImportError as e:
        backends.get("compiled").require(e)
        raise  # not reached: require raises
    module_name = f"rrt_pin_robot_{digest[:24]}"
    where = rnea.generated_dir()
    path = where / f"{module_name.removeprefix('rrt_pin_')}.py" if where is not None else None
    if path is not None and rnea._write(path, source):
        try:
            return RobotCode(name, nv, flops, rnea._import(path, module_name), path, source)
        except Exception as exc:  # an unreadable module: compile in memory
            from rrt_pin.compiled._cache import warn_once

            warn_once(
                f"generated integrators cache {path.parent}: {type(exc).__name__}: {exc}"[:300]
            )
    return RobotCode(name, nv, flops, _in_memory(source), None, source)


def _in_memory(source: str) -> types.ModuleType:
    """The generated module executed in memory, nothing cached on disk."""
    digest = hashlib.sha256(source.encode()).hexdigest()
    namespace = types.ModuleType(f"rrt_pin_robot_{digest[:24]}")
    text = source.replace("cache=True", "cache=False")
    exec(compile(text, f"<{namespace.__name__}>", "exec"), namespace.__dict__)  # noqa: S102
    return namespace


def _estimate(flops: float) -> float:
    return _COMPILE_S + _COMPILE_S_PER_FLOP * flops


def integrators_for(model: pin.Model, name: str | None = None) -> RobotCode:
    """The compiled integrators of ``model`` (generated, written, loaded or compiled once).

    A model seen before and unchanged (compared with a copy kept) costs a look-up and
    a model comparison.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
        MissingExtra: numba is not installed.
    """
    entry = _MODELS.get(model)
    if entry is not None and bool(entry[0] == model):
        return entry[1]
    import pinocchio as pin

    check_supported(model)
    label = name or str(model.name) or "the model"
    source, flops = module_source(model)
    digest = hashlib.sha256(source.encode()).hexdigest()
    with _lock:
        code = _CODE.get(digest)
        if code is None:
            code = _CODE[digest] = _load(source, digest, label, int(model.nv), flops)
    _models.remember("robot", model, {"digest": digest})
    _MODELS.put(model, value=(pin.Model(model), code))
    return code


def state(
    model: pin.Model,
    batch: bool = False,
    code: int | None = None,
    pd: bool = False,
    numeric: bool | None = False,
) -> tuple[bool, bool, bool]:
    """(loaded in this process, built ahead of time, ready without compiling): ``model``'s integrators.

    The entry a job of method ``code`` runs (:func:`rrt_pin.compiled.robot_entries.entry`;
    ``pd``: its laws are all PD plus gravity; ``numeric``: BDF's Jacobian is numerical for
    every variant, None if not known: then either entry may run, and both must be built;
    a batch's may also run in lanes). Cheap: no numba import, no source generated (the
    index of :mod:`rrt_pin.compiled._models`). Integrators are never built ahead of time.
    """
    groups = robot_entries.pd_entries(code, batch, pd, numeric)
    found = _MODELS.get(model)
    if found is not None and bool(found[0] == model):
        loaded = found[1]._entries
        if all(any(e in loaded for e in group) for group in groups):
            return True, False, True
    record = _models.recall("robot", model)
    where = rnea.generated_dir()
    if record is None or where is None:
        return False, False, False
    stem = f"robot_{record['digest'][:24]}"
    built = all(
        any((where / f"{stem}.{e}.cache.json").is_file() for e in group) for group in groups
    )
    return False, False, built
