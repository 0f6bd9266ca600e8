"""Evidence of speed and accuracy: work-precision and inverse-dynamics benchmarks.

The rows come from :mod:`rrt_pin.cli.bench_measure` (offered here too);
:func:`run_bench` writes them (CSV + PNG) and is what ``rrt-pin bench`` calls. Times are medians of repeated
runs [s]; errors are max |q − q_ref| over the chapter's run [rad or m] for the
direct dynamics, and max relative effort error for the inverse dynamics.
"""

from __future__ import annotations

import contextlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rrt_pin.cli import bench_measure
from rrt_pin.cli.bench_measure import (
    BenchRow,
    Progress,
    direct_work_precision,
    energy_drift,
    inverse_backends,
    pareto_front,
    rows_csv,
)
from rrt_pin.cli.flops import KernelRow
from rrt_pin.core.text import argument, duration
from rrt_pin.io.files import (
    OutputError,
    atomic_write_bytes,
    check_outputs,
    write_outputs,
)

__all__ = [
    "BenchReport",
    "kernel_table",
    "plot_work_precision",
    "run_bench",
    "summary",
    "work_precision_png",
]


def plot_work_precision(
    path: str | Path, rows: Sequence[BenchRow], defaults: Sequence[BenchRow] = ()
) -> Path:
    """Write :func:`work_precision_png` to ``path`` atomically."""
    return atomic_write_bytes(path, work_precision_png(rows, defaults))


def work_precision_png(rows: Sequence[BenchRow], defaults: Sequence[BenchRow] = ()) -> bytes:
    """Log-log plot of max |q error| [rad, m] against median time [s], Pareto front drawn (PNG)."""
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if np.isfinite(r.time_s) and np.isfinite(r.max_error) and r.max_error > 0]
    fig, ax = plt.subplots(figsize=(12, 6.5))
    groups: dict[tuple[str, str], list[BenchRow]] = {}
    for r in ok:
        groups.setdefault((r.backend, r.method), []).append(r)
    methods = sorted({m for _, m in groups})
    colours = {m: plt.get_cmap("tab10")(i % 10) for i, m in enumerate(methods)}
    markers = {m: "os^vD<>ph*X"[i % 11] for i, m in enumerate(methods)}
    for (backend, method), rs in sorted(groups.items()):
        rs = sorted(rs, key=lambda r: r.time_s)
        ax.plot(
            [r.time_s for r in rs],
            [r.max_error for r in rs],
            "-" if backend == "pinocchio" else "--",
            color=colours[method],
            marker=markers[method],
            markerfacecolor=colours[method] if backend == "pinocchio" else "white",
            label=f"{method} ({backend})",
            alpha=0.85,
        )

    def draw_front(subset: list[BenchRow], **style: object) -> None:
        keep = pareto_front([r.time_s for r in subset], [r.max_error for r in subset])
        front = sorted((r for r, k in zip(subset, keep, strict=True) if k), key=lambda r: r.time_s)
        if front:
            ax.step([r.time_s for r in front], [r.max_error for r in front], where="post", **style)

    every = [*ok, *defaults]
    draw_front(every, color="k", linewidth=3, alpha=0.3, label="Pareto front, all")
    draw_front(
        [r for r in every if r.backend == "pinocchio"],
        color="k",
        linewidth=1.2,
        linestyle=":",
        label="Pareto front, pinocchio",
    )
    for d, colour in zip(defaults, ("k", "r"), strict=False):
        ax.plot(
            [d.time_s],
            [d.max_error],
            "*",
            color=colour,
            markersize=18,
            markeredgecolor="white",
            label=f"simulate() default, {d.backend} ({d.method})",
        )
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("median wall time of one 15 s run [s]")
    ax.set_ylabel("max |q − q_ref| over 0..15 s [rad, m]")
    ax.set_title("Work–precision of the chapter's direct dynamics (eq. 31)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    fig.tight_layout()
    try:
        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=110)
        return buffer.getvalue()
    finally:
        plt.close(fig)


def _remove_empty(folder: Path) -> None:
    """Remove ``folder`` (which this run created) when nothing was written into it."""
    with contextlib.suppress(OSError):
        folder.rmdir()


