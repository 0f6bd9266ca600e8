"""The viewer without a browser: keyframes, scene data, meshcat commands, CSV input, the server."""

from __future__ import annotations

import asyncio
import json
import math
import os
import signal
import socket
import subprocess
import sys
import urllib.request

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.errors import InputError, ViewerError
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.io.csvio import write_csv
from rrt_pin.robot.model import build_geometry, rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.urdf import urdf_xml
from rrt_pin.viewer import build_drawing, keyframe_times, resample
from rrt_pin.viewer.keyframes import frame_placements
from tests.support import TIGHT, mass_centres, seed_to_world, unit_vectors

FPS = 30.0


@pytest.fixture(scope="module")
def seed_scene():
    p = Params()
    model = rrt_model(p)
    geometry = build_geometry(model, urdf_xml(p))
    t = keyframe_times(p.Tp, FPS)
    q = rest_to_rest(p.q0, p.qf, p.Tp, t).q
    return p, model, geometry, build_drawing(model, geometry, t, q, FPS, ghost_q=np.asarray(p.qf))


# ---------------------------------------------------------------------------
# Keyframe times and resampling
# ---------------------------------------------------------------------------
def test_fifteen_seconds_at_30_fps_is_451_keyframes():
    t = keyframe_times(15.0, 30.0)
    assert t.shape == (451,)
    assert t[0] == 0.0 and t[-1] == 15.0
    assert np.array_equal(t[:-1], np.arange(450) / 30.0)
    assert np.allclose(np.diff(t), 1 / 30.0, rtol=0, atol=1e-12)


@pytest.mark.parametrize(
    "duration, fps, expected",
    [
        (1.0, 3.0, [0.0, 1 / 3, 2 / 3, 1.0]),
        (1.01, 3.0, [0.0, 1 / 3, 2 / 3, 1.0, 1.01]),  # last interval shorter, end kept
        (0.0, 30.0, [0.0]),
        (0.01, 30.0, [0.0, 0.01]),
    ],
)
def test_keyframe_times_keep_both_ends(duration, fps, expected):
    assert np.allclose(keyframe_times(duration, fps), expected, rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    "duration, fps, words",
    [
        (-1.0, 30.0, "duration=-1.0"),
        (math.nan, 30.0, "duration=nan"),
        (1.0, 0.0, "fps=0.0"),
        (1.0, math.inf, "fps=inf"),
        (15.0, 1e6, "15,000,001 keyframes; at most 100,000"),
    ],
)
def test_keyframe_times_refuse_bad_values(duration, fps, words):
    with pytest.raises(InputError, match=words):
        keyframe_times(duration, fps)


def test_resampling_reproduces_linear_data_and_hits_samples_exactly(rng):
    # irregular samples of a straight line: linear interpolation is exact
    t = np.sort(np.concatenate([[0.0, 2.0], rng.uniform(0.0, 2.0, 37)]))
    q = np.column_stack([3.0 * t - 1.0, -0.5 * t + 0.25])
    times, values = resample(t, q, 10.0)
    assert times.shape == (21,) and times[0] == 0.0 and times[-1] == 2.0
    assert np.allclose(values[:, 0], 3.0 * times - 1.0, rtol=0, atol=TIGHT)
    assert np.allclose(values[:, 1], -0.5 * times + 0.25, rtol=0, atol=TIGHT)
    # samples that fall on keyframe times come back unchanged
    t2 = np.arange(0, 61) / 60.0 + 5.0
    q2 = np.sin(7.0 * t2)[:, None]
    times2, values2 = resample(t2, q2, 30.0)
    assert np.allclose(times2, t2[::2], rtol=0, atol=1e-12)
    assert np.allclose(values2[:, 0], q2[::2, 0], rtol=0, atol=TIGHT)


def test_resampling_error_is_within_the_linear_interpolation_bound():
    # sin(ωt) sampled every h: |error| <= h²/8 · ω² (max |f''|)
    h, w = 1e-3, 2.0
    t = np.arange(0, 3001) * h
    times, values = resample(t, np.sin(w * t)[:, None], 30.0)
    assert times.size == 91
    err = np.abs(values[:, 0] - np.sin(w * times)).max()
    assert err <= h * h / 8 * w * w * 1.0001


