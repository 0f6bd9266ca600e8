"""Deprecated alias of :mod:`rrt_pin.viewer.drawing` (kept for one release).

What the viewer draws is a :class:`~rrt_pin.viewer.drawing.RobotDrawing`, made by
:func:`~rrt_pin.viewer.drawing.build_drawing`.
"""

from __future__ import annotations

import warnings

from rrt_pin.viewer.drawing import RobotDrawing, build_drawing

warnings.warn(
    "rrt_pin.viewer.scene is deprecated: import from rrt_pin.viewer.drawing "
    "(RobotDrawing, build_drawing)",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ["ArmScene", "build_scene"]

ArmScene = RobotDrawing
build_scene = build_drawing
