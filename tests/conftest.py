"""Shared fixtures: the seed's parameters and model, seeded random states.

Two variables are set for the whole session (and the processes it starts):

* ``RRT_PIN_BACKEND=pinocchio``: the default backend (``auto``) picks compiled code when
  it is built, which depends on what earlier tests compiled; tests that do not name a
  backend test the engine of record. ``tests/test_defaults.py`` tests ``auto`` itself
  (the variable removed), and the sweep tests remove it for their modules
  (:func:`auto_backend`): a sweep chooses like every process it starts, which is what they test.
* ``RRT_PIN_AOT=0``: no generated kernel is built ahead of time (7–9 s each, beside the
  JIT's compilation); ``tests/test_defaults.py`` builds one on purpose.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import numpy as np
import pytest

from rrt_pin.robot.params import Params
from tests.support import DERIVED, TIGHT, random_states  # noqa: F401  (re-exported for fixtures)

os.environ["RRT_PIN_BACKEND"] = "pinocchio"
os.environ["RRT_PIN_AOT"] = "0"


@pytest.fixture(scope="session")
def seed_params() -> Params:
    return Params()


@pytest.fixture(scope="session")
def seed_model(seed_params):
    from rrt_pin.robot.model import rrt_model

    return rrt_model(seed_params)


@pytest.fixture(autouse=True)
def fresh_cpu_readings(monkeypatch):
    """Every reading of the free CPUs is taken anew (tests replace what it reads)."""
    from rrt_pin.core import cpus

    monkeypatch.setattr(cpus, "FRESH", 0.0)
    monkeypatch.setattr(cpus, "_last", (-1.0, 0))


@pytest.fixture(autouse=True)
def fresh_auto_ledger():
    """Each test's ``auto`` starts as a new process's: no earlier job's time counted."""
    from rrt_pin.core import backends

    backends.forget_forgone()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20261122)


def _mount(args: list[str], where: Path) -> None:
    proc = subprocess.run(["mount", *args, str(where)], capture_output=True, text=True)
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {proc.stderr.strip()}")


@pytest.fixture
def tiny_fs(tmp_path):
    """A 64 kB tmpfs inside tmp_path, unmounted afterwards."""
    where = tmp_path / "tiny"
    where.mkdir()
    _mount(["-t", "tmpfs", "-o", "size=64k,mode=0755", "tmpfs"], where)
    try:
        yield where
    finally:
        if subprocess.run(["umount", str(where)], capture_output=True).returncode != 0:
            subprocess.run(["umount", "-l", str(where)], capture_output=True)


@pytest.fixture(scope="module")
def auto_backend():
    """The default backend ``auto`` for a whole module (``$RRT_PIN_BACKEND`` removed)."""
    with pytest.MonkeyPatch.context() as mp:
        mp.delenv("RRT_PIN_BACKEND", raising=False)
        yield
