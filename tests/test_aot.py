"""The closed-form dynamics built ahead of time: the JIT's bits, no numba in the process."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("numba")

from rrt_pin import compiled  # noqa: E402
from rrt_pin.compiled import _aot  # noqa: E402
from rrt_pin.robot.params import Params  # noqa: E402
from rrt_pin.robot.robots import chapter_arm

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def modules():
    compiled.ensure_compiled()  # compiles or loads the JIT, then builds the module once
    assert _aot.is_built() and compiled.aot_built()
    module = _aot.load()
    assert module is not None
    from rrt_pin.compiled import _jit_dynamics as jd

    return module, jd


def _frozen(a):
    a = np.ascontiguousarray(a)
    a.setflags(write=False)
    return a


def test_every_function_gives_the_jit_bits(modules, rng):
    aot, jd = modules
    n = 1003
    q, qd, x = (rng.uniform(-3, 3, (n, 3)) for _ in range(3))
    q[:, 2] = rng.uniform(-0.3, 0.5, n)
    p = _frozen(rng.uniform(0.3, 3.0, 15))
    q, qd, x = _frozen(q), _frozen(qd), _frozen(x)  # read-only inputs are accepted as by the JIT
    for name, args, shape in (
        ("inverse_batch", (q, qd, x, p), (n, 3)),
        ("forward_batch", (q, qd, x, p), (n, 3)),
        ("mass_matrix_batch", (q, p), (n, 3, 3)),
        ("bias_batch", (q, qd, p, 0), (n, 3)),
        ("bias_batch", (q, qd, p, 2), (n, 3)),
    ):
        a, b = np.empty(shape), np.empty(shape)
        ra = getattr(jd, name)(*args, a)
        rb = getattr(aot, name)(*args, b)
        np.testing.assert_array_equal(a, b, err_msg=name)
        assert repr(ra) == repr(rb), name


def test_non_finite_inputs_raise_the_same_flag(modules):
    aot, jd = modules
    q = np.zeros((5, 3))
    q[3, 1] = np.nan
    p = np.ones(15)
    a, b = np.empty((5, 3)), np.empty((5, 3))
    assert np.isnan(jd.inverse_batch(q, q, q, p, a)) and np.isnan(aot.inverse_batch(q, q, q, p, b))


def _fresh_process(code: str) -> dict:
    """What ``code`` prints as JSON, run by a new Python on this checkout."""
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True
    )
    return json.loads(out.stdout)


def test_a_process_computing_inverse_dynamics_does_not_import_numba(modules):
    code = (
        "import sys, json, numpy as np\n"
        "from rrt_pin.dynamics.inverse import inverse_dynamics\n"
        "from rrt_pin.robot.params import Params\n"
        "from rrt_pin.robot.robots import chapter_arm\n"
        "q = np.array([[0.1, 0.2, 0.3], [1.0, -2.0, 0.1]])\n"
        "tau = inverse_dynamics(chapter_arm(Params()), q, q, q, backend='compiled')\n"
        "print(json.dumps({'tau': tau.tolist(), 'numba': 'numba' in sys.modules}))\n"
    )
    got = _fresh_process(code)
    assert got["numba"] is False
    from rrt_pin.dynamics.inverse import inverse_dynamics

    q = np.array([[0.1, 0.2, 0.3], [1.0, -2.0, 0.1]])
    expected = inverse_dynamics(chapter_arm(Params()), q, q, q)  # Pinocchio's RNEA
    np.testing.assert_allclose(got["tau"], expected, rtol=1e-13, atol=1e-12)


def test_a_single_run_in_a_fresh_process_gives_the_jit_bits_without_numba(modules, monkeypatch):
    code = (
        "import sys, json, numpy as np\n"
        "from rrt_pin.simulate.control import chapter_controller\n"
        "from rrt_pin.robot.params import Params\n"
        "from rrt_pin.robot.robots import chapter_arm\n"
        "from rrt_pin.simulate import simulate\n"
        "p = Params()\n"
        "r = simulate(chapter_arm(p), chapter_controller(p), p.q0, np.zeros(3),\n"
        "             np.linspace(0, 15, 301), backend='compiled')\n"
        "print(json.dumps({'q': r.q.tolist(), 'tau': r.tau.tolist(), 'n': r.n_evals,\n"
        "                  'numba': 'numba' in sys.modules}))\n"
    )
    got = _fresh_process(code)
    assert got["numba"] is False
    from rrt_pin.compiled import integrate
    from rrt_pin.simulate.control import chapter_controller

    p = Params()
    monkeypatch.setattr(_aot, "load", lambda: None)  # this process: numba's JIT
    monkeypatch.setattr(compiled, "_code", None)  # chosen again
    assert compiled.machine_code().__name__ == "rrt_pin.compiled._jit"
    jit = integrate.simulate_compiled(
        p, chapter_controller(p), p.q0, np.zeros(3), np.linspace(0, 15, 301)
    )
    np.testing.assert_array_equal(np.array(got["q"]), jit.q)
    np.testing.assert_array_equal(np.array(got["tau"]), jit.tau)
    assert got["n"] == jit.n_evals


def test_a_damaged_module_is_dropped_and_the_jit_takes_over(tmp_path, monkeypatch, modules):
    from rrt_pin.compiled import dynamics

    bad = tmp_path / "rrt_pin_dynamics_aot.so"
    bad.write_bytes(b"\x7fELF truncated")
    monkeypatch.setattr(_aot, "module_path", lambda: bad)
    monkeypatch.setattr(_aot, "_loaded", None)
    monkeypatch.setattr(_aot, "_failed", False)
    monkeypatch.setattr(compiled, "_code", None)  # chosen again, after the damage
    assert _aot.load() is None and not bad.exists()  # removed: the next build replaces it
    q = np.array([[0.1, 0.2, 0.3]])
    np.testing.assert_array_equal(
        dynamics.inverse_dynamics(q, q, q, Params()),
        compiled.inverse_dynamics(q, q, q, Params()),
    )
    assert dynamics._jit().__name__ == "rrt_pin.compiled._jit"


def test_a_failed_build_is_not_retried_by_every_process(tmp_path, monkeypatch):
    target = tmp_path / "fp" / "rrt_pin_dynamics_aot.so"
    monkeypatch.setattr(_aot, "module_path", lambda: target)
    calls = []

    def failing(*args, **kwargs):
        calls.append(args)
        return subprocess.CompletedProcess(args, 1, "", "error: no C compiler\n")

    monkeypatch.setattr(_aot.subprocess, "run", failing)
    assert _aot.build() is False and _aot.build() is False
    assert len(calls) == 1 and not target.exists()
    assert "no C compiler" in (target.parent / "AOT_FAILED").read_text()
    assert not _aot.can_build()  # so ensure_compiled neither retries nor announces a build
