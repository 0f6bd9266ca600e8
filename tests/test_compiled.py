"""The compiled backend's dynamics against Pinocchio, its cache, and its boundary checks."""

from __future__ import annotations

import importlib.util
import subprocess
import sys

import numpy as np
import pytest

from rrt_pin.core.errors import InputError
from rrt_pin.robot.params import Params
from tests.support import TIGHT, random_states

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("numba") is None, reason="numba not installed (rrt-pin[fast])"
)

N_STATES = 1000
# Parameter sets exercising every term (non-zero I1z, I2z, unequal moments, other g).
PARAM_SETS = {
    "seed": Params(),
    "general": Params(
        L1=0.3,
        L2=0.9,
        m1=12.0,
        m2=7.5,
        m3=3.2,
        I1x=0.5,
        I1y=0.4,
        I1z=0.2,
        I2x=0.8,
        I2y=0.7,
        I2z=0.3,
        I3x=0.05,
        I3y=0.06,
        I3z=0.02,
        g=3.7,
    ),  # fmt: skip
}


@pytest.fixture(scope="session")
def compiled():
    """The compiled backend, compiled (or loaded from the disk cache) once per session."""
    from rrt_pin import compiled as backend

    backend.ensure_compiled()
    return backend


def _pin_reference(model, q, qd, qdd, tau):
    import pinocchio as pin

    data = model.createData()
    out = {k: [] for k in ("M", "nle", "G", "rnea", "aba")}
    for i in range(q.shape[0]):
        M = pin.crba(model, data, q[i])
        out["M"].append(np.triu(M) + np.triu(M, 1).T)
        out["nle"].append(pin.nonLinearEffects(model, data, q[i], qd[i]).copy())
        out["G"].append(pin.computeGeneralizedGravity(model, data, q[i]).copy())
        out["rnea"].append(pin.rnea(model, data, q[i], qd[i], qdd[i]).copy())
        out["aba"].append(pin.aba(model, data, q[i], qd[i], tau[i]).copy())
    return {k: np.array(v) for k, v in out.items()}


def _worst_relative(a: np.ndarray, b: np.ndarray) -> float:
    """max over samples of max|a − b| / max|b| (each sample's own scale)."""
    axes = tuple(range(1, a.ndim))
    return float((np.abs(a - b).max(axis=axes) / np.abs(b).max(axis=axes)).max())


@pytest.mark.parametrize("name", sorted(PARAM_SETS))
def test_dynamics_match_pinocchio_at_random_states(compiled, rng, name):
    from rrt_pin.robot.model import rrt_model

    params = PARAM_SETS[name]
    q, qd, qdd = random_states(rng, N_STATES)
    tau = rng.normal(0.0, 200.0, (N_STATES, 3))
    ref = _pin_reference(rrt_model(params), q, qd, qdd, tau)
    got = {
        "M": compiled.mass_matrix(q, params),
        "nle": compiled.nonlinear_effects(q, qd, params),
        "G": compiled.gravity(q, params),
        "rnea": compiled.inverse_dynamics(q, qd, qdd, params),
        "aba": compiled.forward_dynamics(q, qd, tau, params),
    }
    for key, value in got.items():
        assert value.shape == ref[key].shape, key
        assert _worst_relative(value, ref[key]) <= TIGHT, key


def test_coriolis_is_nonlinear_effects_minus_gravity(compiled, rng):
    params = PARAM_SETS["general"]
    q, qd, _ = random_states(rng, 200)
    c = compiled.coriolis(q, qd, params)
    np.testing.assert_allclose(
        c + compiled.gravity(q, params), compiled.nonlinear_effects(q, qd, params), rtol=1e-14,
        atol=1e-12,
    )  # fmt: skip
    np.testing.assert_array_equal(compiled.coriolis(q, np.zeros_like(qd), params), 0.0)


def test_forward_inverts_inverse(compiled, rng):
    params = PARAM_SETS["general"]
    q, qd, qdd = random_states(rng, 500)
    tau = compiled.inverse_dynamics(q, qd, qdd, params)
    np.testing.assert_allclose(compiled.forward_dynamics(q, qd, tau, params), qdd, atol=1e-11)


