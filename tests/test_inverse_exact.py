"""Every backend's efforts against a 30-digit reference, and the exact mount rotation."""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.core.grid import time_grid
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.model import rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from tests.support import random_params, random_states

BACKENDS = [
    "pinocchio",
    "symbolic",
    pytest.param(
        "compiled",
        marks=pytest.mark.skipif(importlib.util.find_spec("numba") is None, reason="no numba"),
    ),
]
#: Agreement asked of every backend: per effort, max |τ − τ_ref| / max |τ_ref|.
AGREEMENT = 1e-15


def _relative(tau: np.ndarray, ref: np.ndarray) -> np.ndarray:
    return np.abs(tau - ref).max(axis=0) / np.abs(ref).max(axis=0)


@pytest.fixture(scope="module", params=["chapter", "random"])
def case(request):
    """States, their 30-digit efforts: the chapter's run (eq. 30) or random states and arm."""
    pytest.importorskip("mpmath")
    from rrt_pin.cli.bench_measure import mpmath_inverse_reference

    if request.param == "chapter":
        p = Params()
        traj = rest_to_rest(p.q0, p.qf, p.Tp, time_grid(p.Tp, 1e-3))
        sel = slice(None, None, 250)  # 61 of the 15,001 samples, both ends included
        q, qd, qdd = traj.q[sel], traj.qd[sel], traj.qdd[sel]
    else:
        rng = np.random.default_rng(16)
        p = random_params(rng)
        q, qd, qdd = random_states(rng, 40)
    return p, q, qd, qdd, mpmath_inverse_reference(q, qd, qdd, p)


@pytest.mark.parametrize("backend", BACKENDS)
def test_every_backend_agrees_with_the_30_digit_reference(case, backend):
    p, q, qd, qdd, ref = case
    if backend == "pinocchio":
        tau = inverse_dynamics(chapter_arm(p), q, qd, qdd)
    else:
        tau = inverse_dynamics(chapter_arm(p), q, qd, qdd, backend=backend)
    worst = _relative(tau, ref)
    assert worst.max() <= AGREEMENT, dict(zip(("T01x", "T12y", "F23z"), worst, strict=True))


@pytest.mark.parametrize("case", ["chapter"], indirect=True)
def test_the_rpy_mount_alone_misses_the_agreement(case):
    """The test above can fail: with the URDF's roll/pitch/yaw rotation, the chapter's T01x
    (small: 5.8 N·m at most, against hundreds for the others) is off by ~7e-14 relative."""
    import pinocchio as pin

    from rrt_pin.robot.model import model_from_xml
    from rrt_pin.robot.urdf import urdf_xml

    p, q, qd, qdd, ref = case
    model = model_from_xml(urdf_xml(p))
    model.gravity.linear[:] = (0.0, 0.0, -p.g)
    data = model.createData()
    tau = np.array([pin.rnea(model, data, a, b, c) for a, b, c in zip(q, qd, qdd, strict=True)])
    assert _relative(tau, ref)[0] > 10 * AGREEMENT


def test_mount_rotation_is_the_exact_permutation():
    import pinocchio as pin

    from rrt_pin.robot.urdf import MOUNT_ROTATION, MOUNT_RPY

    exact = np.array(MOUNT_ROTATION)
    # What the URDF's roll/pitch/yaw stand for, computed independently.
    np.testing.assert_allclose(pin.rpy.rpyToMatrix(*MOUNT_RPY), exact, atol=1e-15)
    model = rrt_model(Params())
    np.testing.assert_array_equal(model.jointPlacements[model.getJointId("q1")].rotation, exact)
    for name in ("mount", "link0"):
        frame = model.frames[model.getFrameId(name)]
        np.testing.assert_array_equal(frame.placement.rotation, exact)
    # Chapter's ı0 is the world's +z, ȷ0 its +x, k0 its +y.
    np.testing.assert_array_equal(exact @ [1, 0, 0], [0, 0, 1])
    np.testing.assert_array_equal(exact @ [0, 1, 0], [1, 0, 0])


@pytest.mark.parametrize("backend", ["symbolic", *BACKENDS[2:]])
@pytest.mark.parametrize("column", range(9))
@pytest.mark.parametrize("value", [np.nan, np.inf, -np.inf])
def test_nonfinite_inputs_are_named_alike_by_the_kernel_backends(backend, column, value):
    """The compiled backend flags them in its loop, then names them as the numpy path does."""
    rng = np.random.default_rng(column)
    arrays = list(random_states(rng, 700))  # more than one of the compiled loop's blocks
    name = ("q", "qd", "qdd")[column // 3]
    arrays[column // 3][613, column % 3] = value
    with pytest.raises(InputError) as info:
        inverse_dynamics(chapter_arm(Params()), *arrays, backend=backend)
    assert f"{name}[613, {column % 3}]={value!r} must be finite" in str(info.value)


@pytest.mark.parametrize("backend", ["symbolic", *BACKENDS[2:]])
def test_overflowing_efforts_are_named_alike(backend):
    q, qd, qdd = np.zeros((600, 3)), np.zeros((600, 3)), np.zeros((600, 3))
    qd[517] = 1e200  # finite, but q̇² overflows
    with pytest.raises(InputError, match="the efforts overflow: .* at sample 517"):
        inverse_dynamics(chapter_arm(Params()), q, qd, qdd, backend=backend)


@pytest.mark.parametrize("backend", BACKENDS[2:])
def test_huge_finite_values_are_no_false_alarm(backend):
    """τ1 + τ2 + τ3 may overflow while each τ is finite: the result is still returned."""
    from rrt_pin.dynamics import kernel

    p = Params()
    q, qd, qdd = np.zeros((3, 3)), np.zeros((3, 3)), np.zeros((3, 3))
    qdd[1] = 0.7e308 / np.diag(kernel.mass_matrix(q[1], p))  # each τ_i ≈ 0.7e308
    tau = inverse_dynamics(chapter_arm(p), q, qd, qdd, backend=backend)
    expected = inverse_dynamics(chapter_arm(p), q, qd, qdd, backend="symbolic")
    assert np.isfinite(tau).all()
    np.testing.assert_allclose(tau, expected, rtol=1e-15)
