"""Batched Pinocchio RNEA: pools kept between calls, the same efforts whatever the threads."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.core import cpus
from rrt_pin.core.errors import InputError
from rrt_pin.dynamics import inverse as inv
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot import robots
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm


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
    before = inverse_dynamics(Robot.from_model(model), m.q, m.qd, m.qdd, num_threads=2)
    saved = model.gravity.linear.copy()
    try:
        model.gravity.linear = np.array([0.0, 0.0, -1.62])  # the Moon: a changed model
        assert inv._pool(model, 2) is not first
        moon = inverse_dynamics(Robot.from_model(model), m.q, m.qd, m.qdd, num_threads=2)
        assert not np.allclose(moon, before)  # the new gravity was used, not a stale copy
    finally:
        model.gravity.linear = saved
    assert len(inv._POOLS) <= inv._POOLS.size


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


def test_chunks_give_the_same_efforts_bit_for_bit_as_one_call(monkeypatch):
    arm, m = _motion(5003)
    whole = inverse_dynamics(arm, m.q, m.qd, m.qdd, num_threads=1)
    inv._POOLS.clear()
    monkeypatch.setattr(inv, "CHUNK", 1000)  # 6 chunks, the last one short
    chunked = inverse_dynamics(arm, m.q, m.qd, m.qdd, num_threads=2)
    np.testing.assert_array_equal(chunked, whole)
    # ...and they are Pinocchio's own, sample by sample
    model, data = arm.model, arm.model.createData()
    for i in (0, 999, 1000, 4321, 5002):
        np.testing.assert_array_equal(whole[i], pin.rnea(model, data, m.q[i], m.qd[i], m.qdd[i]))
    inv._POOLS.clear()


def test_results_are_fresh_arrays_not_the_kept_scratch():
    arm, m = _motion(501)
    first = inverse_dynamics(arm, m.q, m.qd, m.qdd)
    kept = first.copy()
    second = inverse_dynamics(arm, 2 * m.q, m.qd, m.qdd)
    np.testing.assert_array_equal(first, kept)  # the second call did not write into the first
    assert not np.array_equal(first, second)
    assert first.flags.c_contiguous and first.flags.writeable and first.shape == (501, 3)


def test_a_non_finite_input_anywhere_is_named_even_without_a_pass_over_the_inputs():
    # The Pinocchio path searches the inputs only when the efforts are not finite:
    # every position of every input must still be caught and named.
    for robot in (chapter_arm(), robots.get("ur5"), robots.get("kinova")):
        n, nv = 7, robot.nv
        rng = np.random.default_rng(3)
        base = {k: rng.uniform(-1, 1, (n, nv)) for k in ("q", "qd", "qdd")}
        for name in base:
            for i in range(n):
                for k in range(nv):
                    for bad in (np.nan, np.inf, -np.inf):
                        args = {key: v.copy() for key, v in base.items()}
                        args[name][i, k] = bad
                        with pytest.raises(InputError) as info:
                            inverse_dynamics(robot, **args)
                        assert f"{name}[{i}, {k}]={bad!r} must be finite" in str(info.value)


def test_concurrent_calls_from_python_threads_are_each_correct():
    arm, m = _motion(3001)
    expected = [inverse_dynamics(arm, s * m.q, m.qd, m.qdd, num_threads=1) for s in (1, 2, 3, 4)]
    with ThreadPoolExecutor(4) as ex:
        for _ in range(5):
            got = list(ex.map(lambda s: inverse_dynamics(arm, s * m.q, m.qd, m.qdd), (1, 2, 3, 4)))
            for g, e in zip(got, expected, strict=True):
                np.testing.assert_array_equal(g, e)


def test_a_reading_of_the_free_cpus_is_reused_briefly_and_a_busy_one_confirmed(monkeypatch):
    monkeypatch.setattr(cpus, "FRESH", 10.0)
    monkeypatch.setattr(cpus, "_last", (-1.0, 0))
    monkeypatch.setattr(cpus, "available", lambda: 2)
    readings = iter([1, 0])  # a spinning worker of ours seen as another job, once
    monkeypatch.setattr(cpus, "busy", lambda: next(readings))
    assert cpus.free() == 2  # confirmed: nothing else runs
    monkeypatch.setattr(cpus, "busy", lambda: 1)
    assert cpus.free() == 2  # reused within FRESH seconds
    monkeypatch.setattr(cpus, "FRESH", 0.0)
    assert cpus.free() == 1  # read again: a job holds a core now


def test_work_shared_as_threads_finish_uses_every_cpu_even_a_busy_one(monkeypatch):
    """A static split waits for its slowest thread: it takes the free CPUs; threads that
    take items from one counter lose nothing to a busy core, and take them all."""
    monkeypatch.setattr(cpus, "available", lambda: 2)
    monkeypatch.setattr(cpus, "free", lambda: 1)  # another process holds a core
    assert cpus.threads_for(1000, 4) == 1
    assert cpus.threads_for(1000, 4, shared=True) == 2
    assert cpus.threads_for(5, 4, shared=True) == 1  # too little work for a second thread
