"""``rrt-pin inverse``: the CSV contract, the summary, other arms, bad input, light imports."""

import importlib.util
import subprocess
import sys

import numpy as np
import pinocchio as pin
import pytest

import rrt_pin.robot.model
from rrt_pin.cli.app import main
from rrt_pin.cli.commands import inverse as command
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.dynamics.wrenches import RRT_WRENCH_COLUMNS, joint_wrenches, wrench_table
from rrt_pin.io.csvio import read_csv
from rrt_pin.robot.model import load_urdf_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from tests.support import DERIVED, TIGHT, holding_efforts, robot_urdf

HEADER = "t,q1,q2,q3,qd1,qd2,qd3,qdd1,qdd2,qdd3,T01x,T12y,F23z"
HAS_KERNEL = importlib.util.find_spec("rrt_pin.dynamics.kernel") is not None


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.fixture(scope="module")
def seed_csv(tmp_path_factory):
    path = tmp_path_factory.mktemp("inverse") / "seed.csv"
    assert main(["inverse", "--csv", str(path)]) == 0
    return path


def test_csv_contract(seed_csv, seed_params):
    p = seed_params
    lines = seed_csv.read_text().splitlines()
    assert lines[0] == HEADER
    assert len(lines) == 1 + 15001
    header, data = read_csv(seed_csv)
    # Shortest round-trip numbers: the first columns are exactly the grid and eq. (30).
    t = time_grid(p.Tp, 0.001)
    traj = rest_to_rest(p.q0, p.qf, p.Tp, t)
    np.testing.assert_array_equal(data[:, 0], t)
    np.testing.assert_array_equal(data[:, 1:4], traj.q)
    np.testing.assert_array_equal(data[:, 4:7], traj.qd)
    np.testing.assert_array_equal(data[:, 7:10], traj.qdd)
    tau = inverse_dynamics(chapter_arm(p), traj.q, traj.qd, traj.qdd)
    np.testing.assert_array_equal(data[:, 10:13], tau)
    assert data[0, 0] == 0.0 and data[-1, 0] == 15.0


def test_csv_ends_hold_the_arm(seed_csv, seed_params):
    p = seed_params
    _, data = read_csv(seed_csv)
    for row, q in ((0, p.q0), (-1, p.qf)):
        expected = holding_efforts(p, np.array(q))
        scale = np.abs(expected).max()
        np.testing.assert_allclose(data[row, 10:13], expected, rtol=TIGHT, atol=TIGHT * scale)
    np.testing.assert_array_equal(data[-1, 1:4], p.qf)


def test_summary_without_csv(capsys, seed_csv):
    code, out, err = run(["inverse"], capsys)
    assert code == 0 and err == ""
    _, data = read_csv(seed_csv)
    lines = out.splitlines()
    assert "15001 samples" in lines[0]
    for k, name in enumerate(("T01x", "T12y", "F23z")):
        line = next(x for x in lines if x.startswith(name))
        i = np.argmax(np.abs(data[:, 10 + k]))
        peak, unit, when = line.split()[1:4]
        assert float(peak) == pytest.approx(abs(data[i, 10 + k]), rel=1e-5)
        assert unit == ("N" if name == "F23z" else "N·m")
        assert float(when) == pytest.approx(data[i, 0], abs=1e-9)


def test_wrench_columns(tmp_path, capsys, seed_params):
    path = tmp_path / "w.csv"
    code, out, err = run(["inverse", "--wrenches", "--dt", "0.01", "--csv", str(path)], capsys)
    assert code == 0 and err == f"rrt-pin: wrote {path} (backend pinocchio)\n"
    assert out.startswith("inverse dynamics of the RRT arm") and "|F01| at A" in out
    header, data = read_csv(path)
    assert header == HEADER.split(",") + list(RRT_WRENCH_COLUMNS)
    p = seed_params
    traj = rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, 0.01))
    _, table = wrench_table(joint_wrenches(chapter_arm(p), traj.q, traj.qd, traj.qdd), rrt=True)
    np.testing.assert_array_equal(data[:, 13:], table)


def test_help_documents_units_and_every_column(capsys):
    with pytest.raises(SystemExit):
        main(["inverse", "--help"])
    out = capsys.readouterr().out
    assert "SI units" in out and "[N·m]" in out and "[s]" in out
    for name in HEADER.split(",")[10:] + list(RRT_WRENCH_COLUMNS):
        assert name in out
    assert "tau_<joint>" in out and "fx_<joint>" in out


