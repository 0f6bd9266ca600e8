"""Plots: every curve labelled, targets drawn, joints grouped by unit and magnitude, format by suffix."""

from __future__ import annotations

import numpy as np
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.errors import InputError
from rrt_pin.robot.robots import chapter_arm, get
from rrt_pin.viewer.plot import (
    MAGNITUDES,
    MAX_CURVES,
    _groups,
    effort_panels,
    figure,
    plot_format,
    position_panels,
)

MAGIC = {"png": b"\x89PNG\r\n\x1a\n", "svg": b"<?xml", "pdf": b"%PDF-"}


@pytest.mark.parametrize("fmt", ["png", "svg", "pdf"])
@pytest.mark.parametrize("command", ["inverse", "simulate"])
def test_format_follows_the_suffix(fmt, command, tmp_path, capsys):
    path = tmp_path / f"plot.{fmt.upper() if fmt == 'pdf' else fmt}"
    assert main([command, "--dt", "0.5", "--plot", str(path)]) == 0
    data = path.read_bytes()
    assert data.startswith(MAGIC[fmt]), data[:16]
    if fmt == "svg":
        assert b"<svg" in data[:2000]


def test_unknown_suffix_is_refused():
    for path in ("x.jpg", "x", "dir.png/x.gif"):
        with pytest.raises(InputError, match="use .png, .svg, .pdf"):
            plot_format(path)


def test_groups_split_units_and_magnitudes():
    units = ("rad", "rad", "m", "rad", "rad", "rad")
    size = np.array([59.0, 0.08, 1.0, 30.0, 0.1, 3.0])
    groups = _groups(units, size)
    assert ("m", [2]) in groups
    rad = [ks for unit, ks in groups if unit == "rad"]
    assert [0, 3, 5] in rad and [1, 4] in rad  # 3.0 is within 20x of 59; 0.1 is not
    for unit, ks in groups:
        assert all(units[k] == unit for k in ks) and ks == sorted(ks)
        assert size[ks].min() * MAGNITUDES >= size[ks].max()
    assert sorted(k for _, ks in groups for k in ks) == list(range(6))  # each once
    many = _groups(("N·m",) * 15, np.ones(15))
    assert [len(ks) for _, ks in many] == [6, 6, 3] and MAX_CURVES == 6


def _legends(fig):  # label texts of each axes' legend
    return [[t.get_text() for t in ax.get_legend().get_texts()] for ax in fig.axes]


def test_every_curve_of_the_arm_is_labelled_and_targets_drawn():
    import matplotlib.pyplot as plt

    arm = chapter_arm()
    t = np.linspace(0, 1, 11)
    q = np.tile(np.array(arm.defaults.q0), (11, 1))
    tau = np.ones((11, 3))
    panels = position_panels(arm, q, arm.defaults.qf) + effort_panels(arm, tau)
    fig = figure(t, panels, "title")
    try:
        legends = _legends(fig)
        labelled = {x for texts in legends for x in texts}
        assert {"q1", "q2", "q3", "T01x", "T12y", "F23z"} <= labelled
        assert all(texts for texts in legends)  # single-curve panels too
        # the q panels draw qf as dashed horizontal lines at the targets
        dashed = [
            line.get_ydata()[0]
            for ax in fig.axes
            for line in ax.get_lines()
            if line.get_linestyle() == "--"
        ]
        assert sorted(dashed) == pytest.approx(sorted(arm.defaults.qf))
    finally:
        plt.close(fig)


def test_ur5_wrist_is_not_a_flat_line_beside_the_shoulder():
    import matplotlib.pyplot as plt

    from rrt_pin.dynamics.inverse import inverse_dynamics
    from rrt_pin.dynamics.trajectory import rest_to_rest

    ur5 = get("ur5")
    t = np.linspace(0, 15, 301)
    motion = rest_to_rest([0, -1.5, 1, 0, 0, 0], [0.5, -1, 1.5, 0.3, 0.2, 0.1], 15, t)
    tau = inverse_dynamics(ur5, motion.q, motion.qd, motion.qdd)
    panels = effort_panels(ur5, tau)
    peaks = [np.abs(np.column_stack(list(p.curves.values()))).max(axis=0) for p in panels]
    assert len(panels) >= 2
    for p in peaks:
        assert p.min() * MAGNITUDES >= p.max()
    fig = figure(t, panels, "ur5")
    try:
        assert sorted(x for texts in _legends(fig) for x in texts) == sorted(ur5.effort_names)
        # No legend overlaps its axes: each is drawn to the right of the plot area.
        fig.canvas.draw()
        for ax in fig.axes:
            assert ax.get_legend().get_window_extent().x0 >= ax.get_window_extent().x1
    finally:
        plt.close(fig)


def test_title_names_the_robot(tmp_path, capsys):
    import matplotlib.pyplot as plt

    arm = chapter_arm()
    t = np.linspace(0, 1, 5)
    from rrt_pin.viewer import plot

    captured = {}
    real = plot.figure

    def spy(t, panels, title, xlabel="t [s]"):
        captured["title"] = title
        return real(t, panels, title, xlabel)

    plot.figure = spy
    try:
        plot.inverse_figure(arm, t, np.ones((5, 3)))
        assert captured["title"].startswith(arm.name)
        plot.simulate_figure(get("ur5"), t, np.zeros((5, 6)), np.ones((5, 6)))
        assert captured["title"].startswith("ur5")
    finally:
        plot.figure = real
        plt.close("all")


def test_stdout_and_pipes_get_png(tmp_path):
    import os

    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    assert plot_format("-") == "png" and plot_format(fifo) == "png"
    assert plot_format(tmp_path / "x.SVG") == "svg"
    (tmp_path / "plain").write_text("")
    with pytest.raises(InputError, match="no suffix names an image format"):
        plot_format(tmp_path / "plain")  # a regular file still needs its suffix


@pytest.mark.parametrize("command", ["inverse", "simulate"])
def test_unknown_suffix_is_refused_before_any_work(command, tmp_path, capsys):
    assert main([command, "--plot", str(tmp_path / "x.jpg")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"rrt-pin {command}: error: argument --plot: suffix '.jpg'"), err