def test_single_state_shapes(compiled, seed_params):
    q, qd, qdd = np.array([0.1, 0.5, 0.25]), np.array([0.3, -0.2, 0.1]), np.ones(3)
    assert compiled.mass_matrix(q, seed_params).shape == (3, 3)
    assert compiled.gravity(q, seed_params).shape == (3,)
    tau = compiled.inverse_dynamics(q, qd, qdd, seed_params)
    assert tau.shape == (3,)
    np.testing.assert_allclose(compiled.forward_dynamics(q, qd, tau, seed_params), qdd, atol=1e-12)
    batch = compiled.inverse_dynamics(q[None], qd[None], qdd[None], seed_params)
    np.testing.assert_array_equal(batch[0], tau)


def test_matches_the_numpy_kernel(compiled, rng):
    from rrt_pin.dynamics import kernel

    params = PARAM_SETS["general"]
    q, qd, qdd = random_states(rng, 300)
    np.testing.assert_allclose(
        compiled.inverse_dynamics(q, qd, qdd, params),
        kernel.inverse_dynamics(q, qd, qdd, params),
        rtol=1e-13,
        atol=1e-12,
    )


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((np.zeros((4, 2)),), r"q\.shape=\(4, 2\)"),
        ((np.array([0.0, np.nan, 0.0]),), r"q\[1\]=nan must be finite"),
        (("abc",), "not an array of numbers"),
    ],
)
def test_bad_states_are_refused(compiled, seed_params, args, match):
    with pytest.raises(InputError, match=match):
        compiled.gravity(*args, seed_params)


def test_nonfinite_anywhere_in_a_batch_is_refused(compiled, seed_params, rng):
    q, qd, qdd = random_states(rng, 40)
    q[17, 0] = np.nan  # q1 does not enter the equations: only the check can catch it
    with pytest.raises(InputError, match=r"q\[17, 0\]=nan must be finite"):
        compiled.inverse_dynamics(q, qd, qdd, seed_params)
    with pytest.raises(InputError, match=r"q\[17, 0\]=nan must be finite"):
        compiled.mass_matrix(q, seed_params)
    qdd[3, 2] = -np.inf
    q[17, 0] = 0.0
    with pytest.raises(InputError, match=r"qdd\[3, 2\]=-inf must be finite"):
        compiled.inverse_dynamics(q, qd, qdd, seed_params)
    with pytest.raises(InputError, match=r"tau\[3, 2\]=-inf must be finite"):
        compiled.forward_dynamics(q, qd, qdd, seed_params)


def test_overflowing_results_are_refused(compiled, seed_params):
    q, qd, qdd = np.zeros((5, 3)), np.zeros((5, 3)), np.zeros((5, 3))
    qd[2] = 1e200  # finite, but q̇² overflows
    with pytest.raises(InputError, match="the efforts overflow: T.* at sample 2"):
        compiled.inverse_dynamics(q, qd, qdd, seed_params)


def test_vectorized_sine_and_cosine_match_libm():
    import numba

    from rrt_pin.compiled import _jit_dynamics as jd

    @numba.njit
    def both(x, s, c):
        for i in range(x.shape[0]):
            s[i] = jd.vsin(x[i])
            c[i] = jd.vcos(x[i])

    @numba.njit
    def pair(x, s, c):
        for i in range(x.shape[0]):
            s[i], c[i] = jd.vsincos(x[i])

    rng = np.random.default_rng(5)
    x = np.concatenate(
        [
            rng.uniform(-4.0, 4.0, 200_000),
            rng.uniform(-1e3, 1e3, 100_000),
            rng.uniform(-jd.SINCOS_LIMIT, jd.SINCOS_LIMIT, 100_000),
            np.arange(-64, 65) * np.pi / 4,  # octant boundaries
            [0.0, -0.0, 5e-324, 1e-300, -1e-8],
        ]
    )
    s, c = np.empty_like(x), np.empty_like(x)
    both(x, s, c)
    assert np.abs(s - np.sin(x)).max() <= 2.3e-16
    assert np.abs(c - np.cos(x)).max() <= 2.3e-16
    s2, c2 = np.empty_like(x), np.empty_like(x)
    pair(x, s2, c2)  # one shared reduction: the same values, bit for bit
    np.testing.assert_array_equal(s2, s)
    np.testing.assert_array_equal(c2, c)


