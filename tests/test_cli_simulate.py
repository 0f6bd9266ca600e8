"""``rrt-pin simulate``: the CSV contract, the summary, the plot, bad input and divergence."""

import numpy as np
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.grid import time_grid
from rrt_pin.io.csvio import read_csv
from rrt_pin.robot.model import load_urdf_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import pd_gravity_controller, seed_controller
from rrt_pin.simulate.methods import METHODS
from rrt_pin.simulate.metrics import settling_times
from tests.support import robot_urdf

HEADER = ["t", "q1", "q2", "q3", "qd1", "qd2", "qd3", "T01x", "T12y", "F23z"]


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_csv_contract(tmp_path, capsys):
    target = tmp_path / "run.csv"
    code, out, err = run(["simulate", "--csv", str(target)], capsys)
    assert code == 0 and err == f"rrt-pin: wrote {target} (method odepack, backend pinocchio)\n"
    assert out.startswith("simulated the RRT arm") and "settled (2 %)" in out
    assert target.read_text().splitlines()[0] == ",".join(HEADER)
    header, data = read_csv(target, HEADER)
    assert header == HEADER and data.shape == (1501, 10)
    assert data[0, 0] == 0.0 and data[-1, 0] == 15.0
    p = Params()
    expected = simulate(chapter_arm(p), seed_controller(p), p.q0, p.qd0, time_grid(15.0, 0.01))
    # Shortest round-trip numbers: the file holds the simulation's numbers exactly.
    np.testing.assert_array_equal(data, expected.table())


def test_summary_without_csv(capsys):
    code, out, err = run(["simulate"], capsys)
    assert code == 0 and err == ""
    lines = out.splitlines()
    assert lines[0].startswith(
        "simulated the RRT arm under the chapter's feedback law, eq. (31): 1501 samples"
    )
    assert "method odepack" in lines[0]
    rows = {line.split()[0]: line for line in lines[2:]}
    for name in ("q1", "q2", "q3"):
        assert "settled" not in rows[name] and " s" in rows[name]
    assert rows["q3"].split()[4] == "m" and rows["q1"].split()[4] == "rad"
    distance = float(rows["q3"].split()[3])
    assert 0.0 < distance < 1e-3
    for name, unit in (("T01x", "N·m"), ("T12y", "N·m"), ("F23z", "N")):
        assert rows[name].split()[2] == unit


def test_settling_times():
    t = np.linspace(0.0, 4.0, 5)
    q = np.array([[0.0, 1.0], [0.5, 1.0], [0.99, 1.0], [0.985, 1.0], [1.0, 1.0]])
    assert settling_times(t, q, [0.0, 1.0], [1.0, 1.0]) == [2.0, 0.0]
    q[-1, 0] = 0.9
    assert settling_times(t, q, [0.0, 1.0], [1.0, 1.0])[0] is None


def test_options_reach_the_simulation(tmp_path, capsys):
    target = tmp_path / "run.csv"
    argv = ["simulate", "--tf", "2", "--dt", "0.05", "--method", "rk4", "--csv", str(target)]
    argv += ["--q0", "0.1,0.2,0.3", "--kp", "100", "--kd", "50,60,70", "--set", "m3=30"]
    code, _, _ = run(argv, capsys)
    assert code == 0
    _, data = read_csv(target, HEADER)
    p = Params(m3=30.0, q10=0.1, q20=0.2, q30=0.3, gamma01=100.0, gamma12=100.0, gamma23=100.0)
    p = p.with_overrides({"beta01": 50.0, "beta12": 60.0, "beta23": 70.0})
    expected = simulate(
        chapter_arm(p), seed_controller(p), p.q0, p.qd0, time_grid(2.0, 0.05), method="rk4"
    )
    np.testing.assert_array_equal(data, expected.table())


