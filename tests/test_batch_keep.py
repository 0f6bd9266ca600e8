"""Compiled batches that keep final states or metrics only, and their threads.

Each lean result is checked against an independent computation: the full
batch's last row, :func:`rrt_pin.simulate.metrics.batch_metrics` (numpy) on the full
trajectories, one thread against several, the Pinocchio backend.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.robot.params import Params
from rrt_pin.simulate.control import ChapterController
from rrt_pin.simulate.metrics import GROUPS, batch_metrics

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("numba") is None, reason="numba not installed (rrt-pin[fast])"
)

GRID = np.linspace(0.0, 15.0, 1501)
NAMES = (("q1", "q2", "q3"), ("T01x", "T12y", "F23z"))


@pytest.fixture(scope="module")
def compiled():
    from rrt_pin import compiled as backend

    backend.ensure_compiled()
    return backend


def _variants(count: int, seed: int = 3):
    """Chapter variants: masses, gains, targets and initial states varied (own Params each)."""
    rng = np.random.default_rng(seed)
    base = Params()
    plants, laws = [], []
    for i in range(count):
        m = np.array([base.m1, base.m2, base.m3]) * rng.uniform(0.8, 1.25, 3)
        plant = base.with_overrides({"m1": m[0], "m2": m[1], "m3": m[2]})
        qf = np.array(base.qf) + rng.uniform(-0.2, 0.2, 3)
        if i == 1:
            qf[2] = base.q30  # a joint starting at its target: the band scales with its excursion
        plants.append(plant)
        laws.append(
            ChapterController(
                kp=tuple(np.array(base.kp) * rng.uniform(0.5, 1.5, 3)),
                kd=tuple(np.array(base.kd) * rng.uniform(0.5, 1.5, 3)),
                qf=tuple(qf),
                params=plant,
            )
        )
    q0s = np.array(base.q0) + rng.uniform(-0.1, 0.1, (count, 3))
    q0s[1, 2] = base.q30
    return plants, laws, q0s, np.zeros((count, 3))


def _batch(compiled, variants, t=GRID, **kw):
    plants, laws, q0s, qd0s = variants
    return compiled.simulate_batch_compiled(plants, laws, q0s, qd0s, t, **kw)


@pytest.mark.parametrize("method", ["DOP853", "RK45", "rk4", "verlet"])
def test_final_states_equal_the_trajectories_last_row(compiled, method):
    variants = _variants(6)
    t = GRID[:301]  # 0..3 s
    step = {"step": 0.01} if method in ("rk4", "verlet") else {}
    full = _batch(compiled, variants, t, method=method, **step)
    final = _batch(compiled, variants, t, method=method, keep="final", **step)
    assert final.keep == "final" and final.metrics is None
    assert final.q.shape == final.qd.shape == final.tau.shape == (6, 1, 3)
    np.testing.assert_array_equal(final.t, t[-1:])
    if step:  # fixed steps land on every output time: the same numbers
        np.testing.assert_array_equal(final.q[:, 0], full.q[:, -1])
        np.testing.assert_array_equal(final.tau[:, 0], full.tau[:, -1])
        assert final.n_evals == full.n_evals
    else:  # the last step's end, which the dense output reproduces to round-off
        np.testing.assert_allclose(final.q[:, 0], full.q[:, -1], rtol=1e-13, atol=1e-14)
        np.testing.assert_allclose(final.qd[:, 0], full.qd[:, -1], rtol=1e-12, atol=1e-13)
        np.testing.assert_allclose(final.tau[:, 0], full.tau[:, -1], rtol=1e-12, atol=1e-10)
        # no dense output: only the steps' evaluations
        if method == "DOP853":
            assert final.n_evals < full.n_evals
    # the efforts are eq. (31) at the final states
    for i, law in enumerate(variants[1]):
        np.testing.assert_allclose(
            final.tau[i, 0], law.efforts(final.q[i, 0], final.qd[i, 0]), rtol=1e-13, atol=1e-10
        )


@pytest.mark.parametrize(
    ("t", "method"),
    [(GRID, "DOP853"), (GRID[:201], "DOP853"), (GRID, "RK45"), (GRID, "rk4")],
    ids=["settled", "not settled", "RK45", "rk4"],
)
def test_metrics_equal_batch_metrics_on_the_trajectories(compiled, t, method):
    # The adaptive methods keep the scratch run by rows (dense output, efforts and
    # metrics over contiguous rows), the fixed-step ones as the trajectories: both
    # must give batch_metrics of the stored trajectories.
    variants = _variants(8)
    step = {"step": 0.01} if method == "rk4" else {}
    full = _batch(compiled, variants, t, method=method, **step)
    lean = _batch(compiled, variants, t, keep="metrics", method=method, **step)
    qf = np.array([law.qf for law in variants[1]])
    want = batch_metrics(GROUPS, t, full.q, full.qd, full.tau, qf, *NAMES)  # numpy
    assert set(lean.metrics) == set(want)
    for name, value in want.items():
        got = lean.metrics[name]
        assert got.shape == (8,) and not got.flags.writeable
        if name.startswith(("settling_time", "peak_effort_time")):
            np.testing.assert_array_equal(got, value, err_msg=name)  # sample times
        else:
            np.testing.assert_allclose(got, value, rtol=1e-12, atol=1e-15, err_msg=name)
    settled = np.isfinite(np.column_stack([want[f"settling_time_{q}"] for q in NAMES[0]]))
    assert settled.any() and not settled.all()  # both: a settling time, and NaN (not settled)
    np.testing.assert_array_equal(lean.q[:, 0], full.q[:, -1])  # metrics ran the dense output
    assert lean.n_evals == full.n_evals


def test_compiled_metrics_treat_non_finite_samples_as_numpy_does(compiled):
    # The compiled pass takes its maxima on the bits of non-negative doubles: a nan
    # must still win (as numpy's max and argmax), an inf count as the largest, a
    # nan never leave the settling band; a start on target scales by the largest distance.
    rng = np.random.default_rng(1)
    t = np.linspace(0.0, 1.0, 50)
    q, qd, tau = (rng.normal(size=(5, 50, 3)) for _ in range(3))
    qf = rng.normal(size=(5, 3))
    tau[0, 7, 1] = np.nan
    q[1, 9, 2] = np.nan
    tau[2, 3, 0] = -np.inf
    q[3, 0, 0] = qf[3, 0]
    tau[4, 30:, 2] = tau[4, 12, 2]  # a peak reached again: its first time counts
    want = batch_metrics(GROUPS, t, q, qd, tau, qf, *NAMES)
    got = batch_metrics(GROUPS, t, q, qd, tau, qf, *NAMES, compiled=True)
    assert np.isnan(want["peak_effort_T12y"][0]) and np.isnan(want["excursion_q3"][1])
    for name, value in want.items():
        if name == "control_energy":  # numpy sums pairwise, the pass in 16 partial sums
            np.testing.assert_allclose(got[name], value, rtol=1e-14)
        else:
            np.testing.assert_array_equal(got[name], value, err_msg=name)


def test_threads_give_the_same_bits_and_are_kept(compiled):
    variants = _variants(37)
    for keep in ("trajectories", "final", "metrics"):
        runs = [_batch(compiled, variants, GRID[:501], keep=keep, threads=n) for n in (1, 2, 3)]
        assert [r.threads for r in runs] == [1, 2, 3]
        for r in runs[1:]:
            np.testing.assert_array_equal(r.q, runs[0].q)
            np.testing.assert_array_equal(r.qd, runs[0].qd)
            np.testing.assert_array_equal(r.tau, runs[0].tau)
            assert r.n_evals == runs[0].n_evals
            if keep == "metrics":
                for name, value in runs[0].metrics.items():
                    np.testing.assert_array_equal(r.metrics[name], value)
    # an explicit count above the variants: one thread a variant at most
    assert _batch(compiled, _variants(2), GRID[:51], threads=8).threads == 2


@pytest.mark.parametrize("method", ["DOP853", "rk4"])
def test_threads_share_a_batch_laid_out_while_it_runs(compiled, method):
    # More variants than the first parts laid out (64, then 256 at a time): the
    # helpers start on the first part and take the others as they are laid out.
    from rrt_pin.compiled import lanes

    count = lanes._FIRST_PART + 2 * lanes._PART + 5
    variants = _variants(count, seed=5)
    step = {"step": 0.01} if method == "rk4" else {}
    runs = [
        _batch(compiled, variants, GRID[:101], keep="metrics", method=method, threads=n, **step)
        for n in (1, 2, 3)
    ]
    for r in runs[1:]:
        np.testing.assert_array_equal(r.q, runs[0].q)
        np.testing.assert_array_equal(r.tau, runs[0].tau)
        for name, value in runs[0].metrics.items():
            np.testing.assert_array_equal(r.metrics[name], value)
    # each variant is its own single run, whichever thread took it
    for i in (0, lanes._FIRST_PART, count - 1):
        one = _batch(
            compiled, tuple(v[i : i + 1] for v in variants), GRID[:101], keep="metrics",
            method=method, threads=1, **step,
        )  # fmt: skip
        np.testing.assert_array_equal(one.q[0], runs[1].q[i])


def test_a_bad_controller_laid_out_late_stops_the_threads(compiled):
    # The third part holds a bad controller: the helpers, already running the first
    # parts, stop; the call says which variant, and the next batch runs as usual.
    from rrt_pin.compiled import lanes

    count = lanes._FIRST_PART + 2 * lanes._PART
    plants, laws, q0s, qd0s = _variants(count, seed=6)
    bad = count - 3
    laws = [*laws[:bad], object(), *laws[bad + 1 :]]
    with pytest.raises(InputError, match=rf"^controllers\[{bad}\]: backend 'compiled' runs"):
        compiled.simulate_batch_compiled(plants, laws, q0s, qd0s, GRID[:101], threads=2)
    again = compiled.simulate_batch_compiled(
        plants[:40], laws[:40], q0s[:40], qd0s[:40], GRID[:101], threads=2
    )
    assert again.threads == 2 and np.isfinite(again.q).all()


@pytest.mark.parametrize(
    ("cpus", "busy", "count", "threads"),
    [(2, 0, 64, 2), (2, 1, 64, 2), (4, 1, 64, 4), (1, 0, 64, 1), (2, 0, 20, 1)],
)
def test_default_threads_take_every_cpu_busy_or_not(compiled, monkeypatch, cpus, busy, count,
                                                     threads):  # fmt: skip
    """Its threads take variants from one counter as they finish: one beside a busy core
    holds nobody up and adds what it gets (scripts/bench/batch_threads.py --busy)."""
    from rrt_pin.compiled.lanes import MIN_PER_THREAD
    from rrt_pin.core import cpus as module

    monkeypatch.setattr(module, "available", lambda: cpus)
    monkeypatch.setattr(module, "busy", lambda: busy)
    assert count >= 2 * MIN_PER_THREAD or threads == 1
    r = _batch(compiled, _variants(count), GRID[:11], keep="final")
    assert r.threads == threads
    # simulate_batch hands its default over, and keeps an explicit count
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.simulate import simulate_batch

    plants, laws, q0s, qd0s = _variants(count)
    arm = chapter_arm(plants[0])
    kw = {"backend": "compiled", "params": plants, "keep": "final", "estimate_error": False}
    assert simulate_batch(arm, laws, q0s, qd0s, GRID[:11], **kw).threads == threads
    assert simulate_batch(arm, laws, q0s, qd0s, GRID[:11], threads=1, **kw).threads == 1


def test_simulate_batch_keeps_the_same_on_both_backends(compiled):
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.simulate import simulate_batch

    base = Params()
    _, laws, q0s, qd0s = _variants(3)
    laws = [ChapterController(kp=law.kp, kd=law.kd, qf=law.qf, params=base) for law in laws]
    t = GRID[:401]
    arm = chapter_arm(base)
    runs = {
        backend: simulate_batch(
            arm,
            laws,
            q0s,
            qd0s,
            t,
            backend=backend,
            keep="metrics",
            estimate_error=backend == "compiled",
        )  # fmt: skip
        for backend in ("pinocchio", "compiled")
    }
    a, b = runs["pinocchio"], runs["compiled"]
    assert a.q.shape == b.q.shape == (3, 1, 3) and a.keep == b.keep == "metrics"
    np.testing.assert_allclose(a.q, b.q, atol=1e-9)
    for name, value in a.metrics.items():
        if name.startswith(("settling_time", "peak_effort_time")):  # sample times
            np.testing.assert_allclose(b.metrics[name], value, atol=0.0101, err_msg=name)
        else:
            np.testing.assert_allclose(b.metrics[name], value, rtol=1e-7, atol=1e-8, err_msg=name)
    assert b.estimate is not None and b.estimate.variants.shape == (3, 3)
    assert b.estimate.max < 1e-8  # the final states' estimated error


@pytest.mark.parametrize("backend", ["compiled", "pinocchio"])
def test_an_unknown_keep_is_one_line_naming_it(compiled, backend):
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.simulate import simulate_batch

    plants, laws, q0s, qd0s = _variants(2)
    with pytest.raises(InputError, match=r"keep='final_state' is not one of") as e:
        simulate_batch(
            chapter_arm(plants[0]), laws, q0s, qd0s, GRID[:11], backend=backend,
            keep="final_state",
        )  # fmt: skip
    assert "\n" not in str(e.value)
    with pytest.raises(InputError, match=r"keep=3 is not one of trajectories, final, metrics"):
        _batch(compiled, (plants, laws, q0s, qd0s), GRID[:11], keep=3)
    with pytest.raises(InputError, match=r"keep='metrics' .* target qf"):
        _batch(compiled, (plants, None, q0s, qd0s), GRID[:11], keep="metrics")


def test_integrate_arrays_lean_rows(compiled):
    """The sweeps' entry point: final rows and metrics rows from prepared arrays."""
    from rrt_pin.compiled.lanes import integrate_arrays
    from rrt_pin.dynamics.kernel import param_vector
    from rrt_pin.simulate import codes

    plants, laws, q0s, qd0s = _variants(5)
    P = np.array([param_vector(p) for p in plants])
    C = np.column_stack([[law.kp for law in laws], [law.kd for law in laws],
                         [law.qf for law in laws], P])  # fmt: skip
    kinds = np.full(5, codes.KIND_CHAPTER_FOLDED)
    Y0 = np.column_stack([q0s, qd0s])
    t = GRID[:301]
    args = (P, kinds, C, Y0, t, "DOP853", 1e-10, 1e-12, None)
    y, tau, info, _ = integrate_arrays(*args)
    yf, tauf, m, infof, _, used = integrate_arrays(*args, keep="metrics", threads=2, detail=True)
    assert y.shape == (5, 301, 6) and yf.shape == (5, 1, 6) and used == 2
    assert (info[:, 0] == 0).all() and (infof[:, 0] == 0).all()
    np.testing.assert_array_equal(yf[:, 0], y[:, -1])
    want = batch_metrics(GROUPS, t, y[..., :3], y[..., 3:], tau, C[:, 6:9], *NAMES)
    np.testing.assert_allclose(m[:, codes.METRIC_ENERGY], want["control_energy"], rtol=1e-12)
    np.testing.assert_array_equal(m[:, codes.METRIC_SETTLE + 2], want["settling_time_q3"])