@dataclass(frozen=True)
class BenchReport:
    """What :func:`run_bench` measured and wrote.

    Attributes:
        direct: work-precision rows of the direct dynamics.
        defaults: the rows of ``simulate``'s default settings, one per backend.
        on_backend_front: for each default, whether it lies on the Pareto front
            of its own backend's rows.
        on_front: for each default, whether it lies on the Pareto front of all rows.
        reference_disagreement: max |q_DOP853 − q_Radau| of the reference at rtol 1e-13 [rad, m].
        inverse: rows of the inverse-dynamics backends.
        energy: energy-drift rows of passive motion.
        files: the files written.
        kernels: each kernel's ns/sample against the machine's FMA limit.
    """

    direct: tuple[BenchRow, ...]
    defaults: tuple[BenchRow, ...]
    on_backend_front: tuple[bool, ...]
    on_front: tuple[bool, ...]
    reference_disagreement: float
    inverse: tuple[BenchRow, ...]
    energy: tuple[BenchRow, ...]
    files: tuple[Path, ...]
    kernels: tuple[KernelRow, ...] = ()


def run_bench(
    out: str | Path, quick: bool = False, progress: Progress | None = None
) -> BenchReport:
    """Run every benchmark and write its CSV files and plot into ``out``.

    Writes ``work_precision.csv``, ``work_precision.png``, ``inverse.csv``,
    ``energy_drift.csv`` and ``kernels.csv`` (each closed-form kernel's ns/sample,
    flops and fraction of the machine's FMA limit, :mod:`rrt_pin.cli.flops`), all or
    none (one transaction of :mod:`rrt_pin.io.files`);
    ``out`` is created if missing, and checked before any benchmark runs.

    Raises:
        OutputError: ``out`` cannot be created or written (read-only, a file, a
            name too long), or the disk fills up while writing; nothing is left.
    """
    out = Path(out)
    names = (
        "work_precision.csv",
        "work_precision.png",
        "inverse.csv",
        "energy_drift.csv",
        "kernels.csv",
    )
    created = not out.exists()
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise OutputError(
            f"cannot create {argument('out')} folder {str(out)!r}: {e.strerror or e}"
        ) from None
    try:
        check_outputs([(out / name, "--out") for name in names])
    except OutputError:
        if created:
            _remove_empty(out)
        raise
    progress = progress if progress is not None else Progress(0, enabled=False)
    repeats = 1 if quick else 5
    direct, defaults, disagreement = direct_work_precision(
        quick=quick, repeats=repeats, progress=progress
    )
    every = [*direct, *defaults]
    on_backend = tuple(_on_front(d, [r for r in every if r.backend == d.backend]) for d in defaults)
    on_all = tuple(_on_front(d, every) for d in defaults)
    inverse = inverse_backends(
        repeats=3 if quick else 7, reference_stride=10 if quick else 1, progress=progress
    )
    energy = energy_drift(tf=30.0 if quick else 100.0, quick=quick, progress=progress)
    kernels = kernel_table(inverse, quick)
    contents = (
        rows_csv(every).encode(),
        work_precision_png(direct, defaults),
        rows_csv(inverse).encode(),
        rows_csv(energy).encode(),
        rows_csv(kernels, KernelRow).encode(),
    )
    try:
        files = tuple(
            write_outputs(
                [
                    (out / name, "--out", lambda fh, data=data: fh.write(data))
                    for name, data in zip(names, contents, strict=True)
                ]
            )  # fmt: skip
        )
    except OutputError:
        if created:
            _remove_empty(out)
        raise
    return BenchReport(
        tuple(direct),
        tuple(defaults),
        on_backend,
        on_all,
        disagreement,
        tuple(inverse),
        tuple(energy),
        files,
        tuple(kernels),
    )


