"""rrt-pin: rigid-body dynamics of the chapter's RRT arm (and any URDF) with Pinocchio.

SI units everywhere: s, m, rad, kg, N, N·m. ``import rrt_pin`` is cheap: the
names below are imported on first use (PEP 562), so the library never pulls in
pinocchio, meshcat, matplotlib or sympy before a caller needs them.
"""

from __future__ import annotations

import importlib
from typing import Any

from rrt_pin._logging import logger as _logger  # noqa: F401  (installs the NullHandler)
from rrt_pin._version import __version__
from rrt_pin.errors import (
    DivergenceError,
    InputError,
    OverrideError,
    ParameterError,
    RrtPinError,
    RunFileError,
    SceneError,
    SpecError,
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
    "load_runfile": "rrt_pin.runfile",
    "resolve_params": "rrt_pin.runfile",
    "rest_to_rest": "rrt_pin.trajectory",
    "RestToRest": "rrt_pin.trajectory",
    "Trajectory": "rrt_pin.trajectory",
    "time_grid": "rrt_pin.grid",
    "inverse_dynamics": "rrt_pin.inverse",
    "joint_wrenches": "rrt_pin.wrenches",
    "Robot": "rrt_pin.robot",
    "chapter_arm": "rrt_pin.robots",
    "Controller": "rrt_pin.control",
    "chapter_controller": "rrt_pin.control",
    "pd_gravity_controller": "rrt_pin.control",
    "tracking_controller": "rrt_pin.control",
    "seed_controller": "rrt_pin.control",  # deprecated name of chapter_controller
    "simulate_batch": "rrt_pin.simulate.api",
    "SimulationResult": "rrt_pin.simulate.results",
    "BatchResult": "rrt_pin.simulate.results",
    "equations_of_motion": "rrt_pin.symbolic",
    "sweep": "rrt_pin.sweeps.run",
    "load_spec": "rrt_pin.sweeps.spec",
    "show": "rrt_pin.viewer.show",
}
#: Deprecated names (kept for one release), importable but not in ``__all__``.
_DEPRECATED = {"load_scene": "rrt_pin.scene"}
#: Subpackages and modules reachable as attributes (``rrt_pin.simulate`` is callable).
_MODULES = ("simulate", "robots", "methods", "backends", "control", "compiled")

__all__ = [
    "DivergenceError",
    "InputError",
    "ParameterError",
    "Params",
    "OverrideError",
    "RrtPinError",
    "RunFileError",
    "SceneError",
    "SpecError",
    "UrdfError",
    "ViewerError",
    "__version__",
    *_LAZY,
    *_MODULES,
]


def __getattr__(name: str) -> Any:
    if name in _MODULES:
        return importlib.import_module(f"rrt_pin.{name}")
    module = _LAZY.get(name) or _DEPRECATED.get(name)
    if module is None:
        raise AttributeError(f"module 'rrt_pin' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
