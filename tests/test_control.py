"""Feedback laws: eq. (31) as printed, PD + Pinocchio gravity, their agreement, validation."""

import math

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core.errors import InputError, ParameterError
from rrt_pin.robot.model import load_urdf_model, rrt_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate.control import (
    PDGravityController,
    SeedController,
    pd_gravity_controller,
    seed_controller,
)
from tests.support import TIGHT, holding_efforts, random_states, robot_urdf


def eq31(p: Params, q, qd):
    """Eq. (31), typed from the chapter."""
    c2, s2 = math.cos(q[1]), math.sin(q[1])
    return np.array(
        [
            -p.beta01 * qd[0] - p.gamma01 * (q[0] - p.q1f),
            -p.beta12 * qd[1]
            - p.gamma12 * (q[1] - p.q2f)
            + p.g * p.m2 * p.L2 * c2
            + p.g * p.m3 * c2 * (p.L2 + q[2]),
            -p.beta23 * qd[2] - p.gamma23 * (q[2] - p.q3f) + p.g * p.m3 * s2,
        ]
    )


def close(a, b, rel=TIGHT):
    scale = max(1.0, float(np.abs(b).max()))
    np.testing.assert_allclose(a, b, rtol=0, atol=rel * scale)


def test_seed_controller_is_eq31(seed_params, rng):
    c = seed_controller(seed_params)
    assert c.kind == "chapter"
    assert c.kp == seed_params.kp and c.kd == seed_params.kd and c.qf == seed_params.qf
    q, qd, _ = random_states(rng, 50)
    for a, b in zip(q, qd, strict=True):
        close(c(a, b), eq31(seed_params, a, b))


def test_seed_law_gravity_is_eq15_and_other_arms(rng):
    p = Params(m2=33.0, m3=7.5, L2=1.3, g=3.7, gamma12=10.0)
    c = seed_controller(p)
    q, qd, _ = random_states(rng, 20)
    for a, b in zip(q, qd, strict=True):
        close(c(a, b), eq31(p, a, b))
        close(c.gravity(a), holding_efforts(p, a))


def test_seed_and_pd_gravity_agree_on_the_rrt_arm(seed_params, seed_model, rng):
    """The seed's law is PD plus exactly Pinocchio's generalized gravity of the arm."""
    seed = seed_controller(seed_params)
    pdg = pd_gravity_controller(
        chapter_arm(seed_params), seed_params.kp, seed_params.kd, seed_params.qf
    )
    assert pdg.kind == "pd_gravity"
    q, qd, _ = random_states(rng, 200)
    for a, b in zip(q, qd, strict=True):
        close(pdg(a, b), seed(a, b))
    close(pdg.efforts(q, qd), seed.efforts(q, qd))


@pytest.mark.parametrize("kind", ["seed", "pd_gravity"])
def test_batched_efforts_equal_single_calls(kind, seed_params, seed_model, rng):
    c = (
        seed_controller(seed_params)
        if kind == "seed"
        else pd_gravity_controller(chapter_arm(seed_params), [1.0, 2.0, 3.0], 4.0, [0.1, 0.2, 0.3])
    )
    q, qd, _ = random_states(rng, 30)
    batch = c.efforts(q, qd)
    assert batch.shape == (30, 3)
    for i in range(30):
        close(batch[i], c(q[i], qd[i]))


def test_pd_gravity_on_another_model(rng):
    """PD + G for a 6-joint URDF: G from computeGeneralizedGravity, batched by rneaInParallel."""
    model = load_urdf_model(robot_urdf("ur5"))
    data = model.createData()
    kp, kd = np.arange(1.0, 7.0), np.full(6, 2.5)
    qf = rng.uniform(-1, 1, 6)
    c = pd_gravity_controller(Robot.from_model(model), kp, kd, qf)
    q = rng.uniform(-np.pi, np.pi, (10, 6))
    qd = rng.normal(0, 1, (10, 6))
    batch = c.efforts(q, qd)
    for i in range(10):
        expected = -kd * qd[i] - kp * (q[i] - qf) + pin.computeGeneralizedGravity(model, data, q[i])
        close(c(q[i], qd[i]), expected)
        close(batch[i], expected)


@pytest.mark.parametrize("kind", ["seed", "pd_gravity"])
def test_derivatives_match_finite_differences(kind, seed_params, seed_model, rng):
    c = (
        seed_controller(seed_params)
        if kind == "seed"
        else pd_gravity_controller(
            chapter_arm(seed_params), seed_params.kp, seed_params.kd, seed_params.qf
        )
    )
    q, qd, _ = random_states(rng, 5)
    h = 1e-6
    for a, b in zip(q, qd, strict=True):
        dq, dqd = c.derivatives(a, b)
        for k in range(3):
            e = np.eye(3)[k] * h
            np.testing.assert_allclose(dq[:, k], (c(a + e, b) - c(a - e, b)) / (2 * h), atol=1e-5)
            np.testing.assert_allclose(dqd[:, k], (c(a, b + e) - c(a, b - e)) / (2 * h), atol=1e-5)


