"""Deprecated alias of :mod:`rrt_pin.simulate` (kept for one release).

Import from :mod:`rrt_pin.simulate`, :mod:`rrt_pin.methods` and
:mod:`rrt_pin.robot` instead.
"""

from __future__ import annotations

import warnings

from rrt_pin import methods as _methods
from rrt_pin.robot import Robot
from rrt_pin.simulate.api import simulate, simulate_batch
from rrt_pin.simulate.results import BatchResult, SimulationResult

warnings.warn(
    "rrt_pin.simulation is deprecated: import from rrt_pin.simulate",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = [
    "ADAPTIVE_METHODS",
    "BATCH_METHODS",
    "DEFAULT_ATOL",
    "DEFAULT_METHOD",
    "DEFAULT_RTOL",
    "METHODS",
    "BatchResult",
    "SimulationResult",
    "coordinate_names",
    "effort_names",
    "simulate",
    "simulate_batch",
]

METHODS = tuple(_methods.METHODS)
ADAPTIVE_METHODS = _methods.names(adaptive=True)
BATCH_METHODS = _methods.names("pinocchio", batch=True)
DEFAULT_METHOD = "odepack"
DEFAULT_RTOL = _methods.DEFAULT_RTOL
DEFAULT_ATOL = _methods.DEFAULT_ATOL


def coordinate_names(model):  # noqa: ANN001, ANN201
    """Deprecated: ``Robot.from_model(model).q_names, .qd_names``."""
    robot = Robot.from_model(model)
    return robot.q_names, robot.qd_names


def effort_names(model):  # noqa: ANN001, ANN201
    """Deprecated: ``Robot.from_model(model).effort_names``."""
    return Robot.from_model(model).effort_names