def test_tf_beyond_tp_rests_and_set_changes_the_arm(tmp_path, capsys):
    path = tmp_path / "o.csv"
    argv = ["inverse", "--tf", "16", "--dt", "0.5", "--set", "m3=50", "--csv", str(path)]
    assert run(argv, capsys)[0] == 0
    _, data = read_csv(path)
    assert data.shape == (33, 13) and data[-1, 0] == 16.0
    p = Params(m3=50.0)
    np.testing.assert_array_equal(data[-3:, 1:4], [p.qf] * 3)
    np.testing.assert_allclose(
        data[-1, 10:13], holding_efforts(p, np.array(p.qf)), rtol=TIGHT, atol=1e-12
    )


def test_scene_options(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text('[params]\nTp = 2.0\n[options]\ndt = 0.25\nq0 = "0,0,0.1"\n')
    path = tmp_path / "o.csv"
    assert run(["inverse", "--scene", str(scene), "--csv", str(path)], capsys)[0] == 0
    _, data = read_csv(path)
    assert data.shape == (9, 13) and data[-1, 0] == 2.0
    np.testing.assert_array_equal(data[0, 1:4], [0, 0, 0.1])


@pytest.mark.skipif(not HAS_KERNEL, reason="rrt_pin/dynamics/kernel.py not generated yet")
def test_symbolic_backend_agrees(tmp_path, capsys, seed_csv):
    path = tmp_path / "sym.csv"
    assert run(["inverse", "--backend", "symbolic", "--csv", str(path)], capsys)[0] == 0
    _, sym = read_csv(path)
    _, ref = read_csv(seed_csv)
    np.testing.assert_array_equal(sym[:, :10], ref[:, :10])
    scale = np.abs(ref[:, 10:]).max(axis=0)
    assert (np.abs(sym[:, 10:] - ref[:, 10:]) / scale).max() <= DERIVED


@pytest.mark.parametrize(
    "robot, q0, qf",
    [
        ("ur5", "0,-1,1,0,1,0", "1,-2,2,-1,0,1"),
        ("panda", "0,0,0,-1.5,0,1.5,0,0,0", "1,-0.5,0.5,-2,0.5,2,1,0.04,0.04"),
    ],
)
def test_other_arms(tmp_path, capsys, robot, q0, qf):
    urdf = robot_urdf(robot)
    path = tmp_path / f"{robot}.csv"
    argv = ["inverse", "--urdf", str(urdf), "--q0", q0, "--qf", qf, "--tf", "2", "--dt", "0.01"]
    code, out, err = run([*argv, "--wrenches", "--csv", str(path)], capsys)
    assert code == 0, err
    model = load_urdf_model(urdf)
    names = list(model.names[1:])
    header, data = read_csv(path)
    assert header[: 1 + 4 * len(names)] == ["t"] + [
        f"{k}_{n}" for k in ("q", "qd", "qdd", "tau") for n in names
    ]
    assert len(header) == 1 + 4 * len(names) + 6 * len(names) and data.shape[0] == 201
    n = model.nv
    q, qd, qdd, tau = (data[:, 1 + k * n : 1 + (k + 1) * n] for k in range(4))
    np.testing.assert_array_equal(q[0], [float(x) for x in q0.split(",")])
    np.testing.assert_array_equal(q[-1], [float(x) for x in qf.split(",")])
    pin_data = model.createData()
    for i in range(0, 201, 20):
        expected = pin.rnea(model, pin_data, q[i], qd[i], qdd[i])
        np.testing.assert_allclose(tau[i], expected, rtol=0, atol=TIGHT * np.abs(expected).max())
    # Summary: one line per joint, named after the URDF's joints.
    code, out, _ = run(argv, capsys)
    assert code == 0 and all(f"tau_{name}" in out for name in names)


def test_other_arm_moves_for_tp_without_tf(tmp_path, capsys):
    path = tmp_path / "ur5.csv"
    argv = ["inverse", "--urdf", str(robot_urdf("ur5")), "--q0", "0,0,0,0,0,0"]
    argv += ["--qf", "1,1,1,1,1,1", "--set", "Tp=2", "--dt", "0.5", "--csv", str(path)]
    assert run(argv, capsys)[0] == 0
    _, data = read_csv(path)
    np.testing.assert_array_equal(data[:, 0], [0, 0.5, 1, 1.5, 2])
    np.testing.assert_array_equal(data[-1, 1:7], np.ones(6))


TWO_JOINTS = """<robot name="two">
  <link name="base"/>
  <joint name="spin" type="{kind}">
    <parent link="base"/><child link="arm"/>
    <origin xyz="0 0 0.1" rpy="0 0 0"/><axis xyz="0 1 0"/>{limit}
  </joint>
  <link name="arm">
    <inertial><origin xyz="0.3 0 0"/><mass value="2"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial>
  </link>
  <joint name="slide" type="prismatic">
    <parent link="arm"/><child link="tip"/>
    <origin xyz="0.6 0 0" rpy="0 0 0"/><axis xyz="1 0 0"/>
    <limit lower="-1" upper="1" effort="100" velocity="1"/>
  </joint>
  <link name="tip">
    <inertial><origin xyz="0 0 0"/><mass value="0.5"/>
      <inertia ixx="0.001" ixy="0" ixz="0" iyy="0.001" iyz="0" izz="0.001"/></inertial>
  </link>
</robot>
"""


@pytest.mark.parametrize("kind", ["continuous", "revolute"])
def test_continuous_joint_and_units(tmp_path, capsys, kind):
    # A continuous joint keeps (cos θ, sin θ) in Pinocchio's q; the CSV holds θ.
    limit = "" if kind == "continuous" else '<limit lower="-9" upper="9" effort="1" velocity="1"/>'
    urdf = tmp_path / "two.urdf"
    urdf.write_text(TWO_JOINTS.format(kind=kind, limit=limit))
    path = tmp_path / "two.csv"
    argv = ["inverse", "--urdf", str(urdf), "--q0", "0,0", "--qf", "2.5,0.3", "--tf", "1"]
    assert run([*argv, "--dt", "0.05", "--csv", str(path)], capsys)[0] == 0
    header, data = read_csv(path)
    assert header == ["t", "q_spin", "q_slide", "qd_spin", "qd_slide"] + [
        "qdd_spin",
        "qdd_slide",
        "tau_spin",
        "tau_slide",
    ]
    model = load_urdf_model(urdf)
    assert model.nq == (3 if kind == "continuous" else 2)
    pin_data = model.createData()
    for row in data:
        theta, x = row[1:3]
        q = np.array([np.cos(theta), np.sin(theta), x] if kind == "continuous" else [theta, x])
        expected = pin.rnea(model, pin_data, q, row[3:5], row[5:7])
        np.testing.assert_allclose(row[7:9], expected, rtol=TIGHT, atol=1e-12)
    code, out, _ = run(argv, capsys)
    assert "tau_spin" in out and "N·m" in out and "tau_slide" in out
    assert next(x for x in out.splitlines() if x.startswith("tau_slide")).split()[2] == "N"


def test_joint_with_several_coordinates_is_refused(tmp_path, capsys):
    urdf = tmp_path / "planar.urdf"
    urdf.write_text(TWO_JOINTS.format(kind="planar", limit="").replace('<axis xyz="0 1 0"/>', ""))
    argv = ["inverse", "--urdf", str(urdf), "--q0", "0,0", "--qf", "1,1"]
    code, out, err = run(argv, capsys)
    assert code == 2 and "joint 'spin'" in err and "Planar joint" in err and err.count("\n") == 1


def test_urdf_gravity_follows_g(tmp_path, capsys):
    urdf = tmp_path / "two.urdf"
    urdf.write_text(TWO_JOINTS.format(kind="continuous", limit=""))
    path = tmp_path / "g0.csv"
    argv = ["inverse", "--urdf", str(urdf), "--q0", "0.3,0.1", "--qf", "0.3,0.1"]
    assert run([*argv, "--set", "g=0", "--dt", "0.5", "--csv", str(path)], capsys)[0] == 0
    _, data = read_csv(path)
    np.testing.assert_array_equal(data[:, 7:9], 0.0)  # at rest, no gravity: no effort


def test_wrenches_summary(capsys):
    code, out, _ = run(["inverse", "--wrenches", "--dt", "0.01"], capsys)
    assert code == 0
    line = next(x for x in out.splitlines() if x.startswith("|F01| at A"))
    p = Params()
    # The base carries at least the arm's weight.
    assert float(line.split()[3]) >= (p.m1 + p.m2 + p.m3) * p.g


def test_plot(tmp_path, capsys):
    png = tmp_path / "efforts.png"
    code, out, err = run(["inverse", "--dt", "0.05", "--plot", str(png)], capsys)
    assert code == 0 and "T01x" in out and err == f"rrt-pin: wrote {png} (backend pinocchio)\n"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_no_geometry_is_built(tmp_path, capsys, monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("geometry built")

    monkeypatch.setattr(rrt_pin.robot.model, "build_geometry", refuse)
    for name in ("buildGeomFromUrdf", "buildGeomFromUrdfString"):
        monkeypatch.setattr(pin, name, refuse)
    assert run(["inverse", "--dt", "0.1", "--csv", str(tmp_path / "a.csv")], capsys)[0] == 0
    urdf = str(robot_urdf("ur5"))
    argv = ["inverse", "--urdf", urdf, "--q0", "0,0,0,0,0,0", "--qf", "1,1,1,1,1,1", "--dt", "0.1"]
    assert run([*argv, "--wrenches", "--csv", str(tmp_path / "b.csv")], capsys)[0] == 0


BAD = [
    (["--dt", "0"], "--dt=0.0 must be > 0"),
    (["--dt", "-1"], "--dt=-1.0 must be > 0"),
    (["--dt", "20"], "--dt=20.0 is larger than --tf=15.0"),
    (["--tf", "1", "--dt", "2"], "--dt=2.0 is larger than --tf=1.0"),
    (["--tf", "0"], "--tf=0.0 must be > 0"),
    (["--tf", "-2"], "--tf=-2.0 must be > 0"),
    (["--tf", "nan"], "argument --tf: must be finite: 'nan'"),
    (["--dt", "inf"], "argument --dt: must be finite: 'inf'"),
    (["--set", "q1f=inf"], "q1f=inf: must be finite"),
    (["--q0", "0,nan,0"], "argument --q0: must be finite: 'nan'"),
    (["--q0", "1,2"], "--q0 has 2 values but the arm has 3 joints (q1, q2, q3)"),
    (["--qf", "1,2,3,4"], "--qf has 4 values but the arm has 3 joints"),
    (["--backend", "fast"], "argument --backend: invalid choice: 'fast'"),
    (["--urdf", "{missing}", "--q0", "0", "--qf", "1"], "cannot read URDF"),
    (["--urdf", "{garbage}", "--q0", "0", "--qf", "1"], "URDF does not parse"),
    (["--urdf", "{ur5}", "--q0", "0,0", "--qf", "0,0"], "--q0 has 2 values but the arm has 6 joints"),
    (["--urdf", "{ur5}", "--q0", "0,0,0,0,0,0", "--qf", "0,0,0,0,0"], "--qf has 5 values"),
    (["--urdf", "{ur5}"], "needs --q0 and --qf (6 values each"),
    (["--urdf", "{ur5}", "--q0", "0,0,0,0,0,0", "--qf", "0,0,0,0,0,0", "--backend", "symbolic"], "--urdf needs --backend pinocchio"),
    (["--urdf", "{ur5}", "--q0", "0,0,0,0,0,0", "--qf", "0,0,0,0,0,0", "--set", "m2=3"], "parameter m2 describes the RRT arm"),
    (["--plot", "{nofolder}"], "cannot write --plot"),
]  # fmt: skip


@pytest.mark.parametrize("extra, words", BAD, ids=[" ".join(b[0])[:40] for b in BAD])
@pytest.mark.parametrize("existing", [False, True], ids=["new", "existing"])
def test_bad_input_one_line_exit_2_nothing_written(tmp_path, capsys, extra, words, existing):
    garbage = tmp_path / "garbage.urdf"
    garbage.write_text("<robot name='x'><link")
    subs = {
        "{missing}": str(tmp_path / "missing.urdf"),
        "{garbage}": str(garbage),
        "{ur5}": str(robot_urdf("ur5")),
        "{nofolder}": str(tmp_path / "nofolder" / "p.png"),
    }
    extra = [subs.get(a, a) for a in extra]
    target = tmp_path / "out.csv"
    if existing:
        target.write_text("precious")
    before = sorted(p.name for p in tmp_path.iterdir())
    code, out, err = run(["inverse", *extra, "--csv", str(target)], capsys)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("rrt-pin") and words in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    if existing:
        assert target.read_text() == "precious"


def test_bad_scene_option(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text("[options]\ntf = -1.0\n")
    code, out, err = run(["inverse", "--scene", str(scene)], capsys)
    assert code == 2 and out == "" and "--tf=-1.0 must be > 0" in err


def test_compiled_backend_is_wired(capsys, monkeypatch):
    # Unavailable: one line, exit 2. Available: its efforts go to the output.
    import rrt_pin.compiled as real  # (the attribute exists, then the import is blocked)
    from rrt_pin.core import backends

    monkeypatch.setattr(backends, "_ENTRIES", {})  # the backend's entries looked up afresh
    monkeypatch.setitem(sys.modules, "rrt_pin.compiled", None)  # makes the import fail
    monkeypatch.delattr(rrt_pin, "compiled", raising=False)
    code, out, err = run(["inverse", "--backend", "compiled", "--dt", "0.5"], capsys)
    assert code == 2 and out == "" and "backend 'compiled' is not available" in err

    # the real package again, its arm kernel replaced: the front door reaches it
    monkeypatch.setitem(sys.modules, "rrt_pin.compiled", real)
    monkeypatch.setattr(rrt_pin, "compiled", real, raising=False)
    calls = []

    class Report:
        def describe(self):
            return "compiled backend loaded from the cache in 0.01 s"

    def inverse_dynamics(q, qd, qdd, params):
        calls.append(q.shape)
        return np.full(q.shape, 7.0)

    monkeypatch.setattr(real, "aot_built", lambda: False)
    monkeypatch.setattr(real, "ensure_compiled", lambda: Report())
    monkeypatch.setattr(real, "inverse_dynamics", inverse_dynamics)
    code, out, err = run(["inverse", "--backend", "compiled", "--dt", "0.5"], capsys)
    assert code == 0 and len(calls) == 1 and "backend compiled" in out and "7 N·m" in out
    assert err == "rrt-pin: compiled backend loaded from the cache in 0.01 s\n"


def run_process(args, cwd):
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, cwd=cwd, check=False
    )


def test_subprocess_csv_imports_only_what_it_needs(tmp_path):
    out = tmp_path / "out.csv"
    proc = run_process(
        ["-X", "importtime", "-m", "rrt_pin", "inverse", "--csv", str(out)], tmp_path
    )
    assert proc.returncode == 0
    imported = {
        line.split("|")[-1].strip().split(".")[0]
        for line in proc.stderr.splitlines()
        if "|" in line
    }
    assert "pinocchio" in imported
    for heavy in ("meshcat", "sympy", "matplotlib", "numba", "selenium", "scipy"):
        assert heavy not in imported, heavy
    assert proc.stderr.splitlines()[-1] == f"rrt-pin: wrote {out} (backend pinocchio)"
    assert out.read_text().count("\n") == 15002


def test_subprocess_bad_input(tmp_path):
    proc = run_process(["-m", "rrt_pin", "inverse", "--dt", "-0.1", "--csv", "x.csv"], tmp_path)
    assert proc.returncode == 2 and proc.stdout == ""
    assert proc.stderr == "rrt-pin: error: --dt=-0.1 must be > 0 [s]\n"
    assert list(tmp_path.iterdir()) == []


def test_wrench_help_names_match_the_library():
    from rrt_pin.robot.robots import chapter_arm

    arm = chapter_arm()
    columns = ("t", *arm.q_names, *arm.qd_names, *arm.qdd_names, *arm.effort_names)
    assert columns == tuple(HEADER.split(","))
    for name in RRT_WRENCH_COLUMNS:
        assert name in command._WRENCH_HELP


@pytest.mark.skipif(not HAS_KERNEL, reason="rrt_pin/dynamics/kernel.py not generated yet")
def test_subprocess_symbolic_backend_needs_no_pinocchio(tmp_path):
    out = tmp_path / "sym.csv"
    args = ["-X", "importtime", "-m", "rrt_pin", "inverse", "--backend", "symbolic"]
    proc = run_process([*args, "--csv", str(out)], tmp_path)
    assert proc.returncode == 0, proc.stderr[-500:]
    imported = {
        line.split("|")[-1].strip().split(".")[0]
        for line in proc.stderr.splitlines()
        if "|" in line
    }
    assert "pinocchio" not in imported and "sympy" not in imported
    assert out.read_text().count("\n") == 15002