def test_plot(tmp_path, capsys):
    target = tmp_path / "run.png"
    code, out, err = run(["simulate", "--tf", "1", "--plot", str(target)], capsys)
    assert code == 0 and out.startswith("simulated") and f"wrote {target}" in err
    assert target.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_any_urdf(tmp_path, capsys):
    urdf = robot_urdf("ur5")
    target = tmp_path / "ur5.csv"
    qf = [0.5, -1.0, 1.0, 0.0, 0.3, 0.0]
    argv = ["simulate", "--urdf", str(urdf), "--q0", "0,0,0,0,0,0", "--qf", ",".join(map(str, qf))]
    argv += ["--kp", "100", "--kd", "20", "--tf", "2", "--csv", str(target)]
    code, _, err = run(argv, capsys)
    assert code == 0, err
    header, data = read_csv(target)
    assert header[:2] == ["t", "q_shoulder_pan_joint"]
    assert header[7] == "qd_shoulder_pan_joint" and header[-1] == "tau_wrist_3_joint"
    model = load_urdf_model(urdf)
    c = pd_gravity_controller(Robot.from_model(model), 100.0, 20.0, qf)
    expected = simulate(Robot.from_model(model), c, np.zeros(6), np.zeros(6), time_grid(2.0, 0.01))
    np.testing.assert_array_equal(data, expected.table())


def test_methods_listed_by_the_command_are_the_librarys(capsys):
    """--help lists every method of the registry, leapfrog included, with how it steps."""
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = capsys.readouterr().out
    for name, m in METHODS.items():
        line = next(x for x in text.splitlines() if x.startswith(f"  {name} "))  # the epilog's
        assert ("--rtol" in line) == m.adaptive and ("--step" in line) != m.adaptive


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--set", "gamma01=-1"], "gamma01=-1.0: gain must be >= 0"),
        (["--set", "beta23=nan"], "beta23=nan: must be finite"),
        (["--kp=-1,1,1"], "--kp[0]=-1.0: gain must be >= 0"),
        (["--kd", "1,inf,1"], "must be finite: 'inf'"),
        (["--kp", "1,2"], "--kp has 2 values but the arm has 3 joints"),
        (["--q0", "nan,0,0"], "must be finite: 'nan'"),
        (["--set", "q20=inf"], "q20=inf: must be finite"),
        (["--method", "euler"], "method='euler' is not one of odepack"),
        (["--rtol", "0"], "must be > 0"),
        (["--dt", "-0.01"], "argument --dt: must be > 0: '-0.01'"),
        (["--dt", "20"], "dt=20.0 is larger than tf - t0"),
        (["--backend", "gpu"], "invalid choice"),
        (["--urdf", "nowhere.urdf", "--q0", "0"], "cannot read URDF"),
        (["--csv", "/nonexistent/folder/x.csv"], "folder '/nonexistent/folder' does not exist"),
    ],
)
def test_bad_input_is_one_line_exit_2_nothing_written(tmp_path, capsys, argv, words):
    full = ["simulate", *argv]
    if "--csv" not in argv:
        full += ["--csv", str(tmp_path / "out.csv"), "--plot", str(tmp_path / "out.png")]
    code, out, err = run(full, capsys)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and words in err, err
    assert list(tmp_path.iterdir()) == []


def test_urdf_needs_its_own_values(tmp_path, capsys):
    urdf = str(robot_urdf("ur5"))
    cases = [
        ([], "needs --q0, --qf, --kp and --kd (6 values each"),
        (["--q0", "0,0,0,0,0,0", "--qf", "0,0,0,0,0,0", "--kp", "1", "--kd", "1,1"], "--kd has 2"),
        (
            [
                "--q0",
                "0,0,0,0,0,0",
                "--qf",
                "0,0,0,0,0,0",
                "--kp",
                "1",
                "--kd",
                "1",
                "--set",
                "m3=2",
            ],
            "parameter m3 describes the RRT arm",
        ),
    ]
    for extra, words in cases:
        code, out, err = run(["simulate", "--urdf", urdf, *extra], capsys)
        assert code == 2 and out == "" and words in err, err


