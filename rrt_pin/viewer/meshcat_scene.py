"""An :class:`~rrt_pin.viewer.drawing.RobotDrawing` as meshcat commands (plain data, nothing sent).

Each command has meshcat's ``lower()`` (a msgpack-ready dict); the transport
(:mod:`rrt_pin.viewer.server`) only packs and forwards them. Geometry is sent
once; the motion is one meshcat Animation whose keyframes carry only the
moving links' placements, so the page itself plays, pauses, loops and scrubs.
Lengths in metres [m], times in seconds [s].
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from rrt_pin.viewer._deps import import_meshcat
from rrt_pin.viewer.drawing import RobotDrawing, VisualShape

__all__ = [
    "ARM",
    "GHOST",
    "GROUND",
    "PATH",
    "animation",
    "quaternions_xyzw",
    "scene_commands",
    "shape_object",
]

#: meshcat paths of the arm, its ghost at the target pose and the path line.
ARM = "/meshcat/arm"
GHOST = "/meshcat/ghost"
PATH = "/meshcat/path"
GROUND = "/meshcat/ground"
#: Opacity of the ghost arm.
GHOST_OPACITY = 0.3
#: Colour of the path line (RGB, 0xRRGGBB): magenta, unlike any link.
PATH_COLOUR = 0xD81B9A
#: Colour of the ground grid's lines.
GRID_COLOUR = 0xB0B8C0


def _path(text: str) -> Any:
    from meshcat.path import Path

    return Path().append(text)


def _safe(name: str) -> str:
    return name.replace("/", "_") or "_"


def _colour(rgba: tuple[float, ...]) -> int:
    r, g, b = (min(255, max(0, round(255 * c))) for c in rgba[:3])
    return (r << 16) | (g << 8) | b


def quaternions_xyzw(rotations: np.ndarray) -> np.ndarray:
    """Unit quaternions (x, y, z, w) of rotation matrices (..., 3, 3), signs kept continuous.

    three.js's order; consecutive quaternions along the first axis are made to
    have a non-negative dot product so that interpolation takes the short way.
    """
    from scipy.spatial.transform import Rotation

    r = np.asarray(rotations, dtype=float)
    shape = r.shape[:-2]
    out = Rotation.from_matrix(r.reshape(-1, 3, 3)).as_quat()
    out = out.reshape(*shape, 4)
    if out.ndim >= 2:
        flat = out.reshape(out.shape[0], -1, 4)
        for k in range(1, flat.shape[0]):
            flip = np.einsum("ij,ij->i", flat[k], flat[k - 1]) < 0.0
            flat[k, flip] *= -1.0
        out = flat.reshape(out.shape)
    return out


# three.js cylinders and cones are along their local y axis; URDF's along z.
_Y_TO_Z = np.array([[1.0, 0, 0, 0], [0, 0, -1.0, 0], [0, 1.0, 0, 0], [0, 0, 0, 1.0]])


def shape_object(shape: VisualShape, opacity: float = 1.0) -> list[tuple[str, Any, np.ndarray]]:
    """The meshcat objects that draw ``shape``: ``(sub-path, object, transform in the link frame)``.

    Most shapes are one object; a capsule is a cylinder and two spheres.
    """
    mc = import_meshcat()
    g = mc.geometry
    extra = {"depthWrite": False} if opacity < 1.0 else {}
    material = g.MeshLambertMaterial(
        color=_colour(shape.rgba), opacity=opacity * shape.rgba[3], **extra
    )
    name = _safe(shape.name)
    local = shape.local
    if shape.kind == "box":
        return [(name, g.Mesh(g.Box(list(shape.size)), material), local)]
    if shape.kind == "sphere":
        return [(name, g.Mesh(g.Sphere(shape.size[0]), material), local)]
    if shape.kind == "ellipsoid":
        return [(name, g.Mesh(g.Ellipsoid(list(shape.size)), material), local)]
    if shape.kind in ("cylinder", "cone"):
        r, length = shape.size
        geom = g.Cylinder(length, r) if shape.kind == "cylinder" else g.Cylinder(length, 0, 0.0, r)
        return [(name, g.Mesh(geom, material), local @ _Y_TO_Z)]
    if shape.kind == "capsule":
        r, length = shape.size
        out = [(name, g.Mesh(g.Cylinder(length, r), material), local @ _Y_TO_Z)]
        for sign, suffix in ((1.0, "top"), (-1.0, "bottom")):
            end = np.eye(4)
            end[2, 3] = sign * length / 2.0
            out.append((f"{name}_{suffix}", g.Mesh(g.Sphere(r), material), local @ end))
        return out
    if shape.kind == "mesh":
        suffix = shape.mesh_path.lower().rsplit(".", 1)[-1]
        loader = {"dae": g.DaeMeshGeometry, "stl": g.StlMeshGeometry, "obj": g.ObjMeshGeometry}
        geom = loader[suffix].from_file(shape.mesh_path)
        scale = np.diag([*shape.size, 1.0])
        return [(name, g.Mesh(geom, material), local @ scale)]
    raise ValueError(f"unknown shape kind {shape.kind!r}")


def animation(drawing: RobotDrawing) -> Any:
    """The meshcat Animation of the moving links: one clip per link, position and quaternion tracks.

    Keyframe ``k`` sits at frame number ``t[k]·fps`` of a clip at ``fps``, i.e.
    at time ``t[k]`` [s].
    """
    mc = import_meshcat()
    an = mc.animation
    kf = drawing.keyframes
    frames = (kf.t * kf.fps).tolist()
    anim = an.Animation(default_framerate=kf.fps)
    quats = quaternions_xyzw(kf.transforms[:, :, :3, :3])
    for i, frame in enumerate(kf.frames):
        positions = kf.transforms[:, i, :3, 3].tolist()
        tracks = {
            "position": an.AnimationTrack("position", "vector3", list(frames), positions),
            "quaternion": an.AnimationTrack(
                "quaternion", "quaternion", list(frames), quats[:, i].tolist()
            ),
        }
        anim.clips[_path(f"{ARM}/{_safe(frame)}")] = an.AnimationClip(tracks=tracks, fps=kf.fps)
    return anim


def _translation(p: np.ndarray) -> np.ndarray:
    t = np.eye(4)
    t[:3, 3] = p
    return t


def scene_commands(
    drawing: RobotDrawing, *, play: bool = True, loop: bool = True, ghost: bool = True
) -> list[Any]:
    """The meshcat commands that draw ``scene`` and upload its animation.

    Args:
        drawing: what is drawn (shapes, keyframes, ghost, path, camera).
        play: start playing as soon as the page has the animation.
        loop: repeat forever; otherwise play once and stay at the last frame.
        ghost: draw the target pose as a translucent ghost arm.

    Returns:
        Commands in sending order: ground grid and world triad, the arm's
        shapes, the static links, the ghost, the path of the path frame, the
        camera, then the animation.
    """
    mc = import_meshcat()
    c = mc.commands
    g = mc.geometry
    out: list[Any] = []
    size = float(np.max(drawing.hi - drawing.lo))
    # meshcat's camera orbits the page's origin: shift the drawing so that the
    # scene's centre is there (see rrt_pin.viewer.drawing.CameraView).
    shift = -drawing.camera.center
    out.append(c.SetTransform(_translation(shift), _path("/meshcat")))
    # meshcat's own grid (20 m, crossing behind the camera, which headless
    # Chromium's software renderer drops) gives way to one sized to the drawing.
    out.append(c.SetProperty("visible", False, _path("/Grid")))
    grid = g.LineSegments(
        g.PointsGeometry(drawing.grid.T.astype(np.float32)),
        g.LineBasicMaterial(color=GRID_COLOUR),
    )
    out.append(c.SetObject(grid, path=_path(GROUND)))
    # meshcat's default world triad ("/Axes") is 0.5 m long; scale it to the arm.
    axes = _translation(shift) @ np.diag([max(size, 0.2) / 4 / 0.5] * 3 + [1.0])
    out.append(c.SetTransform(axes, _path("/Axes")))
    for s in drawing.shapes:
        for sub, obj, local in shape_object(s):
            p = _path(f"{ARM}/{_safe(s.frame)}/{sub}")
            out.append(c.SetObject(obj, path=p))
            out.append(c.SetTransform(local, p))
    for frame, T in drawing.static:
        out.append(c.SetTransform(T, _path(f"{ARM}/{_safe(frame)}")))
    if ghost and drawing.ghost:
        for s in drawing.shapes:
            for sub, obj, local in shape_object(s, opacity=GHOST_OPACITY):
                p = _path(f"{GHOST}/{_safe(s.frame)}/{sub}")
                out.append(c.SetObject(obj, path=p))
                out.append(c.SetTransform(local, p))
        for frame, T in drawing.ghost:
            out.append(c.SetTransform(T, _path(f"{GHOST}/{_safe(frame)}")))
    if len(drawing.path) > 1:
        line = g.Line(
            g.PointsGeometry(drawing.path.T.astype(np.float32)),
            g.LineBasicMaterial(color=PATH_COLOUR, linewidth=2.0),
        )
        out.append(c.SetObject(line, path=_path(PATH)))
    # The camera sits in the "rotated" frame, which is y up: world (x, y, z) -> (x, z, -y).
    offset = drawing.camera.offset
    camera = _path("/Cameras/default/rotated/<object>")
    out.append(c.SetProperty("fov", drawing.camera.fov_deg, camera))
    out.append(
        c.SetProperty("position", [float(offset[0]), float(offset[2]), float(-offset[1])], camera)
    )
    if drawing.keyframes.frames:
        reps = math.inf if loop else 1
        out.append(c.SetAnimation(animation(drawing), play=play, repetitions=reps))
    return out