def test_gravity_compensation_is_recognised_only_for_the_same_arm(seed_params, seed_model):
    seed = seed_controller(seed_params)
    assert seed.compensates_gravity_of(seed_model)
    assert seed.compensates_gravity_of(rrt_model(seed_params))
    assert not seed.compensates_gravity_of(rrt_model(seed_params.with_overrides({"m3": 41.0})))
    tuned = Params(gamma01=1.0, beta23=3.0, q1f=0.2, q20=0.1, I3x=4.5, L1=0.5)
    assert seed_controller(tuned).compensates_gravity_of(rrt_model(tuned))
    pdg = pd_gravity_controller(chapter_arm(seed_params), 1.0, 1.0, [0, 0, 0])
    assert pdg.compensates_gravity_of(seed_model)
    other = rrt_model(seed_params.with_overrides({"g": 9.0}))
    assert not pdg.compensates_gravity_of(other)


def test_pd_gravity_keeps_its_own_copy_of_the_model(seed_params):
    model = rrt_model(seed_params)
    c = pd_gravity_controller(Robot.from_model(model), 1.0, 1.0, [0, 0, 0])
    before = c(np.zeros(3) + 0.3, np.zeros(3))
    model.gravity.linear[:] = (0.0, 0.0, -1.0)
    np.testing.assert_array_equal(c(np.zeros(3) + 0.3, np.zeros(3)), before)


def test_scalar_gains_apply_to_every_joint(seed_model):
    c = pd_gravity_controller(Robot.from_model(seed_model), 7.0, 0.5, [0.1, 0.2, 0.3])
    assert c.kp == (7.0, 7.0, 7.0) and c.kd == (0.5, 0.5, 0.5)


def test_controllers_are_frozen(seed_params):
    c = seed_controller(seed_params)
    with pytest.raises(AttributeError):
        c.kp = (1.0, 1.0, 1.0)  # type: ignore[misc]


@pytest.mark.parametrize(
    "field, value, words",
    [
        ("kp", [1.0, -2.0, 3.0], "kp[1]=-2.0: gain must be >= 0"),
        ("kd", [1.0, 2.0, float("nan")], "kd[2]=nan: gain must be finite"),
        ("kd", float("inf"), "kd[0]=inf: gain must be finite"),
        ("kp", [1.0, 2.0], "kp has shape (2,) but the model has 3 joints"),
        ("qf", [0.0, float("inf"), 0.0], "qf[1]=inf must be finite"),
        ("qf", [0.0, 0.0, 0.0, 0.0], "qf has shape (4,) but the model has 3 joints"),
        ("kp", "stiff", "kp='stiff' is not a number"),
    ],
)
def test_bad_gains_and_targets_are_refused_naming_the_value(
    seed_params, seed_model, field, value, words
):
    good = {"kp": [1.0, 1.0, 1.0], "kd": [1.0, 1.0, 1.0], "qf": [0.0, 0.0, 0.0]}
    error = ParameterError if field in ("kp", "kd") and "gain" in words else InputError
    with pytest.raises(error) as info:
        pd_gravity_controller(chapter_arm(seed_params), **{**good, field: value})
    assert words in str(info.value)
    with pytest.raises(error) as info:
        SeedController(**{**good, field: value}, params=seed_params)
    assert words in str(info.value)


def test_pd_gravity_needs_a_pinocchio_model():
    with pytest.raises(InputError, match="must be a pinocchio.Model"):
        PDGravityController(kp=(1.0,), kd=(1.0,), qf=(0.0,), model="arm.urdf")  # type: ignore[arg-type]


def test_efforts_refuse_bad_shapes(seed_params):
    with pytest.raises(InputError, match=r"shape \(N, 3\)"):
        seed_controller(seed_params).efforts(np.zeros((4, 2)), np.zeros((4, 2)))


def test_the_chapter_law_of_params_is_the_law_built_from_its_fields():
    """``ChapterController.of(p)`` (a sweep's fast path) is the checked law, field by field."""
    from rrt_pin.simulate.control import ChapterController as _Law

    rng = np.random.default_rng(2)
    for _ in range(20):
        p = Params(m3=float(rng.uniform(20, 60)), gamma12=float(rng.uniform(0, 500)),
                    q2f=float(rng.uniform(-1, 1)), beta23=float(rng.uniform(0, 300)))  # fmt: skip
        fast, checked = _Law.of(p), _Law(kp=p.kp, kd=p.kd, qf=p.qf, params=p)
        assert (fast.kp, fast.kd, fast.qf, fast.params) == (
            checked.kp, checked.kd, checked.qf, checked.params,
        )  # fmt: skip
        assert all(type(v) is float for v in (*fast.kp, *fast.kd, *fast.qf))
        q, qd = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
        np.testing.assert_array_equal(
            fast.efforts_many(0.0, q, qd), checked.efforts_many(0.0, q, qd)
        )
    with pytest.raises(InputError, match="params must be a Params"):
        _Law.of({"m3": 40.0})
