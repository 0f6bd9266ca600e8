"""Labelled PNG plots of time series (matplotlib, imported only here, Agg backend)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from rrt_pin.robot import Robot

__all__ = ["Panel", "effort_panels", "plot_panels", "position_panels", "render_panels"]


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


def render_panels(
    t: np.ndarray,
    panels: Sequence[Panel],
    title: str,
    xlabel: str = "t [s]",
    fmt: str = "png",
) -> bytes:
    """Stacked panels sharing the time axis, as the bytes of a PNG (or ``fmt``) image.

    Raises:
        ImportError: matplotlib is missing (``pip install rrt-pin[plot]``).
    """
    plt = _pyplot()
    import io

    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(8, 2.4 * len(panels) + 0.8))
    axes = np.atleast_1d(axes)
    try:
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
        buffer = io.BytesIO()
        fig.savefig(buffer, format=fmt, dpi=110)
        return buffer.getvalue()
    finally:
        plt.close(fig)


def _pyplot():  # noqa: ANN202
    """matplotlib.pyplot on the Agg backend.

    Raises:
        InputError: matplotlib is missing (with how to install it).
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError as e:  # pragma: no cover - depends on the install
        from rrt_pin.extras import MissingExtra

        raise MissingExtra("matplotlib", "plot", "plots") from e
    return plt


def plot_panels(
    path: str | Path, t: np.ndarray, panels: Sequence[Panel], title: str, xlabel: str = "t [s]"
) -> Path:
    """Plot stacked panels sharing the time axis and write a PNG atomically.

    Raises:
        ImportError: matplotlib is missing (``pip install rrt-pin[plot]``).
    """
    from rrt_pin.io import atomic_write_bytes

    return atomic_write_bytes(path, render_panels(t, panels, title, xlabel))


def _groups(robot: Robot, units: Sequence[str]) -> list[tuple[str, list[int]]]:
    """Coordinates grouped by unit, in order of first appearance."""
    groups: dict[str, list[int]] = {}
    for k, unit in enumerate(units):
        groups.setdefault(unit, []).append(k)
    return list(groups.items())


def effort_panels(robot: Robot, tau: np.ndarray, what: str = "") -> list[Panel]:
    """Panels of a robot's efforts (N, nv).

    One per joint when each has a description (the chapter's arm), else one per unit (N·m, N).
    """
    docs = robot.effort_docs
    if all(docs):
        return [
            Panel(f"{name} [{unit}]", {name: tau[:, k]}, title=f"{doc}{what}")
            for k, (name, unit, doc) in enumerate(
                zip(robot.effort_names, robot.effort_units, docs, strict=True)
            )
        ]
    kinds = {"N·m": "revolute", "N": "prismatic"}
    return [
        Panel(
            f"effort [{unit}]",
            {robot.effort_names[k]: tau[:, k] for k in ks},
            title=f"{kinds.get(unit, unit)} joints{what}",
        )
        for unit, ks in _groups(robot, robot.effort_units)
    ]


def position_panels(robot: Robot, q: np.ndarray) -> list[Panel]:
    """Panels of a robot's joint coordinates (N, nv), one per unit (rad, m)."""
    kinds = {"rad": "revolute", "m": "prismatic"}
    return [
        Panel(
            f"q [{unit}]",
            {robot.q_names[k]: q[:, k] for k in ks},
            title=f"{kinds.get(unit, unit)} joints: positions",
        )
        for unit, ks in _groups(robot, robot.coordinate_units)
    ]