@pytest.mark.parametrize(
    "t, q, words",
    [
        ([0.0, 1.0, 1.0], [[0.0], [1.0], [2.0]], r"t\[2\]=1 s follows t\[1\]=1 s"),
        ([0.0, 2.0, 1.0], [[0.0], [1.0], [2.0]], r"t\[2\]=1 s follows t\[1\]=2 s"),
        ([0.0, 1.0 + 2e-16, 1.0], [[0], [1], [2]], r"t\[2\]=1 s follows t\[1\]=1.0000000000000002"),
        ([0.0, 1.0], [[0.0], [math.nan]], r"q\[1, 0\]=nan is not finite \(at t\[1\]=1 s\)"),
        ([0.0, math.inf], [[0.0], [1.0]], r"t\[1\]=inf is not finite"),
        ([0.0, 1.0], [[0.0]], "q.shape"),
    ],
)
def test_resampling_refuses_bad_samples(t, q, words):
    with pytest.raises(InputError, match=words):
        resample(np.array(t), np.array(q), 30.0)


# ---------------------------------------------------------------------------
# Link placements against the seed's own kinematics
# ---------------------------------------------------------------------------
def test_frame_placements_match_the_seed_kinematics(seed_model, seed_params, rng):
    q = np.column_stack(
        [rng.uniform(-np.pi, np.pi, 20), rng.uniform(-np.pi, np.pi, 20), rng.uniform(-0.5, 1, 20)]
    )
    ids = [seed_model.getFrameId(n) for n in ("link1", "link2", "link3")]
    placed = frame_placements(seed_model, q, ids)
    assert placed.shape == (20, 3, 4, 4)
    for k, qk in enumerate(q):
        i1, j1, k1, i2, j2, k2 = (seed_to_world(v) for v in unit_vectors(qk[0], qk[1]))
        _, _, rC3 = mass_centres(seed_params, qk)
        B = seed_to_world(seed_params.LB * unit_vectors(qk[0], qk[1])[2])
        # link1: origin A, axes (ı1, ȷ1, k1); link2: origin B, axes of (2); link3 at C3
        assert np.allclose(placed[k, 0, :3, 3], 0.0, atol=TIGHT)
        assert np.allclose(placed[k, 0, :3, :3], np.column_stack([i1, j1, k1]), atol=TIGHT)
        assert np.allclose(placed[k, 1, :3, 3], B, atol=TIGHT)
        assert np.allclose(placed[k, 1, :3, :3], np.column_stack([i2, j2, k2]), atol=TIGHT)
        assert np.allclose(placed[k, 2, :3, 3], seed_to_world(rC3), atol=TIGHT)


def test_keyframes_times_shapes_and_placements(seed_scene):
    p, model, geometry, scene = seed_scene
    kf = scene.keyframes
    assert kf.t.shape == (451,) and kf.fps == FPS and kf.duration == 15.0
    assert kf.frames == ("link1", "link2", "link3")  # link0 (the post) does not move
    assert [f for f, _ in scene.static] == ["link0"]
    assert kf.transforms.shape == (451, 3, 4, 4)
    # each keyframe equals pin.forwardKinematics at eq. (30)'s q(t)
    data = model.createData()
    q_expected = rest_to_rest(p.q0, p.qf, p.Tp, kf.t).q
    assert np.allclose(kf.q, q_expected, rtol=0, atol=TIGHT)
    for k in (0, 100, 225, 450):
        pin.forwardKinematics(model, data, q_expected[k])
        for i in range(3):
            assert np.allclose(kf.transforms[k, i], data.oMi[i + 1].homogeneous, atol=TIGHT)


def test_shapes_placed_by_keyframes_equal_pinocchio_geometry_placements(seed_scene):
    p, model, geometry, scene = seed_scene
    gdata = geometry.createData()
    data = model.createData()
    kf = scene.keyframes
    where = {f: kf.transforms[:, i] for i, f in enumerate(kf.frames)}
    where.update({f: np.broadcast_to(T, (kf.t.size, 4, 4)) for f, T in scene.static})
    names = [g.name for g in geometry.geometryObjects]
    assert [s.name for s in scene.shapes] == names
    for k in (0, 300, 450):
        pin.forwardKinematics(model, data, kf.q[k])
        pin.updateGeometryPlacements(model, data, geometry, gdata)
        for s in scene.shapes:
            expected = gdata.oMg[names.index(s.name)].homogeneous
            assert np.allclose(where[s.frame][k] @ s.local, expected, atol=TIGHT)


