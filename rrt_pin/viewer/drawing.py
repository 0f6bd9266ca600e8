"""What the viewer draws, as plain data: shapes, keyframes, ghost, path, ground, camera.

Pure functions of a Pinocchio model, its visual geometry model and a sampled
trajectory; no meshcat, no I/O. Lengths in metres [m], times in seconds [s],
transforms as 4×4 homogeneous matrices in the world frame (z up).
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from rrt_pin.core.errors import InputError
from rrt_pin.core.text import argument
from rrt_pin.viewer.keyframes import Keyframes, frame_placements, keyframes

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "MESH_FORMATS",
    "RobotDrawing",
    "CameraView",
    "VisualShape",
    "build_drawing",
    "camera_view",
    "ground_grid",
    "shape_bounds",
    "visual_shapes",
]

logger = logging.getLogger("rrt_pin")

#: Mesh file formats the browser can load (meshcat's loaders).
MESH_FORMATS = (".dae", ".stl", ".obj")


@dataclass(frozen=True)
class VisualShape:
    """One visual primitive or mesh, fixed to a link frame.

    Attributes:
        name: the geometry object's name (Pinocchio's, e.g. ``link1_0``).
        frame: name of the link (body) frame that carries it.
        kind: ``box``, ``cylinder``, ``sphere``, ``capsule``, ``cone``,
            ``ellipsoid`` or ``mesh``.
        size: box (x, y, z) full lengths; cylinder, capsule, cone (radius,
            length of the straight part); sphere (radius,); ellipsoid the three
            radii; mesh the scale factors [m or 1].
        rgba: colour, components in [0, 1].
        local: placement of the shape relative to its link frame (4×4) [m].
            Cylinders, capsules and cones are along the local z axis (URDF).
        aabb_center: centre of the shape's bounding box in its own frame [m].
        aabb_half: half extents of that box [m].
        mesh_path: the mesh file (kind ``mesh`` only).
    """

    name: str
    frame: str
    kind: str
    size: tuple[float, ...]
    rgba: tuple[float, float, float, float]
    local: np.ndarray
    aabb_center: np.ndarray
    aabb_half: np.ndarray
    mesh_path: str = ""


def _shape_of(geometry_object: pin.GeometryObject) -> tuple[str, tuple[float, ...]] | None:
    import coal

    g = geometry_object.geometry
    if isinstance(g, coal.Box):
        return "box", tuple(float(x) for x in 2.0 * np.asarray(g.halfSide))
    if isinstance(g, coal.Capsule):
        return "capsule", (float(g.radius), 2.0 * float(g.halfLength))
    if isinstance(g, coal.Cone):
        return "cone", (float(g.radius), 2.0 * float(g.halfLength))
    if isinstance(g, coal.Cylinder):
        return "cylinder", (float(g.radius), 2.0 * float(g.halfLength))
    if isinstance(g, coal.Ellipsoid):
        return "ellipsoid", tuple(float(x) for x in np.asarray(g.radii))
    if isinstance(g, coal.Sphere):
        return "sphere", (float(g.radius),)
    path = str(geometry_object.meshPath)
    if path and path.lower().endswith(MESH_FORMATS):
        return "mesh", tuple(float(x) for x in np.asarray(geometry_object.meshScale))
    return None


def _local_aabb(
    kind: str, size: tuple[float, ...], geometry: object
) -> tuple[np.ndarray, np.ndarray]:
    zero = np.zeros(3)
    if kind == "box":
        return zero, np.asarray(size) / 2.0
    if kind in ("cylinder", "cone"):
        r, length = size
        return zero, np.array([r, r, length / 2.0])
    if kind == "capsule":
        r, length = size
        return zero, np.array([r, r, length / 2.0 + r])
    if kind == "sphere":
        return zero, np.full(3, size[0])
    if kind == "ellipsoid":
        return zero, np.asarray(size, dtype=float)
    geometry.computeLocalAABB()  # type: ignore[attr-defined]
    lo = np.asarray(geometry.aabb_local.min_, dtype=float)  # type: ignore[attr-defined]
    hi = np.asarray(geometry.aabb_local.max_, dtype=float)  # type: ignore[attr-defined]
    return (lo + hi) / 2.0, (hi - lo) / 2.0


def visual_shapes(model: pin.Model, geometry_model: pin.GeometryModel) -> tuple[VisualShape, ...]:
    """The drawable shapes of a visual geometry model, each tied to its link frame.

    Primitives (box, cylinder, sphere, capsule, cone, ellipsoid) and mesh files
    the browser can load (``.dae``, ``.stl``, ``.obj``) are kept; any other
    geometry is skipped with a warning on the ``rrt_pin`` logger.
    """
    shapes = []
    for obj in geometry_model.geometryObjects:
        found = _shape_of(obj)
        if found is None:
            logger.warning(
                "viewer: skipping geometry %r (%s%s): not a primitive or a .dae/.stl/.obj mesh",
                obj.name,
                type(obj.geometry).__name__,
                f", {obj.meshPath}" if str(obj.meshPath) else "",
            )
            continue
        kind, size = found
        frame = model.frames[obj.parentFrame]
        if frame.parentJoint != obj.parentJoint:
            raise InputError(f"geometry {obj.name!r}: parent frame and parent joint disagree")
        # geometry placement is relative to the parent joint; express it in the link frame
        local = (frame.placement.inverse() * obj.placement).homogeneous
        center, half = _local_aabb(kind, size, obj.geometry)
        rgba = tuple(float(min(max(c, 0.0), 1.0)) for c in np.asarray(obj.meshColor))
        shapes.append(
            VisualShape(
                name=obj.name,
                frame=frame.name,
                kind=kind,
                size=size,
                rgba=rgba,  # type: ignore[arg-type]
                local=local,
                aabb_center=center,
                aabb_half=half,
                mesh_path=str(obj.meshPath) if kind == "mesh" else "",
            )
        )
    return tuple(shapes)


def shape_bounds(shape: VisualShape, frame_placement: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """World axis-aligned bounds (lo, hi) [m] of ``shape`` with its frame at ``frame_placement``.

    ``frame_placement`` may be one 4×4 transform or a stack (..., 4, 4); the
    bounds are then taken over the whole stack. Exact for boxes and for
    cylinders whose axis is parallel to a world axis, conservative otherwise.
    """
    t = np.asarray(frame_placement, dtype=float).reshape(-1, 4, 4) @ shape.local
    centers = t[:, :3, :3] @ shape.aabb_center + t[:, :3, 3]
    halves = np.abs(t[:, :3, :3]) @ shape.aabb_half
    return (centers - halves).min(axis=0), (centers + halves).max(axis=0)


@dataclass(frozen=True)
class CameraView:
    """Where the camera is, with the scene shifted so that the camera looks at its centre.

    meshcat 0.3.2's orbit controls always look at the origin of the page's
    world and offer no command to move that target, so the viewer moves the
    drawing instead: everything is translated by ``-center`` and the camera
    sits at ``offset`` from the (new) origin.

    Attributes:
        center: the point looked at and orbited about, world coordinates [m].
        offset: camera position relative to ``center``, world axes (z up) [m].
        fov_deg: vertical field of view [deg].
    """

    center: np.ndarray
    offset: np.ndarray
    fov_deg: float


def camera_view(
    lo: np.ndarray,
    hi: np.ndarray,
    direction: tuple[float, float, float] = (1.0, -0.3, 0.45),
    fov_deg: float = 40.0,
    aspect: float = 1.6,
    margin: float = 1.15,
) -> CameraView:
    """A camera that looks at the centre of the box [lo, hi] [m] and sees all of it.

    The camera looks along ``-direction`` (world, z up) at the box centre; its
    distance is the smallest at which every corner of the box is inside the
    vertical field of view ``fov_deg`` [deg] (meshcat's default is 75°) and the
    horizontal one for the window ``aspect`` (width / height), times ``margin``.
    """
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    center = (lo + hi) / 2.0
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    # camera axes: forward = -d, right = forward x z, up = right x forward
    forward = -d
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right = right / np.linalg.norm(right) if np.linalg.norm(right) > 1e-9 else np.array([1.0, 0, 0])
    up = np.cross(right, forward)
    tan_v = math.tan(math.radians(fov_deg) / 2.0)
    tan_h = tan_v * aspect
    corners = np.array(
        [[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])]
    )
    rel = corners - center
    # corner c is visible from distance s if |rel·up| <= tan_v (s - rel·d) (and likewise right)
    along = rel @ d
    need = np.maximum(np.abs(rel @ up) / tan_v, np.abs(rel @ right) / tan_h) + along
    distance = margin * max(float(need.max()), 1e-3)
    return CameraView(center=center, offset=distance * d, fov_deg=float(fov_deg))


def ground_grid(lo: np.ndarray, hi: np.ndarray, z: float, margin: float = 0.15) -> np.ndarray:
    """Line segments of a square ground grid under the box [lo, hi] [m], at height ``z`` [m].

    The grid covers the box's x-y extent plus ``margin`` of its size on each
    side; its spacing is a round number (1, 2 or 5 times a power of ten metres)
    giving 8 to 20 cells across, and its lines pass through x = 0 and y = 0.

    Returns:
        Array (2·K, 3): the endpoints of K segments, in pairs [m].
    """
    lo = np.asarray(lo, dtype=float)
    hi = np.asarray(hi, dtype=float)
    extent = max(float(np.max(hi[:2] - lo[:2])), 1e-3) * (1.0 + 2.0 * margin)
    raw = extent / 12.0
    power = 10.0 ** math.floor(math.log10(raw))
    step = next(m * power for m in (1.0, 2.0, 5.0, 10.0) if m * power >= raw)
    center = (lo[:2] + hi[:2]) / 2.0
    half = math.ceil(extent / 2.0 / step) * step
    x0, x1 = (
        math.floor((center[0] - half) / step) * step,
        math.ceil((center[0] + half) / step) * step,
    )
    y0, y1 = (
        math.floor((center[1] - half) / step) * step,
        math.ceil((center[1] + half) / step) * step,
    )
    xs = np.arange(round((x1 - x0) / step) + 1) * step + x0
    ys = np.arange(round((y1 - y0) / step) + 1) * step + y0
    segments = [((x, y0, z), (x, y1, z)) for x in xs] + [((x0, y, z), (x1, y, z)) for y in ys]
    return np.asarray(segments, dtype=float).reshape(-1, 3)


@dataclass(frozen=True)
class RobotDrawing:
    """Everything the viewer draws, as data.

    Attributes:
        shapes: the visual shapes, each tied to a link frame.
        static: world placements of the link frames that never move (4×4) [m],
            as ``(frame name, transform)`` pairs.
        keyframes: placements of the moving link frames at each keyframe.
        ghost: placements of every shape-carrying frame at the target pose,
            ``(frame name, transform)`` pairs; empty for no ghost.
        path: positions of the path frame's origin at each keyframe, (N, 3) [m].
        path_frame: the frame whose origin ``path`` follows (``link3``, i.e. C3,
            for the RRT arm).
        ground_z: height of the ground grid [m]: the lowest point of the arm
            over the animation, or 0 if that is above 0.
        grid: the ground grid's line segments, endpoints in pairs (2·K, 3) [m].
        lo, hi: world bounds of everything drawn over the animation [m].
        camera: a view that frames the drawing.
    """

    shapes: tuple[VisualShape, ...]
    static: tuple[tuple[str, np.ndarray], ...]
    keyframes: Keyframes
    ghost: tuple[tuple[str, np.ndarray], ...]
    path: np.ndarray
    path_frame: str
    ground_z: float
    grid: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    camera: CameraView = field(repr=False)


def default_path_frame(model: pin.Model) -> str:
    """The tool flange: the last body frame of the chain's last joint, before a gripper.

    The deepest joint's last body frame (the RRT arm's ``link3``, whose origin is C3;
    UR5's ``tool0``), except below a gripper — a joint whose subtree of at most four
    joints forks (Panda's fingers) — whose own body frames are taken. Among those, a
    frame named for the tool (:data:`_FLANGE_WORDS`) wins: Panda's ``panda_hand_tcp``,
    Kinova's ``j2s6s200_end_effector`` rather than a finger tip.
    """
    import pinocchio as pin

    n = model.njoints
    depth, children = [0] * n, [[] for _ in range(n)]
    for j in range(1, n):
        depth[j] = depth[model.parents[j]] + 1
        children[model.parents[j]].append(j)

    def subtree(j: int) -> int:
        return sum(1 + subtree(c) for c in children[j])

    last = max(range(1, n), key=lambda j: (depth[j], j)) if n > 1 else 0
    walk = model.parents[last] if last else 0
    while walk:  # the first fork above the deepest joint, if a gripper's (≤ 4 joints)
        if len(children[walk]) > 1 and subtree(walk) <= 4:
            last = walk  # the fingers' common joint: the hand, not a finger
            break
        walk = model.parents[walk]
    bodies = [
        f.name for f in model.frames if f.type == pin.FrameType.BODY and f.parentJoint == last
    ]
    for word in _FLANGE_WORDS:  # a frame named for the tool, if the URDF has one
        named = [b for b in bodies if word in b.lower()]
        if named:
            return named[-1]
    if bodies:
        return bodies[-1]
    return model.frames[len(model.frames) - 1].name


#: Words of a tool frame's name, by preference (UR5's ``tool0``, Panda's ``panda_hand_tcp``,
#: Kinova's ``j2s6s200_end_effector``).
_FLANGE_WORDS = ("tcp", "tool", "flange", "end_effector", "ee_link")


def check_frame(model: pin.Model, name: str, what: str = "path_frame") -> str:
    """``name`` if ``model`` has a frame of that name, else one line listing some it has."""
    names = [f.name for f in model.frames]
    if name not in names:
        shown = ", ".join(names[-8:])
        raise InputError(
            f"{argument(what)}={name!r} is not a frame of the robot; its last frames: {shown}"
        )
    return name


def build_drawing(
    model: pin.Model,
    geometry_model: pin.GeometryModel,
    t: np.ndarray,
    q: np.ndarray,
    fps: float,
    ghost_q: np.ndarray | None = None,
    path_frame: str | None = None,
) -> RobotDrawing:
    """Assemble the scene of an animation.

    Args:
        model: the Pinocchio model.
        geometry_model: its visual geometry (``rrt_pin.robot.model.build_geometry``).
        t: keyframe times [s], shape (N,), ``1/fps`` apart (see
            :func:`rrt_pin.viewer.keyframes.keyframe_times`).
        q: configurations at those times, shape (N, nq).
        fps: frame rate [1/s].
        ghost_q: the target configuration drawn as a translucent ghost, (nq,);
            None for no ghost.
        path_frame: the frame whose origin's path is drawn as a line; the body
            of the last joint when None.

    Raises:
        InputError: shapes disagree or a name is unknown.
    """
    shapes = visual_shapes(model, geometry_model)
    frame_names = list(dict.fromkeys(s.frame for s in shapes))
    ids = {f: model.getFrameId(f) for f in frame_names}
    moving = tuple(f for f in frame_names if model.frames[ids[f]].parentJoint != 0)
    fixed = [f for f in frame_names if f not in moving]
    q = np.asarray(q, dtype=float)
    kf = keyframes(model, t, q, moving, fps)
    static = tuple((f, frame_placements(model, q[:1], [ids[f]])[0, 0]) for f in fixed)
    ghost: tuple[tuple[str, np.ndarray], ...] = ()
    if ghost_q is not None:
        gq = np.asarray(ghost_q, dtype=float).reshape(1, -1)
        placed = frame_placements(model, gq, [ids[f] for f in frame_names])[0]
        ghost = tuple(zip(frame_names, placed, strict=True))
    path_frame = path_frame or default_path_frame(model)
    kp = keyframes(model, t, q, (path_frame,), fps)
    path = kp.transforms[:, 0, :3, 3].copy()

    lows = [path.min(axis=0)]
    highs = [path.max(axis=0)]
    where: dict[str, np.ndarray] = {f: kf.transforms[:, i] for i, f in enumerate(moving)}
    where.update({f: T for f, T in static})
    for s in shapes:
        lo, hi = shape_bounds(s, where[s.frame])
        lows.append(lo)
        highs.append(hi)
    for f, T in ghost:
        for s in shapes:
            if s.frame == f:
                lo, hi = shape_bounds(s, T)
                lows.append(lo)
                highs.append(hi)
    lo = np.min(lows, axis=0)
    hi = np.max(highs, axis=0)
    ground_z = min(0.0, float(lo[2]))
    lo_cam = lo.copy()
    lo_cam[2] = ground_z
    grid = ground_grid(lo, hi, ground_z)
    for arr in (path, grid, lo, hi):
        arr.flags.writeable = False
    return RobotDrawing(
        shapes=shapes,
        static=static,
        keyframes=kf,
        ghost=ghost,
        path=path,
        path_frame=path_frame,
        ground_z=ground_z,
        grid=grid,
        lo=lo,
        hi=hi,
        camera=camera_view(lo_cam, hi),
    )
