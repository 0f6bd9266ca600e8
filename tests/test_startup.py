"""Start-up: a run imports only what it uses; the lean ODEPACK route gives scipy's bits."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest


def _modules_after(argv: list[str], tmp_path) -> set[str]:
    code = (
        "import sys; from rrt_pin.cli.app import main; "
        f"code = main({argv!r}); "
        "print(code); print(' '.join(sorted(sys.modules)))"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          cwd=tmp_path, check=True)  # fmt: skip
    status, modules = proc.stdout.strip().splitlines()[-2:]
    assert status == "0", proc.stderr
    return set(modules.split())


def test_default_simulate_skips_scipy_integrate(tmp_path):
    modules = _modules_after(["simulate", "--csv", "s.csv"], tmp_path)
    assert "scipy.integrate._odepack" in modules
    assert "scipy.integrate" not in modules and "scipy.special" not in modules
    assert "importlib.metadata" not in modules


def test_solve_ivp_methods_still_import_it(tmp_path):
    modules = _modules_after(["simulate", "--method", "RK45", "--tf", "1", "--csv", "s.csv"],
                             tmp_path)  # fmt: skip
    assert "scipy.integrate" in modules


@pytest.mark.parametrize("band", [None, 1])
def test_lean_odeint_is_scipys_bit_for_bit(band):
    from scipy.integrate import odeint as scipy_odeint

    from rrt_pin.simulate._odepack import odeint

    def f(y, t):  # a damped, driven pair of oscillators
        return np.array([y[1], -4.0 * y[0] - 0.3 * y[1] + np.sin(t), y[3], -y[2] - 0.1 * y[3]])

    y0 = np.array([1.0, 0.0, 0.5, 0.2])
    t = np.linspace(0.0, 20.0, 201)
    mine, info = odeint(f, y0, t, rtol=1e-9, atol=1e-11, mxstep=5000, ml=band, mu=band)
    theirs, their_info = scipy_odeint(f, y0, t, rtol=1e-9, atol=1e-11, mxstep=5000,
                                      ml=band, mu=band, full_output=True)  # fmt: skip
    np.testing.assert_array_equal(mine, theirs)
    assert info["message"] == their_info["message"] == "Integration successful."
    np.testing.assert_array_equal(info["nfe"], their_info["nfe"])


def test_lean_odeint_reports_lsodas_failure_like_scipy():
    from scipy.integrate import odeint as scipy_odeint

    from rrt_pin.simulate._odepack import odeint

    def f(y, t):  # blows up at t = 1
        return np.array([y[0] ** 2])

    t = np.linspace(0.0, 2.0, 5)
    _, info = odeint(f, np.array([1.0]), t, rtol=1e-9, atol=1e-11, mxstep=200)
    with pytest.warns(Warning):
        _, theirs = scipy_odeint(f, np.array([1.0]), t, rtol=1e-9, atol=1e-11, mxstep=200,
                                 full_output=True)  # fmt: skip
    assert info["message"] == theirs["message"] != "Integration successful."
