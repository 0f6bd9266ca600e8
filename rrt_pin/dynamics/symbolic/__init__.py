"""The RRT arm's equations of motion derived symbolically, by Lagrange and by Kane.

Built with ``sympy.physics.mechanics`` following the chapter chapter step by step:
frames (eqs. 1–4), angular velocities and accelerations (5–8), velocities and
accelerations of the mass centres (9–14), generalized active forces (15),
kinetic energies, Lagrange's equations, and Kane's generalized inertia forces
(16–29). sympy is an optional dependency (``pip install rrt-pin[symbolic]``),
imported only by this package; the generated numeric kernel
``rrt_pin.dynamics.kernel`` does not need it.
"""

from __future__ import annotations

try:
    import sympy  # noqa: F401
except ImportError as e:  # pragma: no cover - depends on the installation
    from rrt_pin.core.extras import MissingExtra

    raise MissingExtra("sympy", "symbolic", "the symbolic derivations") from e

from rrt_pin.dynamics.symbolic.eom import METHODS, EquationsOfMotion, equations_of_motion

__all__ = ["METHODS", "EquationsOfMotion", "equations_of_motion"]
