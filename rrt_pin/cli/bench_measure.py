"""The measurements of ``rrt-pin bench``: timed runs against references, as rows.

Pure functions return rows of :class:`BenchRow` (times are medians of repeated runs
[s]; errors are max |q − q_ref| over the chapter's run [rad or m] for the direct
dynamics, and max relative effort error for the inverse dynamics);
:mod:`rrt_pin.cli.bench_report` writes and summarises them.
"""

from __future__ import annotations

import statistics
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import astuple, dataclass, fields
from pathlib import Path
from typing import TextIO

import numpy as np

from rrt_pin.cli.flops import KernelRow
from rrt_pin.core import backends as registry
from rrt_pin.core.errors import RrtPinError
from rrt_pin.core.grid import time_grid
from rrt_pin.core.text import duration
from rrt_pin.dynamics import kernel
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.kernel import PARAM_ORDER
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.io.files import (
    atomic_write_text,
)
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import chapter_controller
from rrt_pin.simulate.methods import METHODS, names
from rrt_pin.simulate.methods import get as method_named
from rrt_pin.simulate.symplectic import mechanical_energy

__all__ = [
    "BenchRow",
    "Progress",
    "direct_work_precision",
    "energy_drift",
    "inverse_backends",
    "median_time",
    "mpmath_inverse_reference",
    "pareto_front",
    "rows_csv",
    "write_rows",
]


@dataclass(frozen=True)
class BenchRow:
    """One measured configuration.

    Attributes:
        backend: ``pinocchio``, ``symbolic``, ``compiled`` (or ``pinocchio-loop`` …).
        method: integrator or algorithm name.
        setting: tolerance (``rtol=1e-08``) or step (``dt=0.001``) as text.
        time_s: median wall time of one run [s].
        n_evals: dynamics evaluations per run (0 where not counted).
        max_error: max |q − q_ref| [rad, m] (direct) or max relative effort
            error (inverse).
    """

    backend: str
    method: str
    setting: str
    time_s: float
    n_evals: int
    max_error: float

    @staticmethod
    def header() -> list[str]:
        """Column names, in order."""
        return [f.name for f in fields(BenchRow)]

    def values(self) -> tuple:
        """The row's values, in header order."""
        return astuple(self)


class Progress:
    """A counter on stderr: ``[ 3/40] DOP853 rtol=1e-08``; rewrites one line on a TTY."""

    def __init__(self, total: int, stream: TextIO | None = None, enabled: bool = True) -> None:
        self.total = total
        self.done = 0
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled
        self.tty = bool(getattr(self.stream, "isatty", lambda: False)())

    def step(self, label: str) -> None:
        """Count one item done and show its label."""
        self.done += 1
        if not self.enabled:
            return
        width = len(str(self.total))
        line = f"[{self.done:>{width}}/{self.total}] {label}"
        if self.tty:
            self.stream.write("\r\033[K" + line + ("\n" if self.done >= self.total else ""))
        else:
            self.stream.write(line + "\n")
        self.stream.flush()


def median_time(
    fn: Callable[[], object], repeats: int, min_total: float = 0.0, max_repeats: int = 500
) -> tuple[float, object]:
    """Median wall time of repeated calls of ``fn`` [s], and the last result.

    Calls ``fn`` at least ``repeats`` times, and more (up to ``max_repeats``)
    until the calls add up to ``min_total`` seconds, so that sub-millisecond
    runs get enough samples for a stable median.
    """
    times: list[float] = []
    result = None
    while len(times) < max(1, repeats) or (sum(times) < min_total and len(times) < max_repeats):
        t0 = time.perf_counter()
        result = fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times), result


def pareto_front(times: Sequence[float], errors: Sequence[float]) -> np.ndarray:
    """Mask of the points no other point beats in both time and error.

    A point is dominated when another is at least as fast and at least as
    accurate, and strictly better in one of the two.
    """
    t = np.asarray(times, dtype=float)
    e = np.asarray(errors, dtype=float)
    keep = np.ones(t.size, dtype=bool)
    for i in range(t.size):
        better = (t <= t[i]) & (e <= e[i]) & ((t < t[i]) | (e < e[i]))
        keep[i] = not better.any()
    return keep