def kernel_table(inverse: Sequence[BenchRow], quick: bool = False) -> list[KernelRow]:
    """ns/sample of the inverse backends and other kernels, against the FMA limit.

    The kernels: each inverse backend, the compiled closed loop and the RNEA generated
    for other robots (UR5 and Panda; UR5 only with ``quick``). The inverse rows' times are divided by their sample counts; the closed loop
    (the direct run's right-hand side) and the generated kernels are timed here.
    """
    from rrt_pin.cli import flops

    names = {
        ("pinocchio", "rnea-loop"): "pinocchio rnea loop",
        ("pinocchio", "rnea-batch"): "pinocchio rnea batched",
        ("symbolic", "numpy-kernel"): "symbolic inverse",
        ("compiled", "numba-kernel"): "compiled inverse",
    }
    ns = {
        names.get((r.backend, r.method), f"{r.backend} {r.method}"): 1e9 * r.time_s / r.n_evals
        for r in inverse
        if r.n_evals
    }
    loop = flops.closed_loop_ns(repeats=3 if quick else 7)
    if loop is not None:
        ns["compiled closed loop (per state)"] = loop
    generated, counts = flops.generated_kernels(
        flops.GENERATED_ROBOTS[:1] if quick else flops.GENERATED_ROBOTS, repeats=3 if quick else 7
    )
    ns.update(generated)
    return flops.kernel_rows(ns, flops.fma_rate(0.1 if quick else 0.3), counts)


def _on_front(row: BenchRow, rows: Sequence[BenchRow]) -> bool:
    """Whether ``row`` (one of ``rows``) lies on their Pareto front.

    Rows that repeat ``row``'s configuration (same backend and method, same
    evaluations and error: the grid may contain the default's settings) are
    left out, so that timing noise between two runs of one configuration
    cannot push it off the front.
    """
    others = [
        r
        for r in rows
        if r is row
        or (r.backend, r.method, r.n_evals, r.max_error)
        != (row.backend, row.method, row.n_evals, row.max_error)
    ]
    times = [r.time_s if np.isfinite(r.time_s) else np.inf for r in others]
    mask = pareto_front(times, [r.max_error for r in others])
    return bool(mask[[i for i, r in enumerate(others) if r is row][0]])


def summary(report: BenchReport) -> str:
    """A few lines for the terminal."""
    fastest_8 = min(
        (r for r in report.direct if r.max_error <= 1e-8 and np.isfinite(r.time_s)),
        key=lambda r: r.time_s,
        default=None,
    )
    lines = [
        f"reference: DOP853 vs Radau at rtol 1e-13 disagree by {report.reference_disagreement:.2g}",
    ]
    for d, mine, every in zip(
        report.defaults, report.on_backend_front, report.on_front, strict=True
    ):
        lines.append(
            f"simulate() default, backend {d.backend} ({d.method}, {d.setting}): "
            f"{duration(d.time_s)}, max |q error| {d.max_error:.2g}; "
            f"{'on' if mine else 'NOT on'} the {d.backend} Pareto front, "
            f"{'on' if every else 'NOT on'} the overall front"
        )
    if fastest_8 is not None:
        lines.append(
            f"fastest at ≤ 1e-8: {fastest_8.method} ({fastest_8.backend}, {fastest_8.setting}) "
            f"{duration(fastest_8.time_s)}"
        )
    base = next((r for r in report.inverse if r.method == "rnea-loop"), None)
    for r in report.inverse:
        ratio = f", {base.time_s / r.time_s:.1f}× the loop" if base else ""
        lines.append(
            f"inverse {r.backend}/{r.method}: {duration(r.time_s)}, rel. error {r.max_error:.2g}{ratio}"
        )
    for r in report.energy:
        lines.append(f"energy drift {r.method} ({r.setting}): {r.max_error:.2g} of max T")
    for k in report.kernels:
        if k.flops:
            lines.append(
                f"kernel {k.kernel}: {k.ns_per_sample:.1f} ns/sample, {k.flops} flops = "
                f"{k.gflops:.1f} Gflop/s, {k.fraction:.0%} of the FMA limit "
                f"({k.fma_gflops:.0f} Gflop/s on one core)"
            )
    lines.append("wrote " + ", ".join(str(f) for f in report.files))
    return "\n".join(lines)


def __getattr__(name: str) -> object:
    """The measurements' names, as the 0.3 module ``rrt_pin.bench`` offered them."""
    if name in bench_measure.__all__:
        return getattr(bench_measure, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
