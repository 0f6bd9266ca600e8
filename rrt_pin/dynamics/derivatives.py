"""Derivatives of the dynamics along a trajectory, for optimisers (analytic, batched).

Pinocchio's ``computeRNEADerivatives`` and ``computeABADerivatives`` at each state, with
respect to the joint coordinates [rad or m] (angles for continuous joints: Pinocchio
differentiates in the tangent space, which for them is the angle), velocities and
accelerations or efforts:

* :func:`inverse_derivatives`: ∂τ/∂q, ∂τ/∂q̇ and ∂τ/∂q̈ (the mass matrix M(q)) of
  τ = RNEA(q, q̇, q̈);
* :func:`forward_derivatives`: ∂q̈/∂q, ∂q̈/∂q̇ and ∂q̈/∂τ (M(q)⁻¹) of q̈ = ABA(q, q̇, τ).

Arrays are (N, nv, nv): row i is the output's i-th component, column j the input's j-th.
Units follow the quotients (N·m/rad, N·m·s/rad, kg·m² for revolute joints, …).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core.errors import InputError

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot

__all__ = ["ForwardDerivatives", "InverseDerivatives", "forward_derivatives", "inverse_derivatives"]


@dataclass(frozen=True)
class InverseDerivatives:
    """∂τ/∂q, ∂τ/∂q̇, ∂τ/∂q̈ at each state, shapes (N, nv, nv)."""

    dtau_dq: np.ndarray
    dtau_dqd: np.ndarray
    dtau_dqdd: np.ndarray


@dataclass(frozen=True)
class ForwardDerivatives:
    """∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂τ at each state, shapes (N, nv, nv)."""

    dqdd_dq: np.ndarray
    dqdd_dqd: np.ndarray
    dqdd_dtau: np.ndarray


def _arrays(robot: Robot, *named: tuple[str, Any]) -> list[np.ndarray]:
    from rrt_pin.robot.robot import Robot

    if not isinstance(robot, Robot):
        raise InputError(f"robot must be a rrt_pin.Robot, not {type(robot).__name__}")
    out = []
    for name, value in named:
        a = np.atleast_2d(np.asarray(value, dtype=float))
        if a.ndim != 2 or a.shape[1] != robot.nv:
            raise InputError(f"{name} has shape {a.shape}; {robot.name} needs (N, {robot.nv})")
        if not np.isfinite(a).all():
            i, j = (int(x) for x in np.argwhere(~np.isfinite(a))[0])
            raise InputError(f"{name}[{i}, {j}]={float(a[i, j])!r} is not finite")
        out.append(a)
    if any(a.shape != out[0].shape for a in out):
        raise InputError("the arrays must have the same shape: " + ", ".join(
            f"{n} {a.shape}" for (n, _), a in zip(named, out, strict=True)))  # fmt: skip
    return out


def _symmetric(upper: np.ndarray) -> np.ndarray:
    """Pinocchio fills M and M⁻¹'s upper triangle only."""
    return np.triu(upper) + np.triu(upper, 1).T


def _along(
    robot: Robot,
    algorithm: str,
    q: np.ndarray,
    qd: np.ndarray,
    third: np.ndarray,
    outputs: tuple[str, str, str],
) -> list[np.ndarray]:
    """Pinocchio's ``algorithm`` at each state, its outputs gathered (N, nv, nv) each.

    The third output (M or M⁻¹) is symmetrised: Pinocchio fills its upper triangle only.
    """
    import pinocchio as pin

    model = robot.model
    data = model.createData()
    config = np.ascontiguousarray(robot.configuration(q))
    run = getattr(pin, algorithm)
    n, nv = q.shape
    out = [np.empty((n, nv, nv)) for _ in range(3)]
    for k in range(n):
        run(model, data, config[k], qd[k], third[k])
        out[0][k], out[1][k] = getattr(data, outputs[0]), getattr(data, outputs[1])
        out[2][k] = _symmetric(getattr(data, outputs[2]))
    return out


def inverse_derivatives(robot: Robot, q: Any, qd: Any, qdd: Any) -> InverseDerivatives:
    """∂τ/∂q, ∂τ/∂q̇, ∂τ/∂q̈ of the inverse dynamics at each state (N, nv) [SI units].

    Raises:
        InputError: not a Robot, shapes that differ from (N, nv), or a non-finite value.
    """
    arrays = _arrays(robot, ("q", q), ("qd", qd), ("qdd", qdd))
    return InverseDerivatives(
        *_along(robot, "computeRNEADerivatives", *arrays, ("dtau_dq", "dtau_dv", "M"))
    )


def forward_derivatives(robot: Robot, q: Any, qd: Any, tau: Any) -> ForwardDerivatives:
    """∂q̈/∂q, ∂q̈/∂q̇, ∂q̈/∂τ of the forward dynamics at each state (N, nv) [SI units].

    Raises:
        InputError: not a Robot, shapes that differ from (N, nv), or a non-finite value.
    """
    arrays = _arrays(robot, ("q", q), ("qd", qd), ("tau", tau))
    return ForwardDerivatives(
        *_along(robot, "computeABADerivatives", *arrays, ("ddq_dq", "ddq_dv", "Minv"))
    )
