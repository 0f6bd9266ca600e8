"""Labelled plots of time series (matplotlib, imported only here, Agg backend).

Every curve has a legend entry, drawn beside the axes (never over the data);
targets are dashed lines in their curve's colour, and so are (finer) the position
limits a run approached or crossed; a robot's joints are grouped by unit and by
magnitude so that a 0.08 N·m wrist is not a flat line beside a 59 N·m shoulder.
The image format follows the file's suffix (:data:`FORMATS`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin import __version__
from rrt_pin.core.errors import InputError
from rrt_pin.core.extras import MissingExtra
from rrt_pin.core.text import argument
from rrt_pin.io.files import atomic_write_bytes
from rrt_pin.robot.limits import physical_model

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot

__all__ = [
    "FORMATS",
    "Panel",
    "effort_panels",
    "figure",
    "limits_near",
    "inverse_figure",
    "plot_format",
    "plot_panels",
    "position_panels",
    "render_panels",
    "simulate_figure",
    "simulate_panels",
]

#: Image formats by file suffix (matplotlib writes each).
FORMATS = {".png": "png", ".svg": "svg", ".pdf": "pdf"}
#: At most this many curves share a panel; a panel's smallest peak is at least
#: 1/MAGNITUDES of its largest.
MAX_CURVES = 6
MAGNITUDES = 20.0
#: A position limit is drawn when its joint came within this fraction of its panel's
#: vertical span of it (or crossed it): limits far from the motion would squash the axes.
LIMIT_NEAR = 0.02
#: The limits' line: thin, finely dashed, in the curve's colour (gid for readers of the figure).
LIMIT_STYLE = {"linestyle": (0, (5.0, 2.5)), "linewidth": 0.9, "alpha": 0.9}
LIMIT_GID = "position limit"


def plot_format(path: str | Path) -> str:
    """The image format of ``path`` from its suffix.

    ``-`` (stdout) and an existing file that is not a regular one (a pipe, a
    device) without a suffix get PNG.

    Raises:
        InputError: a suffix that is not one of :data:`FORMATS` (named, with the choices).
    """
    import os
    import stat

    suffix = Path(str(path)).suffix.lower()
    if not suffix:
        try:
            special = str(path) == "-" or not stat.S_ISREG(os.stat(path).st_mode)
        except OSError:
            special = False
        if special:
            return "png"
    if suffix not in FORMATS:
        problem = f"suffix {suffix!r} is not" if suffix else "no suffix names"
        raise InputError(
            f"{argument('path', '--plot')} {str(path)!r}: {problem} an image format rrt-pin writes; "
            f"use {', '.join(FORMATS)}"
        )
    return FORMATS[suffix]


@dataclass(frozen=True)
class Panel:
    """One subplot: curves against time.

    Attributes:
        ylabel: axis label with its unit, e.g. ``"T01x [N·m]"``.
        curves: label → values, each the length of the time array.
        title: optional subplot title.
        targets: label of a curve → its target value, drawn as a dashed line.
        limits: label of a curve → its limits to draw, (``"lower"`` or ``"upper"``, value),
            each a finely dashed line in the curve's colour, labelled in the legend.
    """

    ylabel: str
    curves: Mapping[str, np.ndarray] = field(default_factory=dict)
    title: str = ""
    targets: Mapping[str, float] = field(default_factory=dict)
    limits: Mapping[str, Sequence[tuple[str, float]]] = field(default_factory=dict)


def render_panels(
    t: np.ndarray,
    panels: Sequence[Panel],
    title: str,
    xlabel: str = "t [s]",
    fmt: str = "png",
) -> bytes:
    """Stacked panels sharing the time axis, as the bytes of a ``fmt`` image (png, svg, pdf).

    Raises:
        MissingExtra: matplotlib is missing (with the command that installs it).
    """
    import io

    plt = _pyplot()
    fig = figure(t, panels, title, xlabel)
    try:
        buffer = io.BytesIO()
        fig.savefig(buffer, format=fmt, dpi=110, metadata=_metadata(fmt, title))
        return buffer.getvalue()
    finally:
        plt.close(fig)


def figure(t: np.ndarray, panels: Sequence[Panel], title: str, xlabel: str = "t [s]"):  # noqa: ANN201
    """The matplotlib Figure of :func:`render_panels` (the caller closes it)."""
    plt = _pyplot()
    from matplotlib.lines import Line2D

    height = max(2.4 * len(panels) + 0.8, 4.2)  # [in]: a lone panel is not a strip
    fig, axes = plt.subplots(len(panels), 1, sharex=True, figsize=(9.5, height))
    colors = plt.get_cmap("tab10").colors
    for ax, panel in zip(np.atleast_1d(axes), panels, strict=True):
        handles = []
        for i, (label, y) in enumerate(panel.curves.items()):
            (line,) = ax.plot(t, y, label=label, linewidth=1.4, color=colors[i % 10])
            handles.append(line)
            if label in panel.targets:
                ax.axhline(panel.targets[label], color=line.get_color(), linestyle="--",
                           linewidth=1.0, alpha=0.8)  # fmt: skip
        if panel.targets:
            handles.append(Line2D([], [], color="0.4", linestyle="--", label="target qf"))
        for label, limits in panel.limits.items():
            color = colors[list(panel.curves).index(label) % 10] if label in panel.curves else "0.4"
            for side, value in limits:
                handles.append(ax.axhline(value, color=color, gid=LIMIT_GID, **LIMIT_STYLE,
                                          label=f"{label} {side} limit ({value:.4g})"))  # fmt: skip
        ax.set_ylabel(panel.ylabel)
        if panel.title:
            ax.set_title(panel.title, fontsize=10)
        ax.grid(True, alpha=0.3)
        ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                  fontsize=8, borderaxespad=0.0, frameon=False)  # fmt: skip
    np.atleast_1d(axes)[-1].set_xlabel(xlabel)
    fig.suptitle(title)
    fig.tight_layout()
    return fig


def _metadata(fmt: str, title: str) -> dict[str, str]:
    """The file's own metadata: its title and what made it (png, svg and pdf each have a Title)."""
    return {
        "Title": title,
        ("Creator" if fmt != "svg" else "Description"): f"rrt-pin {__version__}",
    }


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
        raise MissingExtra("matplotlib", "plot", "plots") from e
    return plt


