"""rrt-pin: rigid-body dynamics of the RRT arm (and any URDF) with Pinocchio.

SI units everywhere: s, m, rad, kg, N, N·m. ``import rrt_pin`` is cheap: the
names below are imported on first use (PEP 562), so the library never pulls in
pinocchio, meshcat, matplotlib or sympy before a caller needs them.
"""

from __future__ import annotations

import importlib
from typing import Any

from rrt_pin._logging import logger as _logger  # noqa: F401  (installs the NullHandler)
from rrt_pin.errors import (
    DivergenceError,
    InputError,
    ParameterError,
    RrtPinError,
    SceneError,
    UrdfError,
    ViewerError,
)
from rrt_pin.params import Params

_LAZY = {
    "urdf_xml": "rrt_pin.urdf",
    "write_urdf": "rrt_pin.urdf",
    "build_model": "rrt_pin.model",
    "rrt_model": "rrt_pin.model",
    "load_urdf_model": "rrt_pin.model",
    "model_from_xml": "rrt_pin.model",
    "load_scene": "rrt_pin.scene",
    "resolve_params": "rrt_pin.scene",
    "rest_to_rest": "rrt_pin.trajectory",
    "inverse_dynamics": "rrt_pin.inverse",
    "joint_wrenches": "rrt_pin.wrenches",
    "seed_controller": "rrt_pin.control",
    "pd_gravity_controller": "rrt_pin.control",
    "simulate": "rrt_pin.simulation",
    "simulate_batch": "rrt_pin.simulation",
    "equations_of_motion": "rrt_pin.symbolic",
}

__all__ = [
    "DivergenceError",
    "InputError",
    "ParameterError",
    "Params",
    "RrtPinError",
    "SceneError",
    "UrdfError",
    "ViewerError",
    *_LAZY,
]


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rrt_pin' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
