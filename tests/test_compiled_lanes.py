"""Adaptive batches run several variants side by side (lanes): each one's steps and bits are a single run's.

:func:`rrt_pin.compiled._jit_batch.integrate_lanes` advances up to ``LANES``
variants together and vectorizes their stages; ``adaptive`` (the single runs of
``simulate_compiled``) integrates one. Every variant must come out the same, bit
for bit, whatever the number of lanes, the controller kind of its neighbours, or
their failures.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from rrt_pin.core.errors import DivergenceError
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate.control import ChapterController, pd_gravity_controller

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("numba") is None, reason="numba not installed (rrt-pin[fast])"
)

T = np.linspace(0.0, 15.0, 301)


@pytest.fixture(scope="module")
def compiled():
    from rrt_pin import compiled as backend

    backend.ensure_compiled()
    return backend


@pytest.fixture
def lanes(monkeypatch):
    """Set the lanes a thread runs (the module's LANES, read at every batch)."""
    from rrt_pin.compiled import _jit_batch

    def set_lanes(n: int) -> None:
        monkeypatch.setattr(_jit_batch, "LANES", n)

    return set_lanes


def _mixed(count: int, seed: int = 3):
    """Variants of every controller kind, in turn: none, eq. (31) of the plant (folded),
    eq. (31) built for another arm, PD plus the plant's gravity."""

    rng = np.random.default_rng(seed)
    base = Params()
    plants, controllers = [], []
    for i in range(count):
        plant = base.with_overrides(
            {"m2": rng.uniform(20, 40), "m3": rng.uniform(10, 30), "L2": rng.uniform(0.4, 0.6)}
        )
        kp = tuple(np.array(base.kp) * rng.uniform(0.8, 1.25, 3))
        kd = tuple(np.array(base.kd) * rng.uniform(0.8, 1.25, 3))
        controllers.append(
            (
                None,
                ChapterController(kp=kp, kd=kd, qf=base.qf, params=plant),
                ChapterController(kp=kp, kd=kd, qf=base.qf, params=base),
                pd_gravity_controller(chapter_arm(plant), kp, kd, base.qf),
            )[i % 4]
        )
        plants.append(plant)
    q0s = np.array(base.q0) + rng.uniform(-0.1, 0.1, (count, 3))
    qd0s = rng.normal(0.0, 0.2, (count, 3))
    return plants, controllers, q0s, qd0s


def test_the_mixed_variants_cover_every_controller_kind():
    from rrt_pin.compiled.integrate import _law
    from rrt_pin.simulate import codes

    plants, controllers, _, _ = _mixed(8)
    kinds = {_law(c, p)[0] for c, p in zip(controllers, plants, strict=True)}
    assert kinds == {
        codes.KIND_NONE, codes.KIND_CHAPTER_FOLDED, codes.KIND_CHAPTER,
        codes.KIND_PD_PLANT_GRAVITY,
    }  # fmt: skip


@pytest.mark.parametrize("method", ["DOP853", "RK45"])
@pytest.mark.parametrize("count_lanes", [1, 3, 16, 32])
def test_every_variant_is_its_single_run_bit_for_bit(compiled, lanes, method, count_lanes):
    lanes(count_lanes)
    # more variants than lanes: lanes whose variant ends take the next ones
    plants, controllers, q0s, qd0s = _mixed(max(11, count_lanes + 8))
    batch = compiled.simulate_batch_compiled(
        plants, controllers, q0s, qd0s, T, method=method, threads=1
    )
    total = 0
    for b in range(len(plants)):
        one = compiled.simulate_compiled(
            plants[b], controllers[b], q0s[b], qd0s[b], T, method=method
        )
        np.testing.assert_array_equal(batch.q[b], one.q)
        np.testing.assert_array_equal(batch.qd[b], one.qd)
        np.testing.assert_array_equal(batch.tau[b], one.tau)
        total += one.n_evals
    assert batch.n_evals == total


@pytest.mark.parametrize("method", ["DOP853", "RK45"])
def test_kept_finals_and_metrics_do_not_depend_on_the_lanes(compiled, lanes, method):
    from rrt_pin.compiled import _jit_metrics
    from rrt_pin.compiled.integrate import _batch_arrays
    from rrt_pin.compiled.lanes import integrate_arrays
    from rrt_pin.simulate.metrics import SETTLING_BAND

    plants, controllers, q0s, qd0s = _mixed(9, seed=5)
    P, kinds, C = _batch_arrays(plants, controllers)[:3]
    Y0 = np.hstack([q0s, qd0s])
    got = {}
    for count_lanes in (1, 4, 16):
        lanes(count_lanes)
        for keep in ("final", "metrics", "trajectories"):
            got[count_lanes, keep] = integrate_arrays(
                P, kinds, C, Y0, T, method, 1e-9, 1e-11, None, keep=keep, detail=True, threads=1
            )
    for keep in ("final", "metrics", "trajectories"):
        for count_lanes in (4, 16):
            for a, b in zip(got[1, keep], got[count_lanes, keep], strict=True):
                if isinstance(a, np.ndarray):
                    np.testing.assert_array_equal(a, b)
    # The metrics are those of the kept trajectories' samples, to the bit.
    y, tau, _, info, _, _ = got[16, "trajectories"]
    assert (info[:, 0] == 0).all()
    want = _jit_metrics.run(T, y[:, :, :3], y[:, :, 3:], tau, C[:, 6:9], SETTLING_BAND)
    np.testing.assert_array_equal(got[16, "metrics"][2], want)
    np.testing.assert_array_equal(got[16, "metrics"][0][:, 0], y[:, -1])
    # The final states: the last step's end, the trajectories' last sample to round-off.
    np.testing.assert_allclose(got[16, "final"][0][:, 0], y[:, -1], rtol=0, atol=1e-12)


def test_failing_variants_leave_their_neighbours_alone(compiled, lanes):
    """Start-up, mid-run failures and libm's sine (|q2| >= SINCOS_LIMIT) beside normal lanes."""
    from rrt_pin.compiled.integrate import _batch_arrays
    from rrt_pin.compiled.lanes import failure, integrate_arrays

    plants, controllers, q0s, qd0s = _mixed(10, seed=9)
    qd0s[1] = (1e160, 0.0, 0.0)  # non-finite q̈2 at t = 0: fails while starting
    qd0s[4] = (1e120, 0.0, 0.0)  # the step size underflows later
    controllers[6] = None
    q0s[6, 1] = 2e8  # passive motion with q2 beyond the branch-free sine: libm
    P, kinds, C = _batch_arrays(plants, controllers)[:3]
    Y0 = np.hstack([q0s, qd0s])
    lanes(3)
    y, tau, _, info, t_reached, _ = integrate_arrays(
        P, kinds, C, Y0, T, "DOP853", 1e-9, 1e-11, None, detail=True, threads=1
    )
    assert sorted(np.flatnonzero(info[:, 0])) == [1, 4]
    for b in range(len(plants)):
        try:
            one = compiled.simulate_compiled(
                plants[b], controllers[b], q0s[b], qd0s[b], T, method="DOP853", rtol=1e-9,
                atol=1e-11,
            )  # fmt: skip
        except DivergenceError as e:
            got = failure(info[b], t_reached[b], "DOP853", None)
            assert got is not None and (got.t, got.coordinate) == (e.t, e.coordinate), b
            assert str(got) == str(e)
            continue
        assert info[b, 0] == 0, b
        np.testing.assert_array_equal(y[b, :, :3], one.q)
        np.testing.assert_array_equal(y[b, :, 3:], one.qd)
        np.testing.assert_array_equal(tau[b], one.tau)
        assert info[b, 2] == one.n_evals


def test_long_output_grids_use_fewer_lanes_and_keep_the_bits(compiled, lanes):
    """Scratch runs stay bounded (9 values an output time a lane): fewer lanes, same numbers."""
    from rrt_pin.compiled.lanes import LANE_SCRATCH_BYTES, lanes_for
    from rrt_pin.simulate import codes

    assert lanes_for(1501, codes.KEEP_METRICS, 16) == 16
    assert lanes_for(10**7, codes.KEEP_TRAJECTORIES, 16) == 1
    assert lanes_for(10**7, codes.KEEP_FINAL, 16) == 16  # no scratch run
    many = 100_000
    assert 1 < lanes_for(many, codes.KEEP_METRICS, 16) < 16
    assert lanes_for(many, codes.KEEP_METRICS, 16) * 9 * 8 * many <= LANE_SCRATCH_BYTES
    plants, controllers, q0s, qd0s = _mixed(5, seed=11)
    t = np.linspace(0.0, 2.0, many)
    got = []
    for n in (16, 1):
        lanes(n)
        got.append(compiled.simulate_batch_compiled(plants, controllers, q0s, qd0s, t, threads=1))
    np.testing.assert_array_equal(got[0].q, got[1].q)
    np.testing.assert_array_equal(got[0].qd, got[1].qd)
    np.testing.assert_array_equal(got[0].tau, got[1].tau)


@pytest.mark.parametrize("keep", ["trajectories", "final", "metrics"])
def test_a_spent_step_budget_is_the_single_runs_failure(compiled, lanes, keep):
    """Every lane stops at its budget at the same time and coordinate as its single run."""
    from rrt_pin.compiled.integrate import _batch_arrays
    from rrt_pin.compiled.lanes import failure, integrate_arrays

    plants, controllers, q0s, qd0s = _mixed(6, seed=13)
    controllers[0] = controllers[1]  # metrics need a target: no passive variant
    P, kinds, C = _batch_arrays(plants, controllers)[:3]
    lanes(4)
    _, _, _, info, t_reached, _ = integrate_arrays(
        P, kinds, C, np.hstack([q0s, qd0s]), T, "DOP853", 1e-9, 1e-11, None, max_steps=12,
        keep=keep, detail=True, threads=1,
    )  # fmt: skip
    for b in range(len(plants)):
        with pytest.raises(DivergenceError) as single:
            compiled.simulate_compiled(
                plants[b], controllers[b], q0s[b], qd0s[b], T, method="DOP853", rtol=1e-9,
                atol=1e-11, max_steps=12,
            )  # fmt: skip
        got = failure(info[b], t_reached[b], "DOP853", None, 12)
        assert got is not None and str(got) == str(single.value), b
