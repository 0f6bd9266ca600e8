"""Pinocchio models of the RRT arm, or of any URDF.

Dynamics only by default: a geometry model is built only on request
(:func:`build_geometry`), for the viewer.
"""

from __future__ import annotations

import functools
import math
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rrt_pin.core._quiet import captured_stderr, native_message
from rrt_pin.core.errors import InputError, UrdfError
from rrt_pin.io._read import read_text_capped
from rrt_pin.robot.params import PLANT_FIELDS, Params, plant_difference
from rrt_pin.robot.urdf import MOUNT_ROTATION, urdf_xml
from rrt_pin.robot.urdf_check import MAX_URDF_BYTES, MimicPolicy, check_urdf_xml

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "refuse_ignored",
    "build_geometry", "build_model", "chapter_model", "load_urdf_model", "model_from_xml",
    "rrt_model",
]  # fmt: skip


def model_from_xml(xml: str, *, mimic: MimicPolicy = "warn") -> pin.Model:
    """A Pinocchio model (fixed base) from URDF text.

    The text is validated first (:func:`rrt_pin.robot.urdf_check.check_urdf_xml`):
    every number of the URDF, no DTD or entity, at most 1,000 joints and
    20 MB, physical inertias. urdfdom's messages on stderr are captured and
    logged at DEBUG level (the first one ends the error when parsing fails).

    Args:
        xml: the URDF text.
        mimic: ``<mimic>`` joints are modelled as independent joints; ``"warn"``
            (default) logs a warning naming them, ``"refuse"`` raises
            UrdfError, ``"allow"`` says nothing.

    Raises:
        UrdfError: the text does not parse or fails validation, or the model
            has no degree of freedom, a non-finite inertia, or a body with
            moving joints and no mass.
    """
    import pinocchio as pin

    check_urdf_xml(xml, mimic=mimic)
    with captured_stderr("urdfdom") as said:
        try:
            model = pin.buildModelFromXML(xml)
        except (RuntimeError, ValueError) as e:
            error = e
        else:
            error = None
    if error is not None:
        text = str(error).strip()
        first = text.splitlines()[0] if text else type(error).__name__
        detail = said.first_line()
        if detail and detail not in first:
            first = f"{first} ({detail})"
        raise UrdfError(f"URDF does not parse: {first}") from error
    _check_model(model)
    return model


def load_urdf_model(path: str | Path, *, mimic: MimicPolicy = "warn") -> pin.Model:
    """A Pinocchio model from a URDF file (UTF-8, at most 20 MB; see :func:`model_from_xml`).

    Raises:
        UrdfError: the file cannot be read, is larger than 20 MB, is a device
            or a folder, is not UTF-8, or does not describe a usable model.
    """
    xml = read_text_capped(path, cap=MAX_URDF_BYTES, what="URDF", error=UrdfError)
    try:
        return model_from_xml(xml, mimic=mimic)
    except UrdfError as e:
        raise UrdfError(f"{path}: {e}") from e


def rrt_model(params: Params | None = None) -> pin.Model:
    """The RRT arm's Pinocchio model, generated from ``params`` (the seed's when None).

    A URDF carries no gravity, so the model's gravity is set to (0, 0, −g) [m/s²]
    from ``params.g`` (world z is the seed's vertical ı0). The mount's rotation
    is set to the exact permutation :data:`rrt_pin.robot.urdf.MOUNT_ROTATION` (the
    URDF's roll/pitch/yaw leave 2e-16 entries, which put ~4e-13 N·m into T01x).
    """
    p = params if params is not None else Params()
    model = model_from_xml(urdf_xml(p))
    model.gravity.linear[:] = (0.0, 0.0, -p.g)
    _exact_mount(model)
    return model


def chapter_model(params: Params) -> pin.Model:
    """The chapter arm's model for ``params``, built once per plant (the last 8 kept).

    Only the plant's parameters (:data:`~rrt_pin.robot.params.PLANT_FIELDS`) count:
    ``Params`` that differ in gains or targets share one model. Do not modify it.
    """
    return _plant_model(tuple(getattr(params, name) for name in PLANT_FIELDS))


@functools.lru_cache(maxsize=8)
def _plant_model(plant: tuple[float, ...]) -> pin.Model:
    return rrt_model(Params(**dict(zip(PLANT_FIELDS, plant, strict=True))))


