"""Pinocchio models of the RRT arm, or of any URDF.

Dynamics only by default: a geometry model is built only on request
(:func:`build_geometry`), for the viewer.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

from rrt_pin.errors import UrdfError
from rrt_pin.params import Params

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = ["build_geometry", "build_model", "load_urdf_model", "model_from_xml", "rrt_model"]


def model_from_xml(xml: str) -> pin.Model:
    """A Pinocchio model (fixed base) from URDF text.

    Raises:
        UrdfError: the text does not parse, or the model has no degree of
            freedom, a non-finite inertia, or a body with moving joints and no
            mass.
    """
    import pinocchio as pin

    _check_xml(xml)
    try:
        model = pin.buildModelFromXML(xml)
    except (RuntimeError, ValueError) as e:
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise UrdfError(f"URDF does not parse: {first}") from e
    _check_model(model)
    return model


def load_urdf_model(path: str | Path) -> pin.Model:
    """A Pinocchio model from a URDF file.

    Raises:
        UrdfError: the file cannot be read or does not describe a usable model.
    """
    path = Path(path)
    try:
        xml = path.read_text(encoding="utf-8")
    except OSError as e:
        raise UrdfError(f"cannot read URDF {str(path)!r}: {e.strerror}") from e
    except UnicodeDecodeError as e:
        raise UrdfError(f"URDF {str(path)!r} is not UTF-8 text") from e
    try:
        return model_from_xml(xml)
    except UrdfError as e:
        raise UrdfError(f"{path}: {e}") from e


def rrt_model(params: Params | None = None) -> pin.Model:
    """The RRT arm's Pinocchio model, generated from ``params`` (the seed's when None).

    A URDF carries no gravity, so the model's gravity is set to (0, 0, −g) [m/s²]
    from ``params.g`` (world z is the seed's vertical ı0).
    """
    from rrt_pin.urdf import urdf_xml

    p = params if params is not None else Params()
    model = model_from_xml(urdf_xml(p))
    model.gravity.linear[:] = (0.0, 0.0, -p.g)
    return model


def build_model(params: Params | None = None, urdf: str | Path | None = None) -> pin.Model:
    """The model of a run: the URDF at ``urdf`` if given, else the RRT arm from ``params``."""
    if urdf is not None:
        return load_urdf_model(urdf)
    return rrt_model(params)


def build_geometry(
    model: pin.Model, xml: str, package_dirs: list[str] | None = None
) -> pin.GeometryModel:
    """The visual geometry model of ``xml`` for ``model`` (only the viewer needs it)."""
    import pinocchio as pin

    try:
        return pin.buildGeomFromUrdfString(
            model, xml, pin.GeometryType.VISUAL, package_dirs=package_dirs or []
        )
    except (RuntimeError, ValueError) as e:
        raise UrdfError(f"URDF geometry does not load: {str(e).strip().splitlines()[0]}") from e


def _check_xml(xml: str) -> None:
    """Refuse what Pinocchio would accept silently: malformed XML, zero joint axes."""
    import xml.etree.ElementTree as ET

    try:
        root = ET.fromstring(xml)
    except ET.ParseError as e:
        raise UrdfError(f"URDF does not parse: {e}") from e
    if root.tag != "robot":
        raise UrdfError(f"URDF root element is <{root.tag}>, not <robot>")
    for joint in root.iter("joint"):
        axis = joint.find("axis")
        if joint.get("type") in ("fixed", "floating", "planar") or axis is None:
            continue
        text = axis.get("xyz", "1 0 0")
        try:
            xyz = [float(v) for v in text.split()]
        except ValueError:
            xyz = []
        if len(xyz) != 3 or not all(math.isfinite(v) for v in xyz):
            raise UrdfError(f"joint {joint.get('name')!r} has an invalid axis xyz={text!r}")
        if math.hypot(*xyz) < 1e-12:
            raise UrdfError(f"joint {joint.get('name')!r} has a zero axis xyz={text!r}")


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
