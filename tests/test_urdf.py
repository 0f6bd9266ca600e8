import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from rrt_pin.robot.params import Params
from rrt_pin.robot.urdf import urdf_xml

ROOT = Path(__file__).resolve().parents[1]
COMMITTED = ROOT / "urdf" / "rrt.urdf"


def test_committed_urdf_is_the_generators_output():
    assert COMMITTED.read_text(encoding="utf-8") == urdf_xml(Params())


def test_cli_prints_the_committed_urdf():
    out = subprocess.run(
        [sys.executable, "-m", "rrt_pin", "urdf"], capture_output=True, text=True, check=True
    )
    assert out.stdout == COMMITTED.read_text(encoding="utf-8")


def _check_urdf() -> str | None:
    found = shutil.which("check_urdf", path=str(Path(sys.executable).parent))
    return found


def test_check_urdf_accepts_it(tmp_path):
    exe = _check_urdf()
    assert exe, "check_urdf from the pin wheel is missing from the venv"
    out = subprocess.run([exe, str(COMMITTED)], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    assert "Successfully Parsed XML" in out.stdout
    assert "child(1):  link3" in out.stdout


def test_check_urdf_rejects_a_broken_one(tmp_path):
    # Shows the check above can fail: drop the parent of joint q2.
    broken = tmp_path / "broken.urdf"
    broken.write_text(urdf_xml().replace('<parent link="link1"/>', ""))
    out = subprocess.run([_check_urdf(), str(broken)], capture_output=True, text=True)
    assert out.returncode != 0


def test_yourdfpy_loads_it():
    yourdfpy = pytest.importorskip("yourdfpy")
    robot = yourdfpy.URDF.load(str(COMMITTED), build_scene_graph=True, load_meshes=False)
    assert robot.actuated_joint_names == ["q1", "q2", "q3"]
    p = Params()
    robot.update_cfg(np.array(p.q0))
    # yourdfpy's forward kinematics: the slider's frame is C3 (seed: rC3 = rC2 + q3·k2).
    from tests.support import mass_centres, seed_to_world

    T = robot.get_transform("link3", "world")
    np.testing.assert_allclose(T[:3, 3], seed_to_world(mass_centres(p, p.q0)[2]), atol=1e-14)


def test_joint_types_and_axes():
    root = ET.fromstring(urdf_xml())
    joints = {j.get("name"): j for j in root.iter("joint")}
    assert joints["mount"].get("type") == "fixed"
    assert [joints[n].get("type") for n in ("q1", "q2", "q3")] == [
        "revolute",
        "revolute",
        "prismatic",
    ]
    assert [joints[n].find("axis").get("xyz") for n in ("q1", "q2", "q3")] == [
        "1 0 0",
        "0 1 0",
        "0 0 1",
    ]
    for n in ("q1", "q2"):
        lim = joints[n].find("limit")
        assert float(lim.get("lower")) <= -2 * np.pi and float(lim.get("upper")) >= 2 * np.pi


def test_visuals_are_primitives_sized_from_the_parameters():
    root = ET.fromstring(urdf_xml(Params(L2=2.0)))
    rod2 = [v for v in root.iter("visual") if v.get("name") == "rod2"][0]
    assert float(rod2.find("geometry/cylinder").get("length")) == 4.0
    shapes = {c.tag for v in root.iter("visual") for c in v.find("geometry")}
    assert shapes <= {"cylinder", "box", "sphere"}


def test_min_inertia_option_only_raises_zero_moments():
    root = ET.fromstring(urdf_xml(min_inertia=1e-6))
    inertias = [i.find("inertia") for i in root.iter("inertial")]
    assert [float(i.get("izz")) for i in inertias] == [1e-6, 1e-6, 1.0]
    assert float(inertias[2].get("ixx")) == 5.0