def test_large_angles_use_libm(compiled, seed_params, rng):
    """Blocks holding |q2| >= SINCOS_LIMIT take the libm path; both agree with the numpy kernel."""
    from rrt_pin.compiled._jit_dynamics import SINCOS_LIMIT
    from rrt_pin.dynamics import kernel

    q, qd, qdd = random_states(rng, 1200)
    q[700, 1] = 3.0 * SINCOS_LIMIT
    np.testing.assert_allclose(
        compiled.inverse_dynamics(q, qd, qdd, seed_params),
        kernel.inverse_dynamics(q, qd, qdd, seed_params),
        rtol=1e-13,
        atol=1e-11,
    )


def test_mismatched_rows_and_bad_params_are_refused(compiled, seed_params):
    with pytest.raises(InputError, match="qd has 2 rows but q has 3"):
        compiled.nonlinear_effects(np.zeros((3, 3)), np.zeros((2, 3)), seed_params)
    with pytest.raises(InputError, match="params must be a Params"):
        compiled.gravity(np.zeros(3), {"m1": 1.0})


def test_dop853_coefficients_are_scipys():
    from scipy.integrate._ivp import dop853_coefficients as scipy_dop

    from rrt_pin.compiled import _dop853_coefficients as ours

    for name in ("A", "B", "C", "D", "E3", "E5"):
        np.testing.assert_array_equal(getattr(ours, name), getattr(scipy_dop, name), err_msg=name)


# --- compile state and cache -------------------------------------------------------------
def test_compile_report_and_is_compiled(compiled):
    report = compiled.ensure_compiled()
    assert report is compiled.compile_report()
    assert compiled.is_compiled()
    assert report.compile >= 0.0 and report.numba_import >= 0.0
    assert "integrate" in report.functions and "inverse_batch" in report.functions
    assert ("loaded from the cache" if report.from_cache else "compiled") in report.describe()


def test_cache_marker_follows_the_sources(tmp_path, monkeypatch):
    from rrt_pin.compiled import _cache

    monkeypatch.setenv("RRT_PIN_CACHE_DIR", str(tmp_path))
    _cache.cache_dir.cache_clear()
    try:
        assert not _cache.is_cached()
        assert not any(tmp_path.iterdir())  # asking creates nothing
        path = _cache.cache_dir()
        assert path == tmp_path / _cache.fingerprint()
        assert not _cache.is_cached()
        _cache.mark_ready(path, {"signatures": {}})
        assert _cache.is_cached()
        # Another source text gives another fingerprint, hence an empty directory.
        _cache._fingerprint_inputs.cache_clear()
        monkeypatch.setattr(_cache, "JIT_MODULES", (*_cache.JIT_MODULES, "rrt_pin.robot.params"))
        assert _cache.fingerprint() != path.name
        assert not _cache.is_cached()
    finally:
        _cache._fingerprint_inputs.cache_clear()
        _cache.cache_dir.cache_clear()


def test_unwritable_cache_candidates_are_skipped(tmp_path, monkeypatch):
    from rrt_pin.compiled import _cache

    blocker = tmp_path / "a-file"
    blocker.write_text("not a directory")
    monkeypatch.setenv("RRT_PIN_CACHE_DIR", str(blocker / "sub"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    _cache.cache_dir.cache_clear()
    try:
        assert _cache.cache_dir() == tmp_path / "xdg" / "rrt_pin" / "numba" / _cache.fingerprint()
    finally:
        _cache.cache_dir.cache_clear()


def test_available_is_false_without_numba(monkeypatch):
    import rrt_pin.compiled as backend

    real = importlib.util.find_spec
    monkeypatch.setattr(backend, "_available", None)
    monkeypatch.setattr(
        backend.importlib.util,
        "find_spec",
        lambda name, *a: None if name == "numba" else real(name, *a),
    )
    assert backend.available() is False


def test_importing_the_package_is_cheap():
    code = (
        "import sys, rrt_pin.compiled as c; c.is_compiled(); "
        "print('numba' in sys.modules, 'pinocchio' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.split() == ["False", "False"]
