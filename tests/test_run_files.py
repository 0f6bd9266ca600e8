"""One run file serves every command: [options] where a command has them, a table per command."""

from __future__ import annotations

import numpy as np

from rrt_pin.cli.app import main
from rrt_pin.robot.robot import Robot


def _rows(path) -> int:
    return len(path.read_text().splitlines()) - 1


def test_the_readme_example_works_for_every_command(tmp_path, capsys):
    run = tmp_path / "run.toml"
    run.write_text('[params]\nm3 = 50.0\nq1f = "pi/3"\n[options]\ndt = 0.001\n')
    for argv in (
        ["urdf", "-o", str(tmp_path / "a.urdf")],
        ["joints"],
        ["equations", "--format", "text"],
        ["view", "--serve-for", "0", "--port", "0"],
        ["inverse", "--csv", str(tmp_path / "i.csv")],
    ):
        assert main([*argv, "--config", str(run)]) == 0, (argv, capsys.readouterr().err)
    assert _rows(tmp_path / "i.csv") == 15_001  # dt applied where it is an option
    assert '<mass value="50.0"/>' in (tmp_path / "a.urdf").read_text()  # [params] too


def test_each_command_its_own_table(tmp_path, capsys):
    run = tmp_path / "run.toml"
    run.write_text("[options]\ntf = 3.0\n[inverse]\ndt = 0.001\n[simulate]\ndt = 0.5\n")
    assert main(["inverse", "--config", str(run), "--csv", str(tmp_path / "i.csv")]) == 0
    assert main(["simulate", "--config", str(run), "--csv", str(tmp_path / "s.csv")]) == 0
    assert _rows(tmp_path / "i.csv") == 3001  # tf from [options], dt from [inverse]
    assert _rows(tmp_path / "s.csv") == 7  # tf from [options], dt from [simulate]
    # explicit flags still win over both tables
    assert (
        main(["simulate", "--config", str(run), "--dt", "1", "--csv", str(tmp_path / "f.csv")]) == 0
    )
    assert _rows(tmp_path / "f.csv") == 4


def test_a_command_table_overrides_options(tmp_path, capsys):
    run = tmp_path / "run.toml"
    run.write_text("[options]\ndt = 0.25\n[simulate]\ndt = 0.5\n")
    assert (
        main(["simulate", "--config", str(run), "--tf", "1", "--csv", str(tmp_path / "s.csv")]) == 0
    )
    t = np.loadtxt(tmp_path / "s.csv", delimiter=",", skiprows=1)[:, 0]
    np.testing.assert_array_equal(t, [0.0, 0.5, 1.0])


def test_a_bad_value_names_its_table(tmp_path, capsys):
    run = tmp_path / "run.toml"
    run.write_text("[simulate]\ndt = -1\n")
    assert main(["simulate", "--config", str(run)]) == 2
    assert "[simulate]" in capsys.readouterr().err


def test_integration_step_is_apart_from_the_output_interval(tmp_path, capsys):
    """--step sets a fixed-step method's step; --dt only the rows (default step: --dt)."""
    from rrt_pin.robot.model import build_model
    from rrt_pin.robot.params import Params
    from rrt_pin.simulate import simulate
    from rrt_pin.simulate.control import chapter_controller

    out = tmp_path / "s.csv"
    argv = ["simulate", "--method", "rk4", "--tf", "1", "--dt", "0.1", "--csv", str(out)]
    assert main([*argv, "--step", "0.001"]) == 0
    fine = np.loadtxt(out, delimiter=",", skiprows=1)
    assert fine.shape[0] == 11
    p = Params()
    expected = simulate(Robot.from_model(build_model(p)), chapter_controller(p), p.q0, p.qd0,
                        np.linspace(0, 1, 11), method="rk4", step=0.001)  # fmt: skip
    np.testing.assert_allclose(fine[:, 1:4], expected.q, rtol=0, atol=1e-13)
    assert main(argv) == 0  # without --step: the step is --dt, a coarser run
    coarse = np.loadtxt(out, delimiter=",", skiprows=1)
    assert coarse.shape == fine.shape and np.abs(coarse[:, 1:4] - fine[:, 1:4]).max() > 1e-6