def test_integrate_arrays_fills_its_rows_as_it_goes(compiled):
    """``fill`` lays rows out during the call: the metrics' targets follow C's rows."""
    from rrt_pin.compiled.integrate import _batch_arrays
    from rrt_pin.compiled.lanes import integrate_arrays

    count = 100
    plants, laws, q0s, qd0s = _variants(count, seed=7)
    ready = _batch_arrays(plants, laws)
    Y0 = np.column_stack([q0s, qd0s])
    rest = (Y0, GRID[:201], "DOP853", 1e-9, 1e-11, None)
    want = integrate_arrays(*ready, *rest, keep="metrics", threads=2, detail=True)
    P, kinds, C = (np.empty_like(a) for a in ready)
    calls = []

    def fill(a, b):
        calls.append((a, b))
        for dst, src in zip((P, kinds, C), ready, strict=True):
            dst[a:b] = src[a:b]

    got = integrate_arrays(P, kinds, C, *rest, keep="metrics", threads=2, detail=True, fill=fill)
    assert calls[0] == (0, 64) and calls[-1][1] == count  # the first part, then the rest
    for g, w in zip(got[:5], want[:5], strict=True):
        np.testing.assert_array_equal(g, w)
    with pytest.raises(ValueError, match="in place"):  # a copy would not see the rows
        integrate_arrays(P[:, ::-1], kinds, C, *rest, threads=2, fill=fill)