def mpmath_inverse_reference(
    q: np.ndarray, qd: np.ndarray, qdd: np.ndarray, params, digits: int = 30
) -> np.ndarray:
    """Efforts τ = M(q)·q̈ − f(q, q̇, 0) in ``digits``-digit arithmetic.

    Evaluates Lagrange's equations from :mod:`rrt_pin.dynamics.symbolic` (sympy +
    mpmath, imported here only) at the given float64 states, so that a
    backend's error excludes the rounding of its inputs. Returns float64
    (N, 3) [N·m, N·m, N].
    """
    import mpmath
    import sympy as sp

    from rrt_pin.dynamics.symbolic import equations_of_motion

    eom = equations_of_motion("lagrange")
    zero = {u: 0 for u in eom.efforts}
    tau_expr = eom.mass_matrix * sp.Matrix(eom.qdd) - eom.forcing.subs(zero)
    args = (*eom.q, *eom.qd, *eom.qdd, *eom.parameters)
    fn = sp.lambdify(args, list(tau_expr), modules="mpmath", cse=True)

    out = np.empty((len(q), 3))
    with mpmath.workdps(digits):
        pv = [mpmath.mpf(getattr(params, n)) for n in PARAM_ORDER]
        for i in range(len(q)):
            state = [mpmath.mpf(float(x)) for x in (*q[i], *qd[i], *qdd[i])]
            out[i] = [float(v) for v in fn(*state, *pv)]
    return out


def _relative_error(tau: np.ndarray, ref: np.ndarray) -> float:
    scale = np.abs(ref).max(axis=0)
    return float((np.abs(tau - ref) / scale).max())


def inverse_backends(
    params=None,
    dt: float = 1e-3,
    repeats: int = 5,
    reference_stride: int = 1,
    progress: Progress | None = None,
) -> list[BenchRow]:
    """Time each inverse-dynamics backend on the chapter's trajectory (eq. 30).

    Backends: a Python loop over ``pin.rnea``, the batched Pinocchio path, the
    generated numpy kernel, and the compiled kernel when numba is available.
    The error is the max over joints of max_t |τ − τ_ref| / max_t |τ_ref|,
    against :func:`mpmath_inverse_reference` at every ``reference_stride``-th
    sample.
    """
    import pinocchio as pin

    p = params if params is not None else Params()
    arm = chapter_arm(p)
    model = arm.model
    traj = rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, dt))
    q, qd, qdd = traj.q, traj.qd, traj.qdd
    sel = slice(None, None, reference_stride)
    ref = mpmath_inverse_reference(q[sel], qd[sel], qdd[sel], p)

    def loop() -> np.ndarray:
        data = model.createData()
        return np.array(
            [pin.rnea(model, data, a, b, c) for a, b, c in zip(q, qd, qdd, strict=True)]
        )

    candidates: list[tuple[str, str, Callable[[], np.ndarray]]] = [
        ("pinocchio", "rnea-loop", loop),
        ("pinocchio", "rnea-batch", lambda: inverse_dynamics(arm, q, qd, qdd, backend="pinocchio")),
        ("symbolic", "numpy-kernel", lambda: kernel.inverse_dynamics(q, qd, qdd, p)),
    ]
    try:
        from rrt_pin import compiled

        if getattr(compiled, "available", lambda: False)():
            compiled.inverse_dynamics(
                q[:2], qd[:2], qdd[:2], p
            )  # compile (or load the cache) first
            candidates.append(
                ("compiled", "numba-kernel", lambda: compiled.inverse_dynamics(q, qd, qdd, p))
            )
    except ImportError:
        pass
    if progress is not None:
        progress.total += len(candidates)
    rows = []
    for backend, method, fn in candidates:
        t, tau = median_time(fn, repeats, min_total=0.05 * repeats)
        rows.append(
            BenchRow(
                backend,
                method,
                f"N={len(q)}",
                t,
                len(q),
                _relative_error(np.asarray(tau)[sel], ref),
            )
        )
        if progress is not None:
            progress.step(f"inverse {backend} {method}: {duration(t)}")
    return rows


