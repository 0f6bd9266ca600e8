"""The robot: its parameters, its description, its Pinocchio model.

* :mod:`~rrt_pin.robot.params`: the chapter's parameters (``L1``, ``m3``, ``I3x``, …)
  and their one order (:data:`~rrt_pin.robot.params.PLANT_FIELDS`);
* :mod:`~rrt_pin.robot.robot`: :class:`Robot`, what every entry point takes (model,
  joint and column names, units, defaults);
* :mod:`~rrt_pin.robot.robots`: the registry of robots by name (the chapter's arm,
  ``ur5``, ``panda``, …);
* :mod:`~rrt_pin.robot.urdf`: the chapter arm's generated URDF;
  :mod:`~rrt_pin.robot.urdf_check`: a URDF's numbers checked before they are trusted;
  :mod:`~rrt_pin.robot.model`: Pinocchio models from URDF.

May import: rrt_pin.core, rrt_pin.io.

``from rrt_pin.robot import Robot`` (the names of the 0.3 module ``rrt_pin.robot``)
works: they are offered here on first use.
"""

from __future__ import annotations

import importlib
from typing import Any

__all__ = ["CHAPTER_COLUMNS", "JOINT_KINDS", "Joint", "Robot", "RobotDefaults"]


def __getattr__(name: str) -> Any:
    if name in __all__:
        return getattr(importlib.import_module("rrt_pin.robot.robot"), name)
    raise AttributeError(f"module 'rrt_pin.robot' has no attribute {name!r}")
