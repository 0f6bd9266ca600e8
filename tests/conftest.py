"""Shared fixtures: the seed's parameters and model, seeded random states."""

from __future__ import annotations

import numpy as np
import pytest

from rrt_pin.params import Params

#: Tolerances, named once (relative unless the name says otherwise).
TIGHT = 1e-12
DERIVED = 1e-10


@pytest.fixture(scope="session")
def seed_params() -> Params:
    return Params()


@pytest.fixture(scope="session")
def seed_model(seed_params):
    from rrt_pin.model import rrt_model

    return rrt_model(seed_params)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def random_states(rng: np.random.Generator, n: int):
    """n seeded states (q, q̇, q̈) of the RRT arm, q3 in [-0.5, 1] m."""
    q = np.column_stack(
        [rng.uniform(-np.pi, np.pi, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.5, 1.0, n)]
    )
    qd = rng.normal(0.0, 2.0, (n, 3))
    qdd = rng.normal(0.0, 5.0, (n, 3))
    return q, qd, qdd