def test_batch_laws_of_another_arm_equal_single_runs(compiled):
    """The batch's column-wise preparation: folded and unfolded eq. (31) as in single runs."""
    plants, laws, q0s, qd0s = _variants(4)
    other = Params(g=9.7, m2=40.0)  # eq. (31) built for another arm: its own gravity terms
    laws[1] = ChapterController(kp=laws[1].kp, kd=laws[1].kd, qf=laws[1].qf, params=other)
    laws[2] = ChapterController(  # equal values, another object: still folded
        kp=laws[2].kp, kd=laws[2].kd, qf=laws[2].qf, params=Params(**vars(plants[2]))
    )
    t = GRID[:301]
    batch = compiled.simulate_batch_compiled(plants, laws, q0s, qd0s, t, threads=2)
    for i in range(4):
        one = compiled.simulate_compiled(plants[i], laws[i], q0s[i], qd0s[i], t)
        np.testing.assert_array_equal(batch.q[i], one.q)
        np.testing.assert_array_equal(batch.tau[i], one.tau)
    from rrt_pin.compiled.integrate import _batch_arrays
    from rrt_pin.simulate import codes

    _, kinds, _ = _batch_arrays(plants, laws)
    assert (
        list(kinds)
        == [codes.KIND_CHAPTER_FOLDED, codes.KIND_CHAPTER] + [codes.KIND_CHAPTER_FOLDED] * 2
    )


