"""Arms shipped by example-robot-data, for the any-URDF tests.

The URDFs are found at run time from the installed distribution (its files live
under ``site-packages/cmeel.prefix/share/example-robot-data/robots``), so no path
is hard-coded. Their meshes are ``package://example-robot-data/...`` URIs; they
are never resolved here, because the dynamics build no geometry model.
"""

from __future__ import annotations

from functools import cache
from importlib.metadata import PackageNotFoundError, distribution
from pathlib import Path

import pytest

#: Robot name → URDF path inside example-robot-data's ``robots`` folder.
ROBOTS = {
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
}


@cache
def robots_dir() -> Path | None:
    """``.../share/example-robot-data/robots`` of the installed package, or None."""
    try:
        dist = distribution("example-robot-data")
    except PackageNotFoundError:
        return None
    for f in dist.files or ():
        parts = Path(str(f)).parts
        if "robots" in parts and parts[-1].endswith(".urdf"):
            i = parts.index("robots")
            return Path(dist.locate_file(Path(*parts[: i + 1])))
    return None


def package_dir() -> Path | None:
    """The folder that resolves ``package://example-robot-data/...`` mesh URIs.

    Pass it as ``package_dirs=[str(package_dir())]`` to ``pin.buildGeomFromUrdf``
    (only a viewer needs meshes; without it Pinocchio reports "Mesh ... could not
    be found").
    """
    base = robots_dir()
    return None if base is None else base.parent.parent


def robot_urdf(name: str) -> Path:
    """Path of one robot's URDF; skips the test when example-robot-data is missing."""
    base = robots_dir()
    if base is None:
        pytest.skip("example-robot-data is not installed (pip install rrt-pin[test])")
    path = base / ROBOTS[name]
    if not path.is_file():
        pytest.skip(f"example-robot-data has no {ROBOTS[name]}")
    return path
