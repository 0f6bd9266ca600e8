"""Labelled PNG plots of time series (matplotlib, imported only here, Agg backend)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

__all__ = ["Panel", "plot_panels"]


@dataclass(frozen=True)
class Panel:
    """One subplot: curves against time.

    Attributes:
        ylabel: axis label with its unit, e.g. ``"T01x [N·m]"``.
        curves: label → values, each the length of the time array.
        title: optional subplot title.
    """

    ylabel: str
    curves: Mapping[str, np.ndarray] = field(default_factory=dict)
    title: str = ""


def plot_panels(
    path: str | Path, t: np.ndarray, panels: Sequence[Panel], title: str, xlabel: str = "t [s]"
) -> Path:
    """Plot stacked panels sharing the time axis and write a PNG atomically.

    Raises:
        ImportError: matplotlib is missing (``pip install rrt-pin[plot]``).
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the install
        raise ImportError("matplotlib not found: pip install rrt-pin[plot]") from e
    from rrt_pin.io import atomic_write

    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(8, 2.4 * len(panels) + 0.8))
    axes = np.atleast_1d(axes)
    for ax, panel in zip(axes, panels, strict=True):
        for label, y in panel.curves.items():
            ax.plot(t, y, label=label, linewidth=1.4)
        ax.set_ylabel(panel.ylabel)
        if panel.title:
            ax.set_title(panel.title, fontsize=10)
        ax.grid(True, alpha=0.3)
        if len(panel.curves) > 1:
            ax.legend(loc="best", fontsize=8)
    axes[-1].set_xlabel(xlabel)
    fig.suptitle(title)
    fig.tight_layout()
    try:
        return atomic_write(path, lambda fh: fig.savefig(fh, format="png", dpi=110))
    finally:
        plt.close(fig)