def test_divergence_is_one_line_exit_2_nothing_written(tmp_path, capsys):
    """A 1 g slider on a 1e7 N/m spring with explicit Euler at 10 ms diverges."""
    target = tmp_path / "out.csv"
    argv = ["simulate", "--method", "symplectic_euler", "--set", "m3=0.001"]
    argv += ["--set", "gamma23=1e7", "--set", "beta23=0", "--csv", str(target)]
    code, out, err = run(argv, capsys)
    assert code == 2 and out == ""
    assert err.startswith("rrt-pin: error: simulation diverged at t=") and " in qd3: " in err
    assert err.count("\n") == 1
    assert list(tmp_path.iterdir()) == []


def test_scene_options(tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text('[params]\nm3 = 35.0\n\n[options]\ntf = 3.0\nmethod = "DOP853"\n')
    code, out, _ = run(["simulate", "--scene", str(scene)], capsys)
    assert code == 0
    assert "t = 0 .. 3 s, method DOP853" in out.splitlines()[0]


@pytest.mark.parametrize("command", ["simulate", "inverse"])
def test_a_full_disk_changes_no_output_of_the_run(command, tiny_fs, capsys):
    """The CSV and the plot are written together or not at all: old files stay as they were."""
    png, csv = tiny_fs / "p.png", tiny_fs / "r.csv"
    png.write_bytes(b"old plot")
    csv.write_text("old csv")
    (tiny_fs / "filler").write_bytes(b"x" * 40_000)  # leaves less than a plot's size
    code = main([command, "--tf", "1", "--csv", str(csv), "--plot", str(png)])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "no space left on device" in err, err
    assert png.read_bytes() == b"old plot" and csv.read_text() == "old csv"
    assert sorted(p.name for p in tiny_fs.iterdir()) == ["filler", "p.png", "r.csv"]


def test_csv_and_plot_naming_one_file_are_refused(tmp_path, capsys):
    out = tmp_path / "same.png"
    code = main(["simulate", "--csv", str(out), "--plot", str(out)])
    assert code == 2 and "--csv and --plot name the same file" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("robot_flags", [[], ["--robot", "ur5"]])
def test_passive_is_no_controller_at_all(tmp_path, capsys, robot_flags):
    """--passive: zero efforts and no gravity compensation (--kp 0 --kd 0 still has G(q))."""
    import json

    from rrt_pin.robot.robots import get

    target, meta = tmp_path / "p.csv", tmp_path / "p.json"
    code, out, err = run(["simulate", "--passive", "--tf", "1", "--csv", str(target),
                          "--json", str(meta), *robot_flags], capsys)  # fmt: skip
    assert code == 0, err
    assert "under no controller (passive" in out
    robot = get("ur5") if robot_flags else chapter_arm()
    q0 = robot.defaults.q0 if robot.defaults.q0 is not None else np.zeros(robot.nv)
    expected = simulate(robot, None, q0, None, time_grid(1.0, 0.01))
    _, data = read_csv(target)
    np.testing.assert_array_equal(data, expected.table())
    assert not data[:, 1 + 2 * robot.nv :].any()  # no effort at all
    doc = json.loads(meta.read_text())
    assert (
        doc["metadata"]["regulator"].startswith("no controller") and doc["metadata"]["kp"] is None
    )
    # a PD law with zero gains still compensates gravity: another motion
    rest = ["--q0", ",".join(["0"] * 6), "--qf", ",".join(["0"] * 6)] if robot_flags else []
    code, _, err = run(["simulate", "--tf", "1", "--kp", "0", "--kd", "0", "--csv",
                        str(tmp_path / "zero.csv"), *robot_flags, *rest], capsys)  # fmt: skip
    assert code == 0, err
    _, zero_gains = read_csv(tmp_path / "zero.csv")
    assert np.abs(zero_gains[:, 1 : 1 + robot.nv] - data[:, 1 : 1 + robot.nv]).max() > 1e-3


def _eq30_csv(tmp_path, capsys, dt="0.01"):
    path = tmp_path / "eq30.csv"
    assert main(["inverse", "--dt", dt, "--csv", str(path)]) == 0
    capsys.readouterr()
    return path


def test_track_follows_a_motion_from_a_file(tmp_path, capsys):
    """--track: computed torque along the file's motion, the same run as the library's."""
    from rrt_pin.dynamics.sampled import read_motion
    from rrt_pin.dynamics.trajectory import Trajectory
    from rrt_pin.simulate.control import tracking_controller

    motion_file = _eq30_csv(tmp_path, capsys)
    out = tmp_path / "tracked.csv"
    code, text, err = run(["simulate", "--track", str(motion_file), "--tf", "3", "--csv",
                           str(out)], capsys)  # fmt: skip
    assert code == 0, err
    assert "computed-torque tracking of eq30.csv" in text
    arm = chapter_arm()
    m = read_motion(motion_file, arm)
    law = tracking_controller(arm, Trajectory(m.t, m.q, m.qd, m.qdd), kp=100.0, kd=20.0)
    expected = simulate(arm, law, m.q[0], m.qd[0], time_grid(3.0, 0.01))
    _, data = read_csv(out)
    np.testing.assert_array_equal(data, expected.table())
    # starting on the motion, an exact model keeps it (to the reference's interpolation)
    assert np.abs(data[:, 1:4] - m.q[:301]).max() < 1e-5


def test_efforts_are_played_open_loop(tmp_path, capsys):
    """--efforts: eq. (30)'s own efforts, played back, move the arm along eq. (30)."""
    from rrt_pin.dynamics.sampled import read_efforts, read_motion
    from rrt_pin.simulate.control import OpenLoop

    efforts_file = _eq30_csv(tmp_path, capsys, dt="0.001")
    out = tmp_path / "open.csv"
    code, text, err = run(["simulate", "--efforts", str(efforts_file), "--tf", "1", "--csv",
                           str(out)], capsys)  # fmt: skip
    assert code == 0, err
    assert "(open loop)" in text
    arm = chapter_arm()
    t, tau = read_efforts(efforts_file, arm)
    expected = simulate(arm, OpenLoop(t, tau), arm.defaults.q0, None, time_grid(1.0, 0.01))
    _, data = read_csv(out)
    np.testing.assert_array_equal(data, expected.table())
    planned = read_motion(efforts_file, arm).q[::10][:101]
    assert np.abs(data[:, 1:4] - planned).max() < 1e-5  # open loop, 1 s: the plan holds
    # the law ignores the state, and interpolates linearly between samples
    law = OpenLoop(t, tau)
    assert np.array_equal(law.efforts(0.0005, np.ones(3), np.ones(3)), 0.5 * (tau[0] + tau[1]))


def test_a_users_controller_from_the_command_line(tmp_path, capsys, monkeypatch):
    (tmp_path / "mylaw.py").write_text(
        "import numpy as np\n\ndef law(t, q, qd):\n"
        "    return -50.0 * (np.asarray(q) - 0.3) - 10.0 * np.asarray(qd)\n"
    )
    monkeypatch.chdir(tmp_path)
    monkeypatch.delitem(__import__("sys").modules, "mylaw", raising=False)
    code, text, err = run(["simulate", "--controller", "mylaw:law", "--tf", "2", "--csv",
                           "run.csv"], capsys)  # fmt: skip
    assert code == 0, err
    assert "mylaw:law (your law)" in text
    import mylaw  # noqa: E402  (the module the run imported, from the current directory)

    arm = chapter_arm()
    expected = simulate(arm, mylaw.law, arm.defaults.q0, None, time_grid(2.0, 0.01))
    _, data = read_csv(tmp_path / "run.csv")
    np.testing.assert_array_equal(data, expected.table())
