"""Batched Pinocchio RNEA: pools kept between calls, the same efforts whatever the threads."""

from __future__ import annotations

import numpy as np

from rrt_pin import cpus
from rrt_pin import inverse as inv
from rrt_pin.inverse import inverse_dynamics
from rrt_pin.robots import chapter_arm
from rrt_pin.trajectory import rest_to_rest


def _motion(n: int = 4001):
    arm = chapter_arm()
    d = arm.defaults
    return arm, rest_to_rest(d.q0, d.qf, 15.0, np.linspace(0.0, 15.0, n))


def test_same_efforts_bit_for_bit_whatever_the_threads():
    arm, m = _motion()
    one = inverse_dynamics(arm, m.q, m.qd, m.qdd, num_threads=1)
    for threads in (2, 3, None):
        np.testing.assert_array_equal(
            inverse_dynamics(arm, m.q, m.qd, m.qdd, num_threads=threads), one
        )


def test_the_pool_is_kept_between_calls_and_rebuilt_when_the_model_changes():
    arm, m = _motion(1001)
    model = arm.model
    inv._POOLS.clear()
    first = inv._pool(model, 2)
    assert inv._pool(model, 2) is first and inv._pool(model, 1) is first  # big enough
    before = inverse_dynamics(model, m.q, m.qd, m.qdd, num_threads=2)
    saved = model.gravity.linear.copy()
    try:
        model.gravity.linear = np.array([0.0, 0.0, -1.62])  # the Moon: a changed model
        assert inv._pool(model, 2) is not first
        moon = inverse_dynamics(model, m.q, m.qd, m.qdd, num_threads=2)
        assert not np.allclose(moon, before)  # the new gravity was used, not a stale copy
    finally:
        model.gravity.linear = saved
    assert len(inv._POOLS) <= inv._POOL_CACHE


def test_busy_cpus_reads_other_processes_only(monkeypatch):
    busy = cpus.busy()
    assert isinstance(busy, int) and busy >= 0
    # Unknown (no /proc): nothing assumed busy.
    monkeypatch.setattr(
        cpus, "open", lambda *a, **k: (_ for _ in ()).throw(OSError()), raising=False
    )
    assert cpus.busy() == 0


def test_default_threads_follow_the_free_cpus(monkeypatch):
    arm, m = _motion(20_001)
    used = []
    real = inv._pool

    def spy(model, threads):
        used.append(threads)
        return real(model, threads)

    monkeypatch.setattr(inv, "_pool", spy)
    monkeypatch.setattr(cpus, "available", lambda: 2)
    monkeypatch.setattr(cpus, "busy", lambda: 0)
    inverse_dynamics(arm, m.q, m.qd, m.qdd)
    monkeypatch.setattr(cpus, "busy", lambda: 1)  # another job holds a core
    inverse_dynamics(arm, m.q, m.qd, m.qdd)
    inverse_dynamics(arm, m.q, m.qd, m.qdd, num_threads=2)  # asked for: kept
    assert used == [2, 1, 2]