def plot_panels(
    path: str | Path, t: np.ndarray, panels: Sequence[Panel], title: str, xlabel: str = "t [s]"
) -> Path:
    """Plot stacked panels sharing the time axis and write them atomically (format by suffix).

    Raises:
        InputError: an unknown image suffix.
        MissingExtra: matplotlib is missing.
    """
    fmt = plot_format(path)
    return atomic_write_bytes(path, render_panels(t, panels, title, xlabel, fmt=fmt))


def _groups(units: Sequence[str], size: np.ndarray) -> list[tuple[str, list[int]]]:
    """Coordinates grouped by unit, then by magnitude (``size`` per coordinate).

    Within a unit, coordinates are taken largest first; a panel closes when the
    next one is MAGNITUDES times smaller than its largest or it holds MAX_CURVES.
    Each panel lists its coordinates in joint order; panels keep the units' order.
    """
    by_unit: dict[str, list[int]] = {}
    for k, unit in enumerate(units):
        by_unit.setdefault(unit, []).append(k)
    out: list[tuple[str, list[int]]] = []
    for unit, ks in by_unit.items():
        order = sorted(ks, key=lambda k: (-float(size[k]), k))
        current: list[int] = []
        for k in order:
            if current and (len(current) >= MAX_CURVES or size[k] * MAGNITUDES < size[current[0]]):
                out.append((unit, sorted(current)))
                current = []
            current.append(k)
        out.append((unit, sorted(current)))
    return out


def _kind(unit: str, what: str) -> str:
    return {"N·m": "revolute", "N": "prismatic", "rad": "revolute", "m": "prismatic"}.get(
        unit, unit
    ) + f" joints{what}"


def effort_panels(robot: Robot, tau: np.ndarray, what: str = "") -> list[Panel]:
    """Panels of a robot's efforts (N, nv).

    One per joint when each has a description (the chapter's arm), else grouped
    by unit (N·m, N) and magnitude.
    """
    docs = robot.effort_docs
    if all(docs):
        return [
            Panel(f"{name} [{unit}]", {name: tau[:, k]}, title=f"{doc}{what}")
            for k, (name, unit, doc) in enumerate(
                zip(robot.effort_names, robot.effort_units, docs, strict=True)
            )
        ]
    peak = np.abs(tau).max(axis=0) if len(tau) else np.zeros(robot.nv)
    return [
        Panel(
            f"effort [{unit}]",
            {robot.effort_names[k]: tau[:, k] for k in ks},
            title=_kind(unit, what or ": efforts"),
        )
        for unit, ks in _groups(robot.effort_units, peak)
    ]