def rows_csv(rows: Iterable[BenchRow | KernelRow], kind: type = BenchRow) -> str:
    """Rows of one ``kind`` as CSV text under its header (numbers to 6 digits).

    A text with a comma or a quote is quoted, as the csv module does.
    """
    import csv
    import io

    text = io.StringIO()
    writer = csv.writer(text, lineterminator="\n")
    writer.writerow(kind.header())
    for r in rows:
        writer.writerow(f"{v:.6g}" if isinstance(v, float) else str(v) for v in r.values())
    return text.getvalue()


def write_rows(path: str | Path, rows: Iterable[BenchRow]) -> Path:
    """Write rows as CSV (:func:`rows_csv`) atomically."""
    return atomic_write_text(path, rows_csv(rows))


#: Tolerances of the adaptive methods (atol = rtol / 100) and steps of the fixed-step ones.
RTOLS = (1e-4, 1e-6, 1e-8, 1e-10, 1e-12)
STEPS = (1e-2, 5e-3, 2e-3, 1e-3, 5e-4)
QUICK_RTOLS = (1e-6, 1e-9, 1e-12)
QUICK_STEPS = (1e-2, 2e-3)
#: Shortest burst of repeated calls timed as one sample [s].
BURST = 0.005


def _settings(method: str, quick: bool) -> list[tuple[str, dict]]:

    ADAPTIVE_METHODS = names(adaptive=True)

    if method in ADAPTIVE_METHODS:
        return [
            (f"rtol={r:.0e}", {"rtol": r, "atol": r * 1e-2})
            for r in (QUICK_RTOLS if quick else RTOLS)
        ]
    return [(f"dt={h:g}", {"step": h}) for h in (QUICK_STEPS if quick else STEPS)]


def direct_work_precision(
    params=None,
    quick: bool = False,
    repeats: int = 5,
    backends: Sequence[str] = ("pinocchio", "compiled"),
    progress: Progress | None = None,
) -> tuple[list[BenchRow], list[BenchRow], float]:
    """Every method of ``simulate`` × tolerances or steps, on the chapter's run (0..15 s, 1,501 outputs).

    Returns:
        The rows; the rows of ``simulate``'s default settings for each backend
        (measured the same way); and the disagreement of the reference's two
        methods [rad, m].
    """
    from rrt_pin.simulate.reference import chapter_reference

    p = params if params is not None else Params()
    arm = chapter_arm(p)
    ctrl = chapter_controller(p)
    t = time_grid(15.0, 0.01)
    ref = chapter_reference(p, tf=15.0, dt=0.01)
    have_compiled = False
    compiled_methods: tuple[str, ...] = ()
    if "compiled" in backends:
        try:
            from rrt_pin import compiled

            have_compiled = compiled.available()
            compiled_methods = tuple(  # the arm's kernel: not the generated robots' own methods
                m for m in names("compiled") if compiled.refusal(arm, [ctrl], None, m) is None
            )
        except ImportError:
            have_compiled = False
    plan: list[tuple[str, str, str, dict]] = []
    for backend in backends:
        if backend == "compiled" and not have_compiled:
            continue
        for method in METHODS:
            if not METHODS[method].runs_on(backend) or (
                backend == "compiled" and method not in compiled_methods
            ):
                continue  # not on this backend; on compiled, the arm's kernel's methods only
            for setting, kw in _settings(method, quick):
                plan.append((backend, method, setting, kw))

    for backend in backends:
        if backend == "compiled" and not have_compiled:
            continue
        default = method_named(registry.get(backend).default_method)
        kw = {"rtol": default.rtol, "atol": default.atol}
        plan.append((backend, default.name, f"default rtol={default.rtol:.0e}", kw))
    rounds = max(1, repeats)
    if progress is not None:
        progress.total += len(plan) + rounds

    def runner(backend: str, method: str, kw: dict) -> Callable[[], object]:
        return lambda: simulate(
            arm, ctrl, p.q0, p.qd0, t, method=method, backend=backend, estimate_error=False,
            **kw
        )  # fmt: skip

    runner("pinocchio", "RK45", {"rtol": 1e-3, "atol": 1e-5})()  # warm imports and caches
    # One run of each configuration first: its cost and error (both deterministic), and
    # compilation or cache loading out of the way. Then rounds that time every
    # configuration once each, so that slow drifts of the machine hit all of them alike;
    # sub-millisecond runs are timed in bursts of at least BURST seconds.
    first: dict[int, tuple[float, int, float]] = {}
    for i, (backend, method, setting, kw) in enumerate(plan):
        try:
            t0 = time.perf_counter()
            res = runner(backend, method, kw)()
            first[i] = (
                time.perf_counter() - t0,
                int(res.n_evals),
                float(np.abs(res.q - ref.q).max()),
            )
        except RrtPinError:  # a failing configuration is a result too
            pass
        if progress is not None:
            err = first[i][2] if i in first else float("inf")
            progress.step(f"direct {backend} {method} {setting}: error {err:.2g}")
    times: dict[int, list[float]] = {i: [] for i in first}
    for k in range(rounds):
        for i in first:
            backend, method, _, kw = plan[i]
            fn = runner(backend, method, kw)
            burst = max(1, min(200, int(BURST / max(first[i][0], 1e-6))))
            t0 = time.perf_counter()
            for _ in range(burst):
                fn()
            times[i].append((time.perf_counter() - t0) / burst)
        if progress is not None:
            progress.step(f"direct timing round {k + 1}/{rounds}")
    rows, defaults = [], []
    for i, (backend, method, setting, _) in enumerate(plan):
        if i in first:
            _, n_evals, err = first[i]
            row = BenchRow(backend, method, setting, statistics.median(times[i]), n_evals, err)
        else:
            row = BenchRow(backend, method, setting, float("nan"), 0, float("inf"))
        (defaults if setting.startswith("default") else rows).append(row)
    return rows, defaults, ref.difference_q