def test_shapes_keep_the_urdf_colours_and_sizes(seed_scene):
    p, _, _, scene = seed_scene
    by_name = {s.name: s for s in scene.shapes}
    rod1, rod2, slider = by_name["link1_0"], by_name["link2_0"], by_name["link3_0"]
    assert rod1.kind == "cylinder" and rod1.frame == "link1"
    assert np.allclose(rod1.rgba, (0.95, 0.5, 0.1, 1.0), atol=1e-7)
    assert np.allclose(rod1.size, (0.12 * p.L1, 2 * p.L1))
    assert rod2.kind == "cylinder" and np.allclose(rod2.rgba, (0.15, 0.4, 0.85, 1.0), atol=1e-7)
    assert slider.kind == "box" and np.allclose(slider.rgba, (0.2, 0.7, 0.3, 1.0), atol=1e-7)
    assert np.allclose(slider.size, (0.2 * p.L2, 0.2 * p.L2, 0.4 * p.L2))


def test_scene_ground_path_ghost_and_bounds(seed_scene):
    p, model, _, scene = seed_scene
    # the post reaches down to z = -2·L1: the ground grid lies there
    assert scene.ground_z == pytest.approx(-2 * p.L1, abs=1e-12)
    assert np.allclose(scene.grid[:, 2], -2 * p.L1, atol=1e-12)
    assert scene.grid.shape[0] % 2 == 0
    assert scene.grid[:, 0].min() <= scene.lo[0] and scene.grid[:, 0].max() >= scene.hi[0]
    assert scene.grid[:, 1].min() <= scene.lo[1] and scene.grid[:, 1].max() >= scene.hi[1]
    # the path is C3's, from C3(q0) to C3(qf)
    assert scene.path_frame == "link3" and scene.path.shape == (451, 3)
    assert np.allclose(scene.path[0], seed_to_world(mass_centres(p, p.q0)[2]), atol=TIGHT)
    assert np.allclose(scene.path[-1], seed_to_world(mass_centres(p, p.qf)[2]), atol=TIGHT)
    # the ghost stands at qf
    ghost = dict(scene.ghost)
    assert set(ghost) == {"link0", "link1", "link2", "link3"}
    assert np.allclose(ghost["link3"][:3, 3], seed_to_world(mass_centres(p, p.qf)[2]), atol=TIGHT)
    # everything drawn lies inside the bounds
    assert np.all(scene.path >= scene.lo - 1e-12) and np.all(scene.path <= scene.hi + 1e-12)
    assert scene.hi[2] > seed_to_world(mass_centres(p, p.qf)[2])[2]


