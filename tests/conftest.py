"""Shared fixtures: the seed's parameters and model, seeded random states."""

from __future__ import annotations

import numpy as np
import pytest

from rrt_pin.params import Params
from tests.support import DERIVED, TIGHT, random_states  # noqa: F401  (re-exported for fixtures)


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
