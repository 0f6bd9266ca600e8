"""A picture of one sweep metric over the varied values: a line over one, a heat map over two."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from rrt_pin.core import text
from rrt_pin.core.errors import InputError
from rrt_pin.core.text import argument
from rrt_pin.io.files import atomic_write_bytes
from rrt_pin.sweeps.spec import TEXT_COLUMNS

__all__ = ["check_metric", "plot_metric"]

#: Bins of a random axis.
BINS = 24


def _bins(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(bin index per row, bin centres): each grid value its own bin; random axes in BINS."""
    unique = np.unique(values)
    if unique.size <= BINS:
        return np.searchsorted(unique, values), unique
    edges = np.linspace(values.min(), values.max(), BINS + 1)
    index = np.clip(np.searchsorted(edges, values, side="right") - 1, 0, BINS - 1)
    return index, 0.5 * (edges[1:] + edges[:-1])


def check_metric(spec: Any, metric: str) -> None:
    """Refuse, before a sweep runs, a ``--plot`` metric its chunks will not have.

    Args:
        spec: the sweep's spec (a Spec, its dict or a TOML file's path).
        metric: a metric column of numbers (``final_error_q3``, ``diverged`` …).

    Raises:
        InputError: no such metric column, or a column of text.
        SpecError: the spec itself is bad (as the sweep would say).
    """
    from rrt_pin.sweeps.compute import metric_names, plan
    from rrt_pin.sweeps.run import _spec

    names = metric_names(plan(_spec(spec)))
    numbers = [n for n in names if n not in TEXT_COLUMNS]
    if metric in TEXT_COLUMNS and metric in names:
        raise InputError(
            f"{argument('metric', '--plot')} {metric!r} is a column of text; plot one of numbers: {text.names(numbers, 20)}"
        )
    if metric not in numbers:
        raise InputError(
            f"{argument('metric', '--plot')} {metric!r} is not a column; valid: {text.names(numbers, 20)}"
        )


def plot_metric(out: str | Path, metric: str, path: str | Path | None = None) -> Path:
    """Draw ``metric`` of the sweep in ``out`` over its varied values; returns the PNG's path.

    One varied name: the metric's mean per value (or bin) as a line, with its
    min–max band. Two or more: a heat map of the mean over the first two (the
    others averaged). Units on the axes come from the Parquet metadata.

    Raises:
        InputError: no such metric column, or nothing varied.
    """
    from rrt_pin.sweeps.store import Store
    from rrt_pin.viewer.plot import _pyplot

    store = Store(out)
    manifest = store.read_manifest()
    if manifest is None:
        raise InputError(f"{str(out)!r} holds no sweep")
    table = store.read()
    names = [n for n in table.column_names if n != "variant" and n not in TEXT_COLUMNS]
    if metric in TEXT_COLUMNS:
        raise InputError(
            f"{argument('metric', '--plot')} {metric!r} is a column of text; plot one of numbers: {text.names(names, 20)}"
        )
    if metric not in table.column_names:
        raise InputError(
            f"{argument('metric', '--plot')} {metric!r} is not a column; valid: {text.names(names, 20)}"
        )
    units = json.loads((table.schema.metadata or {}).get(b"rrt_pin.units", b"{}"))
    varied = list(manifest["spec"].get("vary", {}))
    if not varied:
        raise InputError(f"{argument('metric', '--plot')} needs a sweep that varies something")
    y = np.asarray(table.column(metric).to_numpy(zero_copy_only=False), dtype=float)

    def label(name: str) -> str:
        unit = units.get(name, "")
        return f"{name} [{unit}]" if unit else name

    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(7, 4.8))
    try:
        if len(varied) == 1:
            x = table.column(varied[0]).to_numpy()
            index, centres = _bins(x)
            means = np.array([np.nanmean(y[index == k]) if (index == k).any() else np.nan
                              for k in range(centres.size)])  # fmt: skip
            lows = np.array([np.nanmin(y[index == k]) if (index == k).any() else np.nan
                             for k in range(centres.size)])  # fmt: skip
            highs = np.array([np.nanmax(y[index == k]) if (index == k).any() else np.nan
                              for k in range(centres.size)])  # fmt: skip
            ax.fill_between(centres, lows, highs, alpha=0.25, label="min–max")
            ax.plot(centres, means, marker="o", label="mean")
            ax.set_xlabel(label(varied[0]))
            ax.set_ylabel(label(metric))
            ax.legend(fontsize=8)
            ax.grid(True, alpha=0.3)
        else:
            xa, xb = (table.column(v).to_numpy() for v in varied[:2])
            ia, ca = _bins(xa)
            ib, cb = _bins(xb)
            grid = np.full((cb.size, ca.size), np.nan)
            total = np.zeros_like(grid)
            count = np.zeros_like(grid)
            ok = np.isfinite(y)
            np.add.at(total, (ib[ok], ia[ok]), y[ok])
            np.add.at(count, (ib[ok], ia[ok]), 1)
            grid[count > 0] = total[count > 0] / count[count > 0]
            mesh = ax.pcolormesh(ca, cb, grid, shading="nearest", cmap="viridis")
            fig.colorbar(mesh, ax=ax, label=f"mean {label(metric)}")
            if np.isnan(grid).any():
                ax.text(0.01, 0.01, "blank: no finite value (not settled, diverged)",
                        transform=ax.transAxes, fontsize=8, va="bottom")  # fmt: skip
            ax.set_xlabel(label(varied[0]))
            ax.set_ylabel(label(varied[1]))
        others = f" (mean over {', '.join(varied[2:])})" if len(varied) > 2 else ""
        ax.set_title(f"{metric} over {table.num_rows} variants{others}", fontsize=10)
        fig.tight_layout()
        import io

        buffer = io.BytesIO()
        fig.savefig(buffer, format="png", dpi=110)
    finally:
        plt.close(fig)
    if path is None:  # inside the sweep folder: as its own files, never through a link
        from rrt_pin.sweeps.store import write_into

        return write_into(out, f"{metric}.png", buffer.getvalue())
    target = Path(path)
    atomic_write_bytes(target, buffer.getvalue(), flag="--plot")
    return target