def energy_drift(
    params=None,
    tf: float = 100.0,
    quick: bool = False,
    progress: Progress | None = None,
) -> list[BenchRow]:
    """Energy drift of passive motion (τ = 0, gravity on) from the chapter's q(0), per method.

    ``max_error`` is max_t |E(t) − E(0)| / max_t T(t) (dimensionless), with E = T + V
    sampled every second; ``setting`` is the tolerance or step used.
    """
    p = params if params is not None else Params()
    arm = chapter_arm(p)
    model = arm.model
    t = time_grid(tf, 1.0)
    zero = np.zeros(3)

    def passive(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        return zero.copy()

    def kinetic(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
        import pinocchio as pin

        data = model.createData()
        return np.array(
            [pin.computeKineticEnergy(model, data, a, b) for a, b in zip(q, qd, strict=True)]
        )

    runs: list[tuple[str, str, Callable[[], tuple[np.ndarray, np.ndarray, int]]]] = []
    for method, rtol in (("DOP853", 1e-12), ("RK45", 1e-10), ("odepack", 1e-12), ("Radau", 1e-10)):

        def run(method=method, rtol=rtol):
            r = simulate(arm, passive, p.q0, p.qd0, t, method=method, rtol=rtol, atol=rtol * 1e-2,
                         backend="pinocchio", estimate_error=False)  # fmt: skip
            return r.q, r.qd, r.n_evals

        runs.append((method, f"rtol={rtol:.0e}", run))
    h = 0.01 if quick else 0.005
    for method in ("rk4", "verlet", "symplectic_euler", "leapfrog"):

        def run(method=method):
            r = simulate(arm, passive, p.q0, p.qd0, t, method=method, step=h,
                         backend="pinocchio", estimate_error=False)  # fmt: skip
            return r.q, r.qd, r.n_evals

        runs.append((method, f"dt={h:g}", run))

    if progress is not None:
        progress.total += len(runs)
    rows = []
    for method, setting, run in runs:
        t0 = time.perf_counter()
        q, qd, n = run()
        elapsed = time.perf_counter() - t0
        E = mechanical_energy(model, q, qd)
        drift = float(np.abs(E - E[0]).max() / kinetic(q, qd).max())
        rows.append(BenchRow("pinocchio", method, setting, elapsed, int(n), drift))
        if progress is not None:
            progress.step(f"energy {method} {setting}: relative drift {drift:.2g}")
    return rows
