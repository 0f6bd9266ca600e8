"""Numerical-stability stress tests of the dynamics.

Extreme but valid scenes, and consistency of independent algorithms at many
seeded random states. Condition numbers are printed (``pytest -s``) and kept
in the assertions' tolerances: an error is judged against cond(M)·1e-14.
"""

from __future__ import annotations

import itertools

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.robot.model import rrt_model
from rrt_pin.robot.params import Params
from tests.support import random_states

EPS_ALGO = 1e-14  # per unit of cond(M): the accuracy ABA/RNEA should keep
N_RANDOM = 1000


def _full(M: np.ndarray) -> np.ndarray:
    return np.triu(M) + np.triu(M, 1).T


def _scene(mass: float, length: float) -> Params:
    # Scale the slider's inertia with the scene so the triangle inequality holds.
    return Params(
        m1=mass,
        m2=mass,
        m3=mass,
        L1=length,
        L2=length,
        I3x=5e-2 * mass * length**2,
        I3y=4e-2 * mass * length**2,
        I3z=1e-2 * mass * length**2,
    )


EXTREMES = list(itertools.product([1e-3, 1.0, 1e4], [1e-3, 0.4, 10.0]))


@pytest.mark.parametrize("mass, length", EXTREMES)
def test_rnea_after_aba_returns_the_efforts(mass, length):
    """q3 < 0 (slider through B), q2 = ±π/2 (arm vertical), speeds of 100 rad/s."""
    p = _scene(mass, length)
    model = rrt_model(p)
    data = model.createData()
    rng = np.random.default_rng(7)
    worst = 0.0
    for q2, q3 in itertools.product(
        [np.pi / 2, -np.pi / 2, 0.3], [-2.5 * length, -0.5 * length, 0.0, 2.0 * length]
    ):
        q = np.array([rng.uniform(-np.pi, np.pi), q2, q3])
        qd = np.array([100.0, -100.0, 100.0 * length])
        b = pin.nonLinearEffects(model, data, q, qd)
        tau = b + rng.normal(size=3) * np.abs(b).max()
        qdd = pin.aba(model, data, q, qd, tau)
        assert np.all(np.isfinite(qdd))
        back = pin.rnea(model, data, q, qd, qdd)
        cond = np.linalg.cond(_full(pin.crba(model, data, q)))
        err = np.linalg.norm(back - tau) / (np.linalg.norm(tau) + np.linalg.norm(b))
        worst = max(worst, err)
        assert err <= cond * EPS_ALGO, f"{q=} {cond=:.3g} {err=:.3g}"
    print(f"m={mass:g} kg, L={length:g} m: worst relative error {worst:.2e}")


def test_seed_scale_round_trip_within_1e_9(seed_model, rng):
    data = seed_model.createData()
    q, qd, _ = random_states(rng, 200)
    q[:, 1] = np.where(rng.random(200) < 0.2, np.pi / 2, q[:, 1])
    qd *= 50.0
    for qi, qdi in zip(q, qd, strict=True):
        tau = rng.normal(size=3) * 1e3
        back = pin.rnea(seed_model, data, qi, qdi, pin.aba(seed_model, data, qi, qdi, tau))
        assert np.abs(back - tau).max() <= 1e-9 * np.abs(tau).max()


def test_condition_number_of_the_seed_mass_matrix_is_reported(seed_model):
    data = seed_model.createData()
    conds = []
    for q2 in np.linspace(-np.pi, np.pi, 13):
        for q3 in (-1.0, 0.0, 0.25, 1.0):
            conds.append(np.linalg.cond(_full(pin.crba(seed_model, data, np.array([0.0, q2, q3])))))
    print(f"cond(M) over q2 ∈ [-π, π], q3 ∈ [-1, 1] m: {min(conds):.3g} … {max(conds):.3g}")
    assert max(conds) < 1e4  # the seed's arm is well conditioned everywhere sampled


def test_aba_equals_minv_tau_minus_b_at_1000_states(seed_model, rng):
    data = seed_model.createData()
    q, qd, _ = random_states(rng, N_RANDOM)
    for qi, qdi in zip(q, qd, strict=True):
        tau = rng.normal(size=3) * 500.0
        M = _full(pin.crba(seed_model, data, qi))
        b = pin.rnea(seed_model, data, qi, qdi, np.zeros(3))
        expected = np.linalg.solve(M, tau - b)
        got = pin.aba(seed_model, data, qi, qdi, tau)
        assert np.abs(got - expected).max() <= 1e-12 * max(1.0, np.abs(expected).max())


def test_crba_equals_rnea_columns_at_1000_states(seed_model, rng):
    data = seed_model.createData()
    q, _, _ = random_states(rng, N_RANDOM)
    zero = np.zeros(3)
    gravity_off = seed_model.copy()
    gravity_off.gravity.linear[:] = 0.0
    data0 = gravity_off.createData()
    for qi in q:
        M = _full(pin.crba(seed_model, data, qi))
        cols = np.column_stack([pin.rnea(gravity_off, data0, qi, zero, e) for e in np.eye(3)])
        assert np.abs(M - cols).max() <= 1e-12 * np.abs(M).max()


def test_symbolic_kernel_equals_pinocchio_at_1000_states(seed_model, seed_params, rng):
    from rrt_pin.dynamics import kernel

    data = seed_model.createData()
    q, qd, qdd = random_states(rng, N_RANDOM)
    tau = rng.normal(size=(N_RANDOM, 3)) * 500.0
    M = kernel.mass_matrix(q, seed_params)
    id_k = kernel.inverse_dynamics(q, qd, qdd, seed_params)
    fd_k = kernel.forward_dynamics(q, qd, tau, seed_params)
    for i in range(N_RANDOM):
        M_p = _full(pin.crba(seed_model, data, q[i]))
        assert np.abs(M[i] - M_p).max() <= 1e-12 * np.abs(M_p).max()
        id_p = pin.rnea(seed_model, data, q[i], qd[i], qdd[i])
        assert np.abs(id_k[i] - id_p).max() <= 1e-12 * max(1.0, np.abs(id_p).max())
        fd_p = pin.aba(seed_model, data, q[i], qd[i], tau[i])
        assert np.abs(fd_k[i] - fd_p).max() <= 1e-12 * max(1.0, np.abs(fd_p).max())