def test_camera_sees_every_corner_of_the_scene(seed_scene):
    _, _, _, scene = seed_scene
    view = scene.camera
    eye = view.center + view.offset
    forward = -view.offset / np.linalg.norm(view.offset)
    right = np.cross(forward, [0, 0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    lo = scene.lo.copy()
    lo[2] = scene.ground_z
    assert view.fov_deg == 40.0
    tan_v = math.tan(math.radians(view.fov_deg / 2))
    for x in (lo[0], scene.hi[0]):
        for y in (lo[1], scene.hi[1]):
            for z in (lo[2], scene.hi[2]):
                v = np.array([x, y, z]) - eye
                depth = v @ forward
                assert depth > 0
                assert abs(v @ up) / depth <= tan_v
                assert abs(v @ right) / depth <= tan_v * 1.6


# ---------------------------------------------------------------------------
# meshcat commands (plain data: lowered and packed, nothing sent)
# ---------------------------------------------------------------------------
def test_animation_has_one_clip_per_moving_link_with_exact_keyframes(seed_scene):
    from rrt_pin.viewer.meshcat_scene import animation

    _, _, _, scene = seed_scene
    lowered = animation(scene).lower()
    assert [c["path"] for c in lowered] == [
        "/meshcat/arm/link1",
        "/meshcat/arm/link2",
        "/meshcat/arm/link3",
    ]
    kf = scene.keyframes
    for i, clip in enumerate(lowered):
        assert clip["clip"]["fps"] == FPS
        tracks = {tr["name"]: tr for tr in clip["clip"]["tracks"]}
        assert set(tracks) == {".position", ".quaternion"}
        keys = tracks[".position"]["keys"]
        assert len(keys) == 451
        # three.js reads key time / fps as seconds
        assert np.allclose([k["time"] / FPS for k in keys], kf.t, rtol=0, atol=1e-12)
        assert np.allclose([k["value"] for k in keys], kf.transforms[:, i, :3, 3], atol=TIGHT)
        quats = np.array([k["value"] for k in tracks[".quaternion"]["keys"]])
        for k in (0, 200, 450):
            x, y, z, w = quats[k]
            R = pin.Quaternion(w, x, y, z).toRotationMatrix()
            assert np.allclose(R, kf.transforms[k, i, :3, :3], atol=1e-12)
        # consecutive quaternions on the same side: interpolation takes the short way
        assert (np.einsum("ij,ij->i", quats[1:], quats[:-1]) > 0).all()


def test_scene_commands_lower_and_pack(seed_scene):
    import umsgpack

    from rrt_pin.viewer.meshcat_scene import scene_commands

    _, _, _, scene = seed_scene
    commands = scene_commands(scene, loop=True)
    lowered = [c.lower() for c in commands]
    for low in lowered:
        umsgpack.packb(low)
    kinds = [low["type"] for low in lowered]
    assert kinds[-1] == "set_animation" and kinds.count("set_animation") == 1
    assert lowered[-1]["options"] == {"play": True, "repetitions": math.inf}
    objects = {low["path"]: low["object"] for low in lowered if low["type"] == "set_object"}
    arm = {p for p in objects if p.startswith("/meshcat/arm/")}
    assert arm == {
        "/meshcat/arm/link0/link0_0",
        "/meshcat/arm/link1/link1_0",
        "/meshcat/arm/link1/link1_1",
        "/meshcat/arm/link2/link2_0",
        "/meshcat/arm/link3/link3_0",
    }
    assert {p.replace("ghost", "arm") for p in objects if p.startswith("/meshcat/ghost/")} == arm
    # the URDF's colours: link 1 orange 0.95 0.5 0.1
    rod1 = objects["/meshcat/arm/link1/link1_0"]
    assert rod1["materials"][0]["color"] == (242 << 16) | (128 << 8) | 26
    ghost_rod = objects["/meshcat/ghost/link1/link1_0"]["materials"][0]
    assert ghost_rod["transparent"] and ghost_rod["opacity"] == pytest.approx(0.3)
    assert objects["/meshcat/path"]["object"]["type"] == "Line"
    assert objects["/meshcat/ground"]["object"]["type"] == "LineSegments"
    once = scene_commands(scene, loop=False, play=False, ghost=False)
    assert once[-1].lower()["options"] == {"play": False, "repetitions": 1}
    assert not any(c.lower()["path"].startswith("/meshcat/ghost") for c in once)


def test_cylinders_turn_from_three_js_y_to_urdf_z(seed_scene):
    from rrt_pin.viewer.meshcat_scene import shape_object

    _, _, _, scene = seed_scene
    rod1 = next(s for s in scene.shapes if s.name == "link1_0")
    [(name, obj, transform)] = shape_object(rod1)
    assert name == "link1_0" and obj.lower()["geometries"][0]["type"] == "CylinderGeometry"
    # the drawn cylinder's axis (its local y) is the URDF cylinder's axis (local z)
    assert np.allclose(transform[:3, 1], rod1.local[:3, 2], atol=TIGHT)
    assert np.allclose(transform[:3, 3], rod1.local[:3, 3], atol=TIGHT)


def test_meshes_of_another_urdf_become_meshcat_meshes():
    from rrt_pin.robot.model import load_urdf_model
    from rrt_pin.viewer.meshcat_scene import shape_object
    from tests.support import robot_urdf

    path = robot_urdf("ur5")
    model = load_urdf_model(path)
    dirs = [str(d) for d in path.resolve().parents]
    geometry = build_geometry(model, path.read_text(), package_dirs=dirs)
    t = keyframe_times(1.0, 10.0)
    q = np.outer(t, np.full(model.nq, 0.5))
    drawing = build_drawing(model, geometry, t, q, 10.0)
    assert len(drawing.shapes) == 7 and {s.kind for s in drawing.shapes} == {"mesh"}
    assert drawing.keyframes.frames[0] == "shoulder_link" and drawing.ground_z <= 0.0
    name, obj, _ = shape_object(drawing.shapes[1])[0]
    assert obj.lower()["geometries"][0]["format"] == "dae"


# ---------------------------------------------------------------------------
# The command's input checks: one line, exit 2, no server started
# ---------------------------------------------------------------------------
def _csv(tmp_path, header, rows, name="traj.csv"):
    path = tmp_path / name
    path.write_text(",".join(header) + "\n" + "".join(",".join(map(str, r)) + "\n" for r in rows))
    return str(path)


@pytest.mark.parametrize(
    "header, rows, words",
    [
        (["t", "q1", "q2"], [[0, 0, 0], [1, 0, 0]], "lacks column 'q3'"),
        (["time", "q1", "q2", "q3"], [[0, 0, 0, 0]], "lacks column 't'"),
        (
            ["t", "q1", "q2", "q3"],
            [[0, 0, 0, 0], [1, "nan", 0, 0]],
            "traj.csv' line 3, column 'q1': 'nan' is not a finite number",
        ),
        (
            ["t", "q1", "q2", "q3"],
            [[0, 0, 0, 0], [1, 0, "inf", 0]],
            "traj.csv' line 3, column 'q2': 'inf' is not a finite number",
        ),
        (
            ["t", "q1", "q2", "q3"],
            [[0, 0, 0, 0], [0, 1, 0, 0]],
            "line 3, column 't': times must increase strictly, but 0 s follows 0 s (line 2)",
        ),
        (
            ["t", "q1", "q2", "q3"],
            [[0, 0, 0, 0], [1, 0, "x", 0]],
            "traj.csv' line 3, column 'q2': 'x' is not a number",
        ),
        (["t", "q1", "q2", "q3"], [], "no data rows"),
    ],
)
def test_bad_csv_is_refused_in_one_line(tmp_path, capsys, header, rows, words):
    path = _csv(tmp_path, header, rows)
    code = main(["view", "--trajectory", path, "--port", "0", "--serve-for", "0"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("rrt-pin: error: "), err
    for word in (words,) if isinstance(words, str) else words:
        assert word in err, err


def test_bad_csv_as_a_process_prints_one_line(tmp_path):
    for rows in ([], [[0, 0, 0, 0], [1, "nan", 0, 0]]):
        path = _csv(tmp_path, ["t", "q1", "q2", "q3"], rows)
        proc = subprocess.run(
            [sys.executable, "-m", "rrt_pin", "view", "--trajectory", path, "--serve-for", "0"],
            capture_output=True,
            text=True,
        )
        assert proc.returncode == 2 and proc.stdout == ""
        assert proc.stderr.count("\n") == 1 and proc.stderr.startswith("rrt-pin: error: CSV")


@pytest.mark.parametrize(
    "argv, words",
    [
        (["--trajectory", "nosuch.csv"], "expected inverse, simulate or the path of a CSV file"),
        (["--fps", "0"], "must be > 0"),
        (["--fps", "nan"], "must be finite"),
        (["--port", "70000"], "must be in 0..65535"),
        (["--serve-for", "-1"], "must be >= 0"),
        (["--screenshot", "/no/such/folder/x.png"], "folder '/no/such/folder' does not exist"),
        (["--screenshot-size", "big"], "expected WIDTHxHEIGHT"),
        (["--q0", "1,2"], "--q0 has 2 values but the arm has 3 joints"),
        (["--set", "L1=-1"], "L1=-1.0: must be > 0"),
    ],
)
def test_bad_options_are_refused_in_one_line(capsys, argv, words):
    code = main(["view", "--port", "0", "--serve-for", "0", *argv])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and words in err, err


def test_urdf_needs_its_own_configurations(tmp_path, capsys):
    from tests.support import robot_urdf

    path = str(robot_urdf("ur5"))
    code = main(["view", "--urdf", path, "--port", "0", "--serve-for", "0"])
    assert code == 2 and "--trajectory inverse for ur5 needs --q0" in capsys.readouterr().err
    code = main(["view", "--urdf", path, "--trajectory", "simulate", "--serve-for", "0"])
    assert code == 2 and "--trajectory simulate for ur5 needs" in capsys.readouterr().err
    bad = _csv(tmp_path, ["t", "q_shoulder_pan_joint"], [[0, 0]])
    code = main(["view", "--urdf", path, "--trajectory", bad, "--serve-for", "0"])
    err = capsys.readouterr().err
    assert code == 2 and "lacks column 'q_shoulder_lift_joint'" in err and err.count("\n") == 1


URDF_WITH_A_MISSING_MESH = """<?xml version="1.0"?>
<robot name="m">
  <link name="base"><visual><geometry><box size="0.2 0.2 0.1"/></geometry></visual>
    <visual><origin xyz="0 0 0.3"/><geometry><sphere radius="0.05"/></geometry></visual></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="arm">
    <inertial><origin xyz="0.5 0 0"/><mass value="1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><origin xyz="0.5 0 0"/><geometry><box size="1 0.1 0.1"/></geometry></visual>
    <visual><geometry><mesh filename="package://nowhere/meshes/tool.stl"/></geometry></visual>
  </link>
</robot>
"""


def test_meshes_that_cannot_be_found_are_skipped_with_a_warning(tmp_path, capsys):
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(URDF_WITH_A_MISSING_MESH)
    csv = _csv(tmp_path, ["t", "j1"], [[0, 0], [1, 1.5]])
    code = main(
        ["view", "--urdf", str(urdf), "--trajectory", csv, "--port", "0", "--serve-for", "0"]
    )
    out, err = capsys.readouterr()
    assert code == 0 and out.startswith("http://127.0.0.1:")
    warning = err.splitlines()[0]
    assert warning.startswith(
        "rrt-pin: warning: mesh file package://nowhere/meshes/tool.stl could not be found; "
        "drawing the URDF without its meshes"
    )
    assert "ROS_PACKAGE_PATH" in warning  # and how to make them found


def test_spheres_and_boxes_of_another_urdf():
    from rrt_pin.robot.model import model_from_xml
    from rrt_pin.viewer import visual_shapes
    from rrt_pin.viewer.meshcat_scene import shape_object
    from rrt_pin.viewer.show import _without_meshes

    xml = _without_meshes(URDF_WITH_A_MISSING_MESH)
    assert "mesh" not in xml and xml.count("<visual") == 3
    model = model_from_xml(xml)
    shapes = visual_shapes(model, build_geometry(model, xml))
    assert [(s.frame, s.kind) for s in shapes] == [
        ("base", "box"),
        ("base", "sphere"),
        ("arm", "box"),
    ]
    [(_, sphere, placed)] = shape_object(shapes[1])
    assert sphere.lower()["geometries"][0] == {
        "uuid": sphere.geometry.uuid,
        "type": "SphereGeometry",
        "radius": 0.05,
        "widthSegments": 20,
        "heightSegments": 20,
    }
    assert np.allclose(placed[:3, 3], [0, 0, 0.3])


def test_a_csv_needs_no_dynamics_and_is_resampled(tmp_path):
    """A CSV at 1 kHz of eq. (30) becomes the keyframes of eq. (30) at 30 fps."""
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.viewer.playback import motion_keyframes

    p = Params()
    t = np.arange(0, 15001) * 1e-3
    tr = rest_to_rest(p.q0, p.qf, p.Tp, t)
    path = tmp_path / "inverse.csv"
    write_csv(path, ["t", "q1", "q2", "q3", "T01x"], np.column_stack([t, tr.q, t]))
    frames = motion_keyframes(chapter_arm(p), str(path), 30.0)
    times, q, ghost = frames.t, frames.q, frames.ghost
    assert times.shape == (451,) and times[-1] == 15.0
    # linear interpolation of 1 kHz samples: error <= h²/8 · max|q̈|
    bound = 1e-6 / 8 * np.abs(tr.qdd).max(axis=0)
    assert (np.abs(q - rest_to_rest(p.q0, p.qf, p.Tp, times).q) <= bound + 1e-15).all()
    assert np.allclose(ghost, p.qf)


def test_urdf_csv_columns(tmp_path):
    """q_<joint> (as `rrt-pin inverse --urdf` writes), the joint names and q1..qn all work."""
    from rrt_pin.robot.robot import Robot
    from rrt_pin.viewer.playback import motion_keyframes
    from tests.support import robot_urdf

    path = robot_urdf("ur5")
    robot = Robot.from_urdf(path)
    names = [j.name for j in robot.joints]
    values = np.linspace(0, 1, 6 * 3).reshape(3, 6)
    for header in ([f"q_{n}" for n in names], names, [f"q{k + 1}" for k in range(6)]):
        csv = tmp_path / "ur5.csv"
        write_csv(csv, ["t", *header], np.column_stack([[0.0, 0.5, 1.0], values]))
        frames = motion_keyframes(robot, str(csv), 30.0)
        times, q, ghost = frames.t, frames.q, frames.ghost
        assert times.shape == (31,)
        assert np.allclose(q[0], values[0]) and np.allclose(q[-1], values[-1])
        assert np.allclose(ghost, values[-1])  # the ghost: the CSV's last pose


def test_importing_the_package_and_the_cli_does_not_import_meshcat():
    code = (
        "import sys, rrt_pin, rrt_pin.cli.app, rrt_pin.viewer, rrt_pin.cli.commands.view\n"
        "rrt_pin.cli.app.build_parser()\n"
        "print(sorted(m for m in ('meshcat', 'tornado', 'zmq', 'selenium') if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


# ---------------------------------------------------------------------------
# The server: ports, host, static files, websocket protocol
# ---------------------------------------------------------------------------
def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _listening_socket(port: int) -> socket.socket:
    s = socket.socket()
    s.bind(("127.0.0.1", port))
    s.listen()
    return s


def test_taken_default_port_moves_to_the_next_free_one(monkeypatch, capsys):
    import rrt_pin.viewer.server as server

    taken = _listening_socket(0)
    port = taken.getsockname()[1]
    monkeypatch.setattr(server, "DEFAULT_PORT", port)
    try:
        with server.ViewerServer() as srv:
            assert srv.port > port and srv.moved
            assert srv.url == f"http://127.0.0.1:{srv.port}/static/"
        code = main(["view", "--serve-for", "0"])
        out, err = capsys.readouterr()
        assert code == 0
        moved_to = int(out.strip().rsplit(":", 1)[1].split("/")[0])
        assert moved_to > port
        assert f"port {port} is in use; serving on port {moved_to}" in err
    finally:
        taken.close()


def test_explicit_port_that_is_taken_fails_in_one_line(capsys):
    taken = _listening_socket(0)
    port = taken.getsockname()[1]
    try:
        with pytest.raises(ViewerError, match=f"port {port} on 127.0.0.1 is already in use"):
            from rrt_pin.viewer.server import ViewerServer

            ViewerServer(port=port)
        code = main(["view", "--port", str(port), "--serve-for", "0"])
        out, err = capsys.readouterr()
        assert code == 2 and out == ""
        assert err == f"rrt-pin: error: port {port} on 127.0.0.1 is already in use\n"
    finally:
        taken.close()


def test_server_listens_on_loopback_only_and_serves_meshcat_locally():
    from rrt_pin.viewer.server import ViewerServer

    with ViewerServer(port=0) as srv:
        assert {s.getsockname()[0] for s in srv._sockets} == {"127.0.0.1"}
        html = urllib.request.urlopen(srv.url, timeout=10).read().decode()
        assert '<script type="text/javascript" src="main.min.js"></script>' in html
        # no CDN: the page loads nothing from another host
        assert "http://" not in html.replace("http://www.w3.org", "") and "https://" not in html
        js = urllib.request.urlopen(srv.url + "main.min.js", timeout=10)
        assert js.status == 200 and len(js.read()) > 100_000
        root = urllib.request.urlopen(f"http://127.0.0.1:{srv.port}/", timeout=10)
        assert root.url == srv.url  # a plain GET of / redirects to the page
    with pytest.raises(OSError):
        urllib.request.urlopen(srv.url, timeout=2)


def test_every_websocket_client_gets_the_scene_then_live_commands(seed_scene):
    """Two clients at once (the protocol the page speaks; browsers in test_viewer_browser)."""
    import umsgpack
    from meshcat.commands import SetProperty
    from meshcat.path import Path
    from tornado.websocket import websocket_connect

    from rrt_pin.viewer.meshcat_scene import scene_commands
    from rrt_pin.viewer.server import ViewerServer

    _, _, _, scene = seed_scene
    commands = scene_commands(scene)
    with ViewerServer(port=0) as srv:
        for c in commands:
            srv.send(c)

        async def watch() -> list[list[dict]]:
            url = f"ws://127.0.0.1:{srv.port}/"
            clients = [await websocket_connect(url), await websocket_connect(url)]
            got: list[list[dict]] = [[], []]
            for i, ws in enumerate(clients):
                while len(got[i]) < len(commands):
                    got[i].append(umsgpack.unpackb(await asyncio.wait_for(ws.read_message(), 10)))
            for _ in range(100):
                if srv.n_clients == 2:
                    break
                await asyncio.sleep(0.02)
            assert srv.n_clients == 2
            await asyncio.get_running_loop().run_in_executor(
                None, srv.send, SetProperty("visible", False, Path(("meshcat", "arm")))
            )
            for i, ws in enumerate(clients):
                got[i].append(umsgpack.unpackb(await asyncio.wait_for(ws.read_message(), 10)))
                ws.close()
            return got

        got = asyncio.run(watch())
    for messages in got:
        assert len(messages) == len(commands) + 1
        # the animation comes after every object, so a page that has it has everything
        assert [m["type"] for m in messages[:-1]].index("set_animation") == len(commands) - 1
        assert messages[-1] == {
            "type": "set_property",
            "path": "/meshcat/arm",
            "property": "visible",
            "value": False,
        }
    assert json.dumps(sorted(m["path"] for m in got[0][:-1])) == json.dumps(
        sorted(c.lower()["path"] for c in commands)
    )


# ---------------------------------------------------------------------------
# The command as a process: it starts no other process and leaves nothing behind
# ---------------------------------------------------------------------------
def _start_view(*argv: str) -> tuple[subprocess.Popen, str]:
    proc = subprocess.Popen(
        [sys.executable, "-m", "rrt_pin", "view", "--port", "0", *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    url = proc.stdout.readline().strip()
    if not url.startswith("http://127.0.0.1:"):
        proc.kill()
        raise AssertionError(f"no URL on stdout: {url!r}; stderr: {proc.communicate()[1]}")
    return proc, url


def _listening_ports(pid: int) -> set[tuple[str, int]]:
    import psutil

    return {
        (c.laddr.ip, c.laddr.port)
        for c in psutil.Process(pid).net_connections(kind="inet")
        if c.status == psutil.CONN_LISTEN
    }


def test_serve_for_ends_the_server_and_starts_no_process():
    import psutil

    proc, url = _start_view("--serve-for", "3")
    try:
        assert urllib.request.urlopen(url, timeout=10).status == 200
        # one process: no meshcat-server, no zmq broker, no other child
        assert psutil.Process(proc.pid).children(recursive=True) == []
        port = int(url.split(":")[2].split("/")[0])
        assert _listening_ports(proc.pid) == {("127.0.0.1", port)}
        assert proc.wait(30) == 0
    finally:
        proc.kill()
    err = proc.stderr.read()
    assert "Traceback" not in err
    with pytest.raises(OSError):
        urllib.request.urlopen(url, timeout=2)


@pytest.mark.parametrize(
    "signum", [signal.SIGINT, signal.SIGTERM, signal.SIGHUP], ids=["SIGINT", "SIGTERM", "SIGHUP"]
)
def test_a_signal_ends_the_server_cleanly(signum):
    proc, url = _start_view("--serve-for", "300")
    try:
        assert urllib.request.urlopen(url, timeout=10).status == 200
        os.kill(proc.pid, signum)
        assert proc.wait(30) == 0
    finally:
        proc.kill()
    err = proc.stderr.read()
    assert err.splitlines()[-1] == "rrt-pin: viewer stopped" and "Traceback" not in err
    assert "Controls → Animations" in err and "Ctrl-C stops" in err  # the hints came first
    with pytest.raises(OSError):
        urllib.request.urlopen(url, timeout=2)


def test_the_server_is_a_meshcat_window():
    import meshcat
    import meshcat.geometry as g

    from rrt_pin.viewer.server import ViewerServer, url_host

    with ViewerServer(port=0) as srv:
        vis = meshcat.Visualizer(window=srv)
        assert vis.url() == srv.url
        vis["box"].set_object(g.Box([1.0, 2.0, 3.0]))
        assert srv._tree["meshcat"]["box"].object is not None
        vis["box"].delete()
        assert "box" not in srv._tree["meshcat"]
    assert [url_host(h) for h in ("127.0.0.1", "0.0.0.0", "::1", "::", "localhost")] == [
        "127.0.0.1",
        "127.0.0.1",
        "[::1]",
        "[::1]",
        "localhost",
    ]


@pytest.mark.parametrize("attempt", range(3))
def test_a_signal_right_after_the_url_still_stops_the_server_cleanly(attempt):
    """The URL is the caller's cue: a signal at once must find the server stoppable."""
    proc, _ = _start_view("--serve-for", "300")
    try:
        os.kill(proc.pid, signal.SIGTERM)
        assert proc.wait(30) == 0
    finally:
        proc.kill()
    assert proc.stderr.read().splitlines()[-1] == "rrt-pin: viewer stopped"


@pytest.mark.parametrize(
    "name, flange",
    [("rrt", "link3"), ("ur5", "tool0"), ("panda", "panda_hand_tcp"),
     ("kinova", "j2s6s200_end_effector"), ("double_pendulum", "link2")],
)  # fmt: skip
def test_the_path_follows_the_tool_flange_not_a_finger(name, flange):
    from rrt_pin.robot.robots import get
    from rrt_pin.viewer.drawing import default_path_frame

    assert default_path_frame(get(name).model) == flange


def test_a_chosen_path_frame_is_drawn_and_an_unknown_one_refused():
    from rrt_pin.robot.robots import get
    from rrt_pin.viewer.drawing import default_path_frame
    from rrt_pin.viewer.keyframes import frame_placements
    from rrt_pin.viewer.show import prepare

    ur5 = get("ur5")
    t = np.linspace(0.0, 1.0, 31)
    q = np.column_stack([np.linspace(0.0, 0.8, 31), *[np.zeros(31)] * 5])
    prepared = prepare(ur5, t, ur5.configuration(q), 30.0, path_frame="wrist_3_link")
    drawing = prepared.drawing
    assert drawing.path_frame == "wrist_3_link" and "path of wrist_3_link" in prepared.page
    placements = frame_placements(
        ur5.model, ur5.configuration(q), [ur5.model.getFrameId("wrist_3_link")]
    )
    np.testing.assert_allclose(drawing.path, placements[:, 0, :3, 3], atol=1e-12)
    assert default_path_frame(ur5.model) != "wrist_3_link"  # the choice made a difference
    with pytest.raises(InputError, match=r"path_frame='nope' is not a frame of the robot"):
        prepare(ur5, t, ur5.configuration(q), 30.0, path_frame="nope")
