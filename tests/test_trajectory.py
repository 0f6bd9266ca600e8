"""The rest-to-rest motion of eq. (30): ends, derivatives, any number of joints, bad input."""

import math

import numpy as np
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.trajectory import Trajectory, rest_to_rest
from tests.support import TIGHT

FD_STEP = 1e-4  # central differences [s]: error ~ h²·|q'''| ≈ 1e-8·|qf − q0|·(2π/Tp)²


def eq30(q0, qf, Tp, t):
    """Eq. (30) typed in from the seed, one coordinate, one time (math, not numpy)."""
    return q0 + (qf - q0) / Tp * (t - Tp / (2 * math.pi) * math.sin(2 * math.pi * t / Tp))


def test_seed_motion_matches_eq_30(seed_params):
    p = seed_params
    t = time_grid(p.Tp, 0.01)
    traj = rest_to_rest(p.q0, p.qf, p.Tp, t)
    assert isinstance(traj, Trajectory) and len(traj) == t.size == 1501 and traj.n == 3
    expected = np.array(
        [[eq30(a, b, p.Tp, ti) for a, b in zip(p.q0, p.qf, strict=True)] for ti in t]
    )
    np.testing.assert_allclose(traj.q, expected, rtol=TIGHT, atol=TIGHT)
    np.testing.assert_array_equal(traj.t, t)


def test_starts_and_ends_at_rest(seed_params):
    p = seed_params
    traj = rest_to_rest(p.q0, p.qf, p.Tp, [0.0, p.Tp])
    np.testing.assert_array_equal(traj.q[0], p.q0)
    np.testing.assert_array_equal(traj.q[1], p.qf)
    np.testing.assert_array_equal(traj.qd, np.zeros((2, 3)))
    np.testing.assert_allclose(traj.qdd, np.zeros((2, 3)), rtol=0, atol=1e-15)


def test_midpoint_and_peak_speed(seed_params):
    # Half way, the motion is half done at its top speed 2·(qf − q0)/Tp, with zero acceleration.
    p = seed_params
    traj = rest_to_rest(p.q0, p.qf, p.Tp, p.Tp / 2)
    dq = np.subtract(p.qf, p.q0)
    np.testing.assert_allclose(traj.q[0], np.add(p.q0, p.qf) / 2, rtol=TIGHT)
    np.testing.assert_allclose(traj.qd[0], 2 * dq / p.Tp, rtol=TIGHT)
    np.testing.assert_allclose(traj.qdd[0], 0.0, atol=1e-16)


@pytest.mark.parametrize("n", [1, 3, 7])
def test_derivatives_match_finite_differences(rng, n):
    q0, qf = rng.uniform(-2, 2, n), rng.uniform(-2, 2, n)
    Tp = 4.0
    t = np.linspace(0.05, Tp - 0.05, 97)
    here = rest_to_rest(q0, qf, Tp, t)
    ahead = rest_to_rest(q0, qf, Tp, t + FD_STEP)
    behind = rest_to_rest(q0, qf, Tp, t - FD_STEP)
    scale = np.abs(qf - q0).max()
    fd_qd = (ahead.q - behind.q) / (2 * FD_STEP)
    fd_qdd = (ahead.qd - behind.qd) / (2 * FD_STEP)
    fd_qdd2 = (ahead.q - 2 * here.q + behind.q) / FD_STEP**2
    np.testing.assert_allclose(here.qd, fd_qd, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(here.qdd, fd_qdd, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(here.qdd, fd_qdd2, rtol=0, atol=1e-6 * scale)


def test_rest_outside_the_motion(seed_params):
    p = seed_params
    traj = rest_to_rest(p.q0, p.qf, p.Tp, [-1.0, p.Tp + 0.5, 100.0])
    np.testing.assert_array_equal(traj.q, [p.q0, p.qf, p.qf])
    np.testing.assert_array_equal(traj.qd, np.zeros((3, 3)))
    np.testing.assert_array_equal(traj.qdd, np.zeros((3, 3)))


def test_scalar_time_and_read_only_result(seed_params):
    p = seed_params
    traj = rest_to_rest(p.q0, p.qf, p.Tp, 1.0)
    assert traj.q.shape == (1, 3) and traj.t.shape == (1,)
    with pytest.raises(ValueError):
        traj.q[0, 0] = 1.0
    with pytest.raises(AttributeError):
        traj.q = None  # frozen dataclass


def test_input_arrays_are_not_aliased():
    t = np.array([0.0, 1.0])
    traj = rest_to_rest([0.0], [1.0], 2.0, t)
    t[0] = 5.0
    assert traj.t[0] == 0.0


@pytest.mark.parametrize(
    "args, words",
    [
        (([0.0, 0.0], [1.0], 1.0, [0.0]), "q0 has 2 values but qf has 1"),
        (([0.0], [1.0], 0.0, [0.0]), "Tp=0.0 must be finite and > 0"),
        (([0.0], [1.0], -3.0, [0.0]), "Tp=-3.0 must be finite and > 0"),
        (([0.0], [1.0], math.inf, [0.0]), "Tp=inf must be finite"),
        (([0.0], [1.0], math.nan, [0.0]), "Tp=nan must be finite"),
        (([0.0], [1.0], "2", [0.0]), "Tp='2' must be a number"),
        (([math.nan], [1.0], 1.0, [0.0]), "q0[0]=nan must be finite"),
        (([0.0], [0.0, math.inf], 1.0, [0.0]), "qf[1]=inf must be finite"),
        (([0.0], [1.0], 1.0, [0.0, math.nan]), "t[1]=nan must be finite"),
        (([0.0], [1.0], 1.0, [[0.0]]), "t must be a number or 1-D"),
        (([], [], 1.0, [0.0]), "q0 must be a non-empty 1-D sequence"),
        ((["a"], [1.0], 1.0, [0.0]), "q0 is not an array of numbers"),
    ],
)
def test_bad_input(args, words):
    with pytest.raises(InputError) as info:
        rest_to_rest(*args)
    assert words in str(info.value)
