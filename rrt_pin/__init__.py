"""rrt-pin: rigid-body dynamics of the chapter's RRT arm (and any URDF) with Pinocchio.

SI units everywhere: s, m, rad, kg, N, N·m. ``import rrt_pin`` is cheap: the
names below are imported on first use (PEP 562), so the library never pulls in
pinocchio, meshcat, matplotlib or sympy before a caller needs them.
"""

from __future__ import annotations

import importlib
from typing import Any

from rrt_pin import _moved
from rrt_pin._version import __version__
from rrt_pin.core._logging import logger as _logger  # noqa: F401  (installs the NullHandler)
from rrt_pin.core.errors import (
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
from rrt_pin.robot.params import Params

_moved.install()  # the module paths of 0.3, deprecated: see rrt_pin._moved

_LAZY = {
    "urdf_xml": "rrt_pin.robot.urdf",
    "write_urdf": "rrt_pin.robot.urdf",
    "build_model": "rrt_pin.robot.model",
    "rrt_model": "rrt_pin.robot.model",
    "load_urdf_model": "rrt_pin.robot.model",
    "model_from_xml": "rrt_pin.robot.model",
    "load_runfile": "rrt_pin.cli.runfile",
    "resolve_params": "rrt_pin.cli.runfile",
    "rest_to_rest": "rrt_pin.dynamics.trajectory",
    "RestToRest": "rrt_pin.dynamics.trajectory",
    "Trajectory": "rrt_pin.dynamics.trajectory",
    "read_motion": "rrt_pin.dynamics.sampled",
    "inverse_derivatives": "rrt_pin.dynamics.derivatives",
    "forward_derivatives": "rrt_pin.dynamics.derivatives",
    "sampled_motion": "rrt_pin.dynamics.sampled",
    "time_grid": "rrt_pin.core.grid",
    "inverse_dynamics": "rrt_pin.dynamics.inverse",
    "joint_wrenches": "rrt_pin.dynamics.wrenches",
    "Robot": "rrt_pin.robot.robot",
    "chapter_arm": "rrt_pin.robot.robots",
    "Controller": "rrt_pin.simulate.control",
    "chapter_controller": "rrt_pin.simulate.control",
    "pd_gravity_controller": "rrt_pin.simulate.control",
    "tracking_controller": "rrt_pin.simulate.control",
    "seed_controller": "rrt_pin.simulate.control",  # deprecated name of chapter_controller
    "simulate_batch": "rrt_pin.simulate.api",
    "SimulationResult": "rrt_pin.simulate.results",
    "BatchResult": "rrt_pin.simulate.results",
    "equations_of_motion": "rrt_pin.dynamics.symbolic",
    "sweep": "rrt_pin.sweeps.run",
    "load_spec": "rrt_pin.sweeps.spec",
    "show": "rrt_pin.viewer.show",
}
#: Deprecated names (kept for one release), importable but not in ``__all__``.
_DEPRECATED = {"load_scene": "rrt_pin.scene"}
#: Subpackages and modules reachable as attributes (``rrt_pin.simulate`` is callable).
_MODULES = {
    "simulate": "rrt_pin.simulate",
    "robots": "rrt_pin.robot.robots",
    "methods": "rrt_pin.simulate.methods",
    "backends": "rrt_pin.core.backends",
    "control": "rrt_pin.simulate.control",
    "compiled": "rrt_pin.compiled",
    "derivatives": "rrt_pin.dynamics.derivatives",
}

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
        return importlib.import_module(_MODULES[name])
    module = _LAZY.get(name) or _DEPRECATED.get(name)
    if module is None:
        raise AttributeError(f"module 'rrt_pin' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