def _exact_mount(model: pin.Model) -> None:
    """Replace the near-permutation the URDF's mount leaves by the exact one.

    The mount is a fixed joint, merged by Pinocchio into the placement of q1
    and of the frames on the world (``mount``, ``link0``): each of those
    rotations is the mount's, to within 1e-15, and becomes it exactly.
    """
    import numpy as np
    import pinocchio as pin

    exact = np.array(MOUNT_ROTATION)

    def snapped(placement: pin.SE3) -> pin.SE3 | None:
        if np.abs(placement.rotation - exact).max() > 1e-15:
            return None
        return pin.SE3(exact, placement.translation.copy())

    q1 = model.getJointId("q1")
    new = snapped(model.jointPlacements[q1])
    if new is None:  # pragma: no cover - the generated URDF always has the mount
        raise UrdfError("the RRT arm's URDF has no mount rotation on q1")
    model.jointPlacements[q1] = new
    for i, frame in enumerate(model.frames):
        if frame.parentJoint == 0 and (new := snapped(frame.placement)) is not None:
            frame.placement = new
            model.frames[i] = frame


def build_model(params: Params | None = None, urdf: str | Path | None = None) -> pin.Model:
    """The model of a run: the URDF at ``urdf`` if given, else the RRT arm from ``params``."""
    if urdf is not None:
        return load_urdf_model(urdf)
    return rrt_model(params)


def build_geometry(
    model: pin.Model, xml: str, package_dirs: list[str] | None = None
) -> pin.GeometryModel:
    """The visual geometry model of ``xml`` for ``model`` (only the viewer needs it).

    The text is validated as by :func:`model_from_xml` (silently for mimic
    joints); urdfdom's and assimp's messages on stderr are captured and logged
    at DEBUG level.

    Raises:
        UrdfError: the text fails validation or its geometry does not load.
    """
    import pinocchio as pin

    check_urdf_xml(xml, mimic="allow")
    with captured_stderr("urdfdom/assimp") as said:
        try:
            geometry = pin.buildGeomFromUrdfString(
                model, xml, pin.GeometryType.VISUAL, package_dirs=package_dirs or []
            )
        except (RuntimeError, ValueError) as e:
            error = e
        else:
            error = None
    if error is not None:
        text = str(error).strip()
        first = native_message(text) if text else said.first_line() or type(error).__name__
        raise UrdfError(f"URDF geometry does not load: {first}") from error
    return geometry


def _check_model(model: pin.Model) -> None:
    import numpy as np

    if model.nv == 0:
        raise UrdfError("URDF has no moving joint")
    for j in range(1, model.njoints):
        inertia = model.inertias[j]
        name = model.names[j]
        values = [inertia.mass, *inertia.lever.tolist(), *inertia.inertia.flatten().tolist()]
        if not all(math.isfinite(v) for v in values):
            raise UrdfError(f"body of joint {name!r} has a non-finite inertia")
        if inertia.mass < 0.0:
            raise UrdfError(f"body of joint {name!r} has a negative mass {inertia.mass!r} kg")
        moments = np.linalg.eigvalsh(inertia.inertia)
        if moments.min() < -1e-12 * max(1.0, abs(moments).max()):
            raise UrdfError(
                f"body of joint {name!r} has a negative principal moment of inertia "
                f"{float(moments.min())!r} kg·m²"
            )
    # A moving joint whose whole subtree carries no mass makes M singular.
    subtree_mass = [0.0] * model.njoints
    for j in range(model.njoints - 1, 0, -1):
        subtree_mass[j] += model.inertias[j].mass
        subtree_mass[model.parents[j]] += subtree_mass[j]
    for j in range(1, model.njoints):
        if model.joints[j].nv > 0 and subtree_mass[j] <= 0.0:
            raise UrdfError(f"joint {model.names[j]!r} moves no mass (a URDF without inertials?)")


def refuse_ignored(robot: Any, params: Any, backend: str) -> None:
    """Refuse ``params`` that the Pinocchio backend would ignore.

    The Pinocchio backend simulates the model given; ``params`` may only name that
    model's own arm (its plant fields, :data:`rrt_pin.robot.params.PLANT_FIELDS`). A list of
    Params (one a variant) runs on the compiled backend only.

    Raises:
        InputError: ``params`` describe another arm than the model, or a list of
            them is given to the Pinocchio backend.
    """
    if params is None or backend == "compiled":
        return
    if isinstance(params, list):
        raise InputError(
            "params as one Params a variant runs on backend='compiled' only; backend "
            f"{backend!r} simulates the model given (pass chapter_arm(params) as the model)"
        )

    differs = None
    if robot.params is None:
        if not bool(robot.model == chapter_model(params)):
            differs = "is not the chapter's arm built from them"
    else:
        diff = plant_difference(params, robot.params)
        differs = f"differs from the robot's own parameters ({diff})" if diff else None
    if differs:
        raise InputError(
            f"params= would be ignored: backend {backend!r} simulates the model given, which "
            f"{differs}; pass rrt_pin.robot.robots.chapter_arm(params) as the model instead"
        )
