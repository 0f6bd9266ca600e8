"""The q(t) plot draws the URDF's position limits a run crossed or came near, and no others."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from rrt_pin.cli.app import main
from rrt_pin.robot.limits import physical_model
from rrt_pin.robot.robots import chapter_arm, get
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import regulator
from rrt_pin.viewer import plot
from rrt_pin.viewer.plot import LIMIT_GID, figure, simulate_panels

#: The issue's passive UR5: wrist 1 reaches its −2π limit at ~1.12 s, the elbow its +π at ~1.23 s.
UR5_Q0 = [0.0, -1.0, 1.0, 0.3, 0.5, 0.0]


def _passive_ur5(tf: float):
    t = np.arange(0.0, tf + 1e-9, 0.01)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return simulate(get("ur5"), None, UR5_Q0, None, t, estimate_error=False)


def _limit_lines(fig):
    """(legend label, y, colour) of each limit line, and each curve's colour by label."""
    lines, colours = [], {}
    for ax in fig.axes:
        for line in ax.get_lines():
            if line.get_gid() == LIMIT_GID:
                y = np.unique(line.get_ydata())
                assert y.size == 1  # horizontal
                lines.append((line.get_label(), float(y[0]), line.get_color()))
            else:
                colours[line.get_label()] = line.get_color()
    return lines, colours


def _drawn(robot, result):
    import matplotlib.pyplot as plt

    panels, title = simulate_panels(robot, result.q, result.tau, law="no controller")
    fig = figure(result.t, panels, title)
    try:
        fig.canvas.draw()
        legend = {t.get_text() for ax in fig.axes for t in ax.get_legend().get_texts()}
        return _limit_lines(fig), legend, [ax.get_ylim() for ax in fig.axes], title
    finally:
        plt.close(fig)


def test_a_run_past_its_limits_draws_them_in_its_joints_colours():
    ur5 = get("ur5")
    result = _passive_ur5(1.4)
    crossed = {e.joint for e in result.limits if e.kind == "position"}
    assert crossed == {"wrist_1_joint", "elbow_joint"}  # the scene still does what it says
    (lines, colours), legend, ylims, title = _drawn(ur5, result)
    stated = physical_model(ur5)
    by_joint = {label.split(" ")[0]: (y, colour) for label, y, colour in lines}
    assert sorted(by_joint) == ["q_elbow_joint", "q_wrist_1_joint"]
    assert by_joint["q_wrist_1_joint"][0] == pytest.approx(stated.lower[3]) == -2 * np.pi
    assert by_joint["q_elbow_joint"][0] == pytest.approx(stated.upper[2]) == np.pi
    for joint, (_, colour) in by_joint.items():
        assert colour == colours[joint]  # the line is its curve's colour
    for label, _, _ in lines:
        assert label in legend and " limit (" in label
    # only those two: the shoulder's ±2π and the elbow's −π are not drawn (nor crossed)
    assert len(lines) == 2
    # the plot title names the law, and a passive run has no efforts panel (all zero)
    assert "no controller" in title and len(ylims) == 1


def test_limits_far_from_the_motion_are_not_drawn_and_do_not_squash_the_axes():
    result = _passive_ur5(0.5)  # before any limit; every joint far from its ±2π or ±π
    assert not [e for e in result.limits if e.kind == "position"]
    (lines, _), _, ylims, _ = _drawn(get("ur5"), result)
    assert lines == []
    low, high = ylims[0]
    assert -np.pi < low and high < np.pi  # the axes follow the motion, not the limits


def test_the_chapter_arm_has_no_limit_lines():
    arm = chapter_arm()
    t = np.linspace(0.0, 2.0, 41)
    result = simulate(arm, regulator(arm), arm.defaults.q0, None, t, estimate_error=False)
    (lines, _), legend, ylims, _ = _drawn(arm, result)
    assert lines == [] and not any("limit" in text for text in legend)
    assert len(ylims) > 1  # its efforts are drawn (not all zero)


def test_the_cli_plot_draws_the_limits_and_names_the_passive_law(tmp_path, capsys):
    captured = {}
    real = plot.figure

    def spy(t, panels, title, xlabel="t [s]"):
        captured["panels"], captured["title"] = panels, title
        return real(t, panels, title, xlabel)

    plot.figure = spy
    try:
        path = tmp_path / "ur5.png"
        argv = ["simulate", "--robot", "ur5", "--passive", "--q0", ",".join(map(str, UR5_Q0)),
                "--tf", "1.4", "--dt", "0.01", "--plot", str(path)]  # fmt: skip
        assert main(argv) == 0
        assert path.read_bytes().startswith(b"\x89PNG")
    finally:
        plot.figure = real
    drawn = {k: v for p in captured["panels"] for k, v in p.limits.items()}
    assert drawn == {"q_elbow_joint": [("upper", pytest.approx(np.pi))],
                     "q_wrist_1_joint": [("lower", pytest.approx(-2 * np.pi))]}  # fmt: skip
    assert "passive" in captured["title"]