@pytest.mark.parametrize("keep", ["trajectories", "metrics"])
def test_the_arms_batch_records_a_failing_variant_and_keeps_the_others(compiled, keep):
    """``failures="record"``: the failing variant's error, rows and metrics NaN; the others
    equal the batch without it; evaluations counted per variant."""
    import rrt_pin
    from rrt_pin.core.errors import DivergenceError
    from rrt_pin.robot.robots import chapter_arm

    plants, laws, q0s, qd0s = _variants(4)
    qd0s = qd0s.copy()
    qd0s[2, 0] = 1e200  # its Coriolis terms overflow at once
    t = GRID[:301]

    def run(rows):
        return rrt_pin.simulate_batch(
            chapter_arm(plants[0]), [laws[i] for i in rows], q0s[rows], qd0s[rows], t,
            params=[plants[i] for i in rows], backend="compiled", keep=keep, threads=1,
            failures="record", estimate_error=False,
        )  # fmt: skip

    every, others = run([0, 1, 2, 3]), run([0, 1, 3])
    assert isinstance(every.failures[2], DivergenceError)
    assert [f is None for f in every.failures] == [True, True, False, True]
    assert np.isnan(every.q[2]).all() and np.isfinite(every.q[[0, 1, 3]]).all()
    np.testing.assert_array_equal(every.q[[0, 1, 3]], others.q)
    np.testing.assert_array_equal(every.evaluations[[0, 1, 3]], others.evaluations)
    assert every.evaluations.shape == (4,) and (every.evaluations[[0, 1, 3]] > 100).all()
    if keep == "metrics":
        for name, col in every.metrics.items():
            assert np.isnan(col[2]), name
            np.testing.assert_array_equal(col[[0, 1, 3]], others.metrics[name], err_msg=name)
    with pytest.raises(DivergenceError, match="variant 2"):
        rrt_pin.simulate_batch(
            chapter_arm(plants[0]), laws, q0s, qd0s, t, params=plants, backend="compiled",
            threads=1, estimate_error=False,
        )  # fmt: skip
