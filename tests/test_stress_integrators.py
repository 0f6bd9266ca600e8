"""Numerical-stability stress tests of the integrators.

Passive motion conserves energy; stiff control never fails silently.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.errors import DivergenceError
from rrt_pin.core.grid import time_grid
from rrt_pin.robot.model import rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import simulate
from rrt_pin.simulate.control import seed_controller
from rrt_pin.simulate.symplectic import leapfrog, mechanical_energy

ENERGY_TOL = 1e-9  # |E(t) − E(0)| ≤ ENERGY_TOL · max T over the run
GAINS = ("beta01", "gamma01", "beta12", "gamma12", "beta23", "gamma23")


def passive(q: np.ndarray, qd: np.ndarray) -> np.ndarray:
    """All efforts zero: gravity alone, no damping."""
    return np.zeros(3)


def kinetic(model, q, qd) -> np.ndarray:
    data = model.createData()
    return np.array(
        [pin.computeKineticEnergy(model, data, a, b) for a, b in zip(q, qd, strict=True)]
    )


def initial_states():
    p = Params()
    rng = np.random.default_rng(99)
    yield "seed q(0)", np.array(p.q0), np.zeros(3)
    for i in range(3):
        q = np.array(
            [rng.uniform(-np.pi, np.pi), rng.uniform(-np.pi / 2, np.pi / 2), rng.uniform(-0.5, 1.0)]
        )
        yield f"random {i}", q, rng.normal(0.0, 1.0, 3)


@pytest.mark.parametrize(
    "label, q0, qd0", list(initial_states()), ids=lambda x: x if isinstance(x, str) else ""
)
def test_passive_energy_is_conserved_by_a_tight_adaptive_method(seed_model, label, q0, qd0):
    t = time_grid(100.0, 0.5)
    r = simulate(
        Robot.from_model(seed_model), passive, q0, qd0, t, method="DOP853", rtol=1e-12, atol=1e-14
    )
    E = mechanical_energy(seed_model, r.q, r.qd)
    T = kinetic(seed_model, r.q, r.qd)
    drift = np.abs(E - E[0]).max()
    assert drift <= ENERGY_TOL * T.max(), f"{label}: drift {drift:.3g} J, max T {T.max():.3g} J"
    # The motion is violent (the free slider slides out), so the check is not vacuous.
    assert T.max() > 1e3


def test_a_loose_method_does_drift(seed_model):
    # The energy check can fail: explicit Euler-like loose integration breaks it.
    p = Params()
    t = time_grid(100.0, 0.5)
    r = simulate(
        Robot.from_model(seed_model), passive, p.q0, p.qd0, t, method="symplectic_euler", step=0.01
    )
    E = mechanical_energy(seed_model, r.q, r.qd)
    assert np.abs(E - E[0]).max() > ENERGY_TOL * kinetic(seed_model, r.q, r.qd).max()


@pytest.mark.slow
def test_symplectic_leapfrog_energy_stays_bounded_over_1000_s(seed_model):
    p = Params()
    t = time_grid(1000.0, 1.0)
    r = leapfrog(seed_model, p.q0, [1.0, 0.5, 0.0], t, step=0.02)
    dE = np.abs(
        mechanical_energy(seed_model, r.q, r.qd) - mechanical_energy(seed_model, r.q[:1], r.qd[:1])
    )
    T = kinetic(seed_model, r.q, r.qd)
    early, late = dE[:100].max(), dE[600:].max()
    print(
        f"leapfrog: max |ΔE| {early:.3g} J over 0..100 s, {late:.3g} J over 600..1000 s; max T {T.max():.3g} J"
    )
    assert dE.max() <= ENERGY_TOL * T.max()
    # No secular drift: the late error is no larger than the early one, although T grew 100-fold.
    assert late <= 1.5 * early
    assert T[600:].max() > 50 * T[:100].max()


def test_leapfrog_is_second_order_and_time_reversible(seed_model):
    p = Params()
    t = np.array([0.0, 1.0])
    exact = simulate(
        Robot.from_model(seed_model),
        passive,
        p.q0,
        [0.3, 0.2, 0.1],
        t,
        method="DOP853",
        rtol=1e-13,
        atol=1e-15,
    )
    errs = []
    for h in (0.02, 0.01):
        r = leapfrog(seed_model, p.q0, [0.3, 0.2, 0.1], t, step=h)
        errs.append(np.abs(r.q[-1] - exact.q[-1]).max())
    order = np.log2(errs[0] / errs[1])
    assert 1.8 < order < 2.2, errs
    fwd = leapfrog(seed_model, p.q0, [0.3, 0.2, 0.1], t, step=0.01)
    back = leapfrog(seed_model, fwd.q[-1], -fwd.qd[-1], t, step=0.01)
    np.testing.assert_allclose(back.q[-1], p.q0, atol=1e-11)


def _stiff(k: float) -> Params:
    base = Params()
    return base.with_overrides({n: getattr(base, n) * k for n in GAINS})


@pytest.mark.parametrize("k", [100.0, 1e4])
@pytest.mark.parametrize("method", ["Radau", "BDF", "LSODA"])
def test_implicit_methods_reach_qf_under_stiff_gains(k, method):
    p = _stiff(k)
    r = simulate(
        chapter_arm(p), seed_controller(p), p.q0, p.qd0, time_grid(15.0, 0.01), method=method
    )
    assert np.abs(r.q[-1] - np.array(p.qf)).max() < 1e-3


@pytest.mark.parametrize("k, tf", [(100.0, 15.0), (1e4, 0.3)])
@pytest.mark.parametrize("method", ["RK45", "DOP853"])
def test_explicit_adaptive_methods_converge_under_stiff_gains(k, tf, method):
    # They stay stable by shrinking the step; at ×10,000 that costs ~10⁵ evaluations a second.
    p = _stiff(k)
    t = time_grid(tf, 0.01)
    model, ctrl = rrt_model(p), seed_controller(p)
    r = simulate(
        Robot.from_model(model), ctrl, p.q0, p.qd0, t, method=method, rtol=1e-8, atol=1e-10
    )
    ref = simulate(
        Robot.from_model(model), ctrl, p.q0, p.qd0, t, method="Radau", rtol=1e-11, atol=1e-13
    )
    assert np.isfinite(r.q).all()
    assert np.abs(r.q - ref.q).max() < 1e-6


@pytest.mark.parametrize("k", [100.0, 1e4])
@pytest.mark.parametrize("method", ["rk4", "symplectic_euler", "verlet"])
def test_explicit_fixed_step_methods_report_instability(k, method):
    p = _stiff(k)
    with pytest.raises(DivergenceError) as info:
        simulate(
            chapter_arm(p),
            seed_controller(p),
            p.q0,
            p.qd0,
            time_grid(15.0, 0.01),
            method=method,
            step=0.01,
        )
    e = info.value
    assert 0.0 < e.t < 15.0
    assert e.coordinate in ("q1", "q2", "q3", "qd1", "qd2", "qd3")
    assert f"t={e.t:.6g} s" in str(e) and e.coordinate in str(e)