def position_panels(
    robot: Robot,
    q: np.ndarray,
    targets: Sequence[float] | None = None,
    limits: tuple[np.ndarray, np.ndarray] | None = None,
) -> list[Panel]:
    """Panels of a robot's joint coordinates (N, nv), by unit (rad, m) and magnitude of motion.

    ``targets`` (one per coordinate, e.g. the regulator's qf) are drawn dashed; of the
    position ``limits`` (lower, upper), each (nv,) [rad or m], ±inf for none, those the
    motion approached or crossed (:func:`limits_near`).
    """
    span = np.abs(q - q[:1]).max(axis=0) if len(q) else np.zeros(robot.nv)
    if targets is not None:
        span = np.maximum(span, np.abs(np.asarray(targets, dtype=float) - q[0]))
    panels = []
    for unit, ks in _groups(robot.coordinate_units, span):
        aims = {} if targets is None else {robot.q_names[k]: float(targets[k]) for k in ks}
        near = {} if limits is None else limits_near(q, ks, limits, list(aims.values()))
        panels.append(
            Panel(
                f"q [{unit}]",
                {robot.q_names[k]: q[:, k] for k in ks},
                title=_kind(unit, ": positions"),
                targets=aims,
                limits={robot.q_names[k]: found for k, found in near.items()},
            )
        )
    return panels


def limits_near(
    q: np.ndarray,
    ks: Sequence[int],
    limits: tuple[np.ndarray, np.ndarray],
    extra: Sequence[float] = (),
) -> dict[int, list[tuple[str, float]]]:
    """The position limits of coordinates ``ks`` that ``q`` (N, nv) crossed or came near.

    Near: within :data:`LIMIT_NEAR` of the panel's span (the values of ``q[:, ks]`` and
    ``extra``, e.g. the targets, drawn together). Returns coordinate → [(side, value)].
    """
    if not len(q) or not ks:
        return {}
    values = np.concatenate([q[:, ks].ravel(), np.asarray(extra, dtype=float)])
    values = values[np.isfinite(values)]
    if not values.size:
        return {}
    margin = LIMIT_NEAR * max(float(values.max() - values.min()), 1e-12)
    found: dict[int, list[tuple[str, float]]] = {}
    for k in ks:
        low, high = float(np.nanmin(q[:, k])), float(np.nanmax(q[:, k]))
        for side, value, gap in (("lower", float(limits[0][k]), low - float(limits[0][k])),
                                 ("upper", float(limits[1][k]), float(limits[1][k]) - high)):  # fmt: skip
            if np.isfinite(value) and gap <= margin:
                found.setdefault(k, []).append((side, value))
    return found


def inverse_figure(robot: Robot, t: np.ndarray, tau: np.ndarray, fmt: str = "png") -> bytes:
    """The inverse-dynamics plot of ``robot``: its efforts along its motion, as ``fmt`` bytes."""
    title = f"{robot.name}: joint efforts along {robot.motion}"
    return render_panels(t, effort_panels(robot, tau), title, fmt=fmt)


def simulate_panels(
    robot: Robot,
    q: np.ndarray,
    tau: np.ndarray,
    targets: Sequence[float] | None = None,
    law: str | None = None,
) -> tuple[list[Panel], str]:
    """The panels and title of :func:`simulate_figure` (data, nothing drawn).

    q(t) with its targets and the robot's stated position limits the run approached or
    crossed (:func:`rrt_pin.robot.limits.physical_model`: the URDF's, enforced or not);
    then the applied efforts, left out when all are zero (a passive run).
    """
    stated = physical_model(robot)
    limits = (stated.lower, stated.upper) if stated.has_positions else None
    panels = position_panels(robot, q, targets, limits)
    law = law or robot.regulator
    if np.any(tau):
        panels += effort_panels(robot, tau, what=": applied efforts")
        return panels, f"{robot.name} under {law}: q(t) and efforts"
    return panels, f"{robot.name} under {law}: q(t)"


def simulate_figure(
    robot: Robot,
    t: np.ndarray,
    q: np.ndarray,
    tau: np.ndarray,
    targets: Sequence[float] | None = None,
    fmt: str = "png",
    law: str | None = None,
) -> bytes:
    """The direct-dynamics plot of ``robot`` as ``fmt`` bytes (:func:`simulate_panels`).

    ``law``: the law's name for the title (default the robot's regulator).
    """
    panels, title = simulate_panels(robot, q, tau, targets, law)
    return render_panels(t, panels, title, fmt=fmt)
