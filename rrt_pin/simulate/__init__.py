"""Direct dynamics: integrate M(q)·q̈ + b(q, q̇) = τ(t, q, q̇) under a controller.

``rrt_pin.simulate`` is both this package and its main function: calling the
package calls :func:`simulate` (so ``rrt_pin.simulate(robot, law, q0, qd0, t)``
works however the package was imported).

Layout (data flows down; nothing imports upwards):

* :mod:`~rrt_pin.simulate.api`: :func:`simulate`, :func:`simulate_batch` —
  inputs checked once (:mod:`rrt_pin.core.validate`), options resolved from the
  registries (:mod:`~rrt_pin.simulate.options`), then a backend runs;
* :mod:`~rrt_pin.simulate.pinocchio_backend` (ABA) with
  :mod:`~rrt_pin.simulate.closed_loop` and :mod:`~rrt_pin.simulate.scipy_runs`;
  the compiled backend (:mod:`rrt_pin.compiled.integrate`, a layer above) is reached
  through its entry in :mod:`rrt_pin.core.backends`;
* :mod:`~rrt_pin.simulate.estimate`: the estimate of the global error in q
  that every run carries (``result.error_estimate``), from a companion run;
  :mod:`~rrt_pin.simulate.energy`: the energy check of conservative runs;
* :mod:`~rrt_pin.simulate.results`: what both backends return;
* the registries and pieces both backends share: :mod:`~rrt_pin.simulate.methods`
  (integrators), :mod:`~rrt_pin.simulate.integrators` and
  :mod:`~rrt_pin.simulate.symplectic` (fixed-step formulas),
  :mod:`~rrt_pin.simulate.contract` and :mod:`~rrt_pin.simulate.control` (the
  controller contract, the laws), :mod:`~rrt_pin.simulate.metrics` (the ``Metric``
  registry), :mod:`~rrt_pin.simulate.codes` (the compiled loop's constants);
* :mod:`~rrt_pin.simulate.accuracy` and :mod:`~rrt_pin.simulate.reference`: the
  accuracy catalogue and its high-precision references.

Methods (:data:`rrt_pin.simulate.methods.METHODS`): ``odepack`` (the Pinocchio default:
ODEPACK's LSODA through ``odeint``), scipy's ``RK45``, ``DOP853``, ``LSODA``,
``Radau``, ``BDF`` (the implicit ones get the analytic Jacobian of the closed
loop from ``pin.computeABADerivatives`` and the controller's
:meth:`~rrt_pin.simulate.control.Controller.jacobian`), the fixed-step
``symplectic_euler``, ``rk4``, ``verlet`` and the symplectic ``leapfrog``.
Default tolerances: chosen for the accuracy asked for (``accuracy=``, default 1e-8 rad
or m, :data:`rrt_pin.simulate.methods.ACCURACY`) from the calibration of
:mod:`rrt_pin.simulate.calibration`, so that each method keeps max |q − q_exact| within it
on every problem of :data:`rrt_pin.simulate.accuracy.PROBLEMS` (and a UR5 and a Panda run).

A run that produces a non-finite state or whose integrator fails raises
:class:`~rrt_pin.core.errors.DivergenceError` with the time and the coordinate; no
NaN is returned. Units are SI.

May import: rrt_pin.core, rrt_pin.io, rrt_pin.robot, rrt_pin.dynamics (the compiled
backend is reached through :mod:`rrt_pin.core.backends`).
"""

from __future__ import annotations

import importlib
import sys
import types
from typing import Any

__all__ = [
    "AccuracyWarning",
    "BatchResult",
    "EstimateWarning",
    "ErrorEstimate",
    "SimulationResult",
    "as_robot",
    "simulate",
    "simulate_batch",
]

_LAZY = {
    "simulate": "rrt_pin.simulate.api",
    "simulate_batch": "rrt_pin.simulate.api",
    "as_robot": "rrt_pin.simulate.api",
    "SimulationResult": "rrt_pin.simulate.results",
    "BatchResult": "rrt_pin.simulate.results",
    "ErrorEstimate": "rrt_pin.simulate.results",
    "AccuracyWarning": "rrt_pin.simulate.estimate",
    "EstimateWarning": "rrt_pin.simulate.estimate",
}


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rrt_pin.simulate' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


class _CallablePackage(types.ModuleType):
    """This package's type: calling it calls :func:`rrt_pin.simulate.api.simulate`."""

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return __getattr__("simulate")(*args, **kwargs)


sys.modules[__name__].__class__ = _CallablePackage
