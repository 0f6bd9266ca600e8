"""The browser viewer: keyframes and scene as data, meshcat commands, a local server, headless Chromium.

Importing this package is cheap: meshcat, tornado and selenium are imported
only by :mod:`rrt_pin.viewer.meshcat_scene`, :mod:`rrt_pin.viewer.server` and
:mod:`rrt_pin.viewer.browser` when used.

* :mod:`rrt_pin.viewer.keyframes`: times at a frame rate, resampling, link placements.
* :mod:`rrt_pin.viewer.scene`: shapes, ghost, path, ground and camera of an animation.
* :mod:`rrt_pin.viewer.meshcat_scene`: the scene as meshcat commands and one Animation.
* :mod:`rrt_pin.viewer.server`: meshcat's page served from a thread, 127.0.0.1 by default.
* :mod:`rrt_pin.viewer.browser`: headless Chromium screenshots.
"""

from rrt_pin.viewer.keyframes import (
    Keyframes,
    frame_placements,
    keyframe_times,
    keyframes,
    resample,
)
from rrt_pin.viewer.scene import ArmScene, CameraView, VisualShape, build_scene, visual_shapes

__all__ = [
    "ArmScene",
    "CameraView",
    "Keyframes",
    "VisualShape",
    "build_scene",
    "frame_placements",
    "keyframe_times",
    "keyframes",
    "resample",
    "visual_shapes",
]
