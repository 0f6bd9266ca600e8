"""Derivatives of the dynamics for optimisers: against central finite differences."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

import rrt_pin
from rrt_pin.core.errors import InputError
from rrt_pin.dynamics.derivatives import forward_derivatives, inverse_derivatives
from rrt_pin.robot.robots import chapter_arm, get


def _fd(f, x, h=1e-6):
    """Central differences of f (nv,) -> (nv,) at x: (nv, nv), column j = ∂f/∂x_j."""
    cols = []
    for j in range(x.size):
        e = np.zeros_like(x)
        e[j] = h
        cols.append((f(x + e) - f(x - e)) / (2 * h))
    return np.column_stack(cols)


@pytest.mark.parametrize("name", ["rrt", "ur5", "double_pendulum_continuous"])
def test_derivatives_equal_finite_differences(name):
    robot = chapter_arm() if name == "rrt" else get(name)
    rng = np.random.default_rng(4)
    q, qd, qdd = (rng.uniform(-1, 1, (3, robot.nv)) for _ in range(3))
    model, data = robot.model, robot.model.createData()

    def rnea(q_, v_, a_):
        return pin.rnea(model, data, robot.configuration(q_), v_, a_)

    def aba(q_, v_, t_):
        return pin.aba(model, data, robot.configuration(q_), v_, t_)

    inv = inverse_derivatives(robot, q, qd, qdd)
    tau = np.array([rnea(*s) for s in zip(q, qd, qdd, strict=True)])
    fwd = forward_derivatives(robot, q, qd, tau)
    for k in range(3):
        a, v, acc, t = q[k], qd[k], qdd[k], tau[k]
        checks = [
            (inv.dtau_dq[k], _fd(lambda x, v=v, acc=acc: rnea(x, v, acc), a)),
            (inv.dtau_dqd[k], _fd(lambda x, a=a, acc=acc: rnea(a, x, acc), v)),
            (inv.dtau_dqdd[k], _fd(lambda x, a=a, v=v: rnea(a, v, x), acc)),
            (fwd.dqdd_dq[k], _fd(lambda x, v=v, t=t: aba(x, v, t), a)),
            (fwd.dqdd_dqd[k], _fd(lambda x, a=a, t=t: aba(a, x, t), v)),
            (fwd.dqdd_dtau[k], _fd(lambda x, a=a, v=v: aba(a, v, x), t)),
        ]
        for analytic, numeric in checks:
            scale = max(1.0, np.abs(numeric).max())
            assert np.abs(analytic - numeric).max() <= 1e-6 * scale
        # ∂q̈/∂τ is M⁻¹: the two sides are inverses, and M is symmetric
        np.testing.assert_allclose(
            fwd.dqdd_dtau[k] @ inv.dtau_dqdd[k], np.eye(robot.nv), atol=1e-10
        )
        assert np.array_equal(inv.dtau_dqdd[k], inv.dtau_dqdd[k].T)


def test_the_check_can_fail_and_bad_inputs_are_one_line():
    arm = chapter_arm()
    z = np.zeros((2, 3))
    d = inverse_derivatives(arm, z, z, z)
    assert np.abs(d.dtau_dqdd[0] - np.eye(3)).max() > 1.0  # M is not the identity
    with pytest.raises(InputError, match=r"qd has shape \(2, 2\); RRT arm needs \(N, 3\)"):
        inverse_derivatives(arm, z, np.zeros((2, 2)), z)
    with pytest.raises(InputError, match=r"tau\[1, 0\]=nan is not finite"):
        forward_derivatives(arm, z, z, np.array([[0, 0, 0], [np.nan, 0, 0]]))
    with pytest.raises(InputError, match="robot must be a rrt_pin.Robot"):
        inverse_derivatives(arm.model, z, z, z)
    assert rrt_pin.derivatives.inverse_derivatives is inverse_derivatives
    assert rrt_pin.forward_derivatives is forward_derivatives
