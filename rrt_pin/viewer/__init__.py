"""The browser viewer: keyframes and the drawing as data, meshcat commands, a local server, headless Chromium.

Importing this package is cheap: meshcat, tornado and selenium are imported
only by :mod:`rrt_pin.viewer.meshcat_scene`, :mod:`rrt_pin.viewer.server` and
:mod:`rrt_pin.viewer.browser` when used.

* :mod:`rrt_pin.viewer.keyframes`: times at a frame rate, resampling, link placements.
* :mod:`rrt_pin.viewer.drawing`: shapes, ghost, path, ground and camera of an animation.
* :mod:`rrt_pin.viewer.meshcat_scene`: the drawing as meshcat's scene commands and one Animation.
* :mod:`rrt_pin.viewer.server`: meshcat's page served from a thread, 127.0.0.1 by default.
* :mod:`rrt_pin.viewer.browser`: headless Chromium screenshots.

May import: rrt_pin.core, rrt_pin.io, rrt_pin.robot, rrt_pin.dynamics, rrt_pin.simulate.
"""

import warnings
from typing import Any

from rrt_pin.viewer.drawing import (
    CameraView,
    RobotDrawing,
    VisualShape,
    build_drawing,
    visual_shapes,
)
from rrt_pin.viewer.keyframes import (
    Keyframes,
    frame_placements,
    keyframe_times,
    keyframes,
    resample,
)

__all__ = [
    "CameraView",
    "Keyframes",
    "RobotDrawing",
    "VisualShape",
    "build_drawing",
    "frame_placements",
    "keyframe_times",
    "keyframes",
    "resample",
    "visual_shapes",
]

#: Old names, kept for one release.
_DEPRECATED = {"ArmScene": RobotDrawing, "build_scene": build_drawing}


def __getattr__(name: str) -> Any:
    if name in _DEPRECATED:
        new = _DEPRECATED[name].__name__
        warnings.warn(
            f"rrt_pin.viewer.{name} is deprecated: use rrt_pin.viewer.{new}",
            DeprecationWarning,
            stacklevel=2,
        )
        return _DEPRECATED[name]
    raise AttributeError(f"module 'rrt_pin.viewer' has no attribute {name!r}")
