"""Failed integrations say what happened, when and where; tolerances mean what they say."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

from rrt_pin.core.errors import DivergenceError, InputError
from rrt_pin.robot.model import build_model
from rrt_pin.robot.params import Params
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import methods, simulate
from rrt_pin.simulate.control import chapter_controller
from rrt_pin.simulate.scipy_runs import eval_budget


def _cli(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "rrt_pin", "simulate", "--no-error-estimate",
                           *argv], capture_output=True, text=True, timeout=300)  # fmt: skip


def _meaningful(err: str) -> None:
    assert err.count("\n") == 1 and err.startswith("rrt-pin: error: simulation "), err
    assert "successful" not in err and "Traceback" not in err
    assert "Warning" not in err  # no numpy RuntimeWarning on the user's terminal


def test_huge_initial_derivatives_name_the_cause_not_illegal_input():
    proc = _cli("--tf", "2", "--set", "gamma01=1e300")
    assert proc.returncode == 2
    _meaningful(proc.stderr)
    head = proc.stderr.split("[")[0]  # the explanation comes before odepack's own words
    assert "stopped at t=0 s in qd1" in head and "|dqd1/dt| = " in head
    assert "first step" in head and "internal error" not in head


def test_tolerance_below_the_floor_is_refused_not_a_divergence():
    for argv in (
        ["--rtol", "1e-15"],
        ["--method", "DOP853", "--rtol", "1e-300", "--atol", "1e-300"],
    ):
        proc = _cli("--tf", "1", *argv)
        assert proc.returncode == 2 and "floor of 2.22e-14" in proc.stderr, proc.stderr
        assert "diverged" not in proc.stderr and "Warning" not in proc.stderr
    p = Params()
    for backend, method in (
        ("pinocchio", "odepack"),
        ("pinocchio", "Radau"),
        ("compiled", "DOP853"),
    ):
        with pytest.raises(InputError, match=f"below {method}'s floor"):
            simulate(chapter_arm(p), chapter_controller(p), p.q0, p.qd0, [0.0, 1.0],
                     method=method, rtol=1e-15, backend=backend)  # fmt: skip
    assert all(m.min_rtol == methods.RTOL_FLOOR for m in methods.METHODS.values() if m.adaptive)


def test_rtol_alone_tightens_the_whole_run():
    p = Params()
    model, law = build_model(p), chapter_controller(p)
    t = np.linspace(0.0, 15.0, 151)
    run = simulate(
        Robot.from_model(model),
        law,
        p.q0,
        p.qd0,
        t,
        method="DOP853",
        rtol=1e-12,
        estimate_error=False,
    )
    assert run.atol == pytest.approx(1e-14)  # rtol/100: the defaults' ratio
    given = simulate(Robot.from_model(model), law, p.q0, p.qd0, t, method="DOP853", rtol=1e-12, atol=1e-9,
                     estimate_error=False)  # fmt: skip
    assert given.atol == 1e-9  # an explicit atol is kept
    ref = simulate(
        Robot.from_model(model),
        law,
        p.q0,
        p.qd0,
        t,
        method="Radau",
        rtol=1e-13,
        estimate_error=False,
    )
    default = simulate(
        Robot.from_model(model), law, p.q0, p.qd0, t, method="DOP853", estimate_error=False
    )
    err = lambda r: np.abs(r.q - ref.q).max()  # noqa: E731
    assert err(run) < err(default)  # --rtol alone is now more accurate than the default


def test_stiff_explicit_run_stops_within_its_budget_once():
    p = Params().with_overrides({"gamma23": 1e12, "beta23": 1e9})
    calls = 0
    law = chapter_controller(p)

    class Counting:
        def efforts(self, t, q, qd):
            nonlocal calls
            calls += 1
            return law.efforts(t, q, qd)

    t = np.linspace(0.0, 2.0, 21)
    with pytest.raises(DivergenceError) as info:
        simulate(chapter_arm(p), Counting(), p.q0, p.qd0, t, method="RK45",
                 estimate_error=False)  # fmt: skip
    message = str(info.value)
    assert "simulation stopped at" in message and "gave up after 120,000 evaluations" in message
    assert "implicit" in message and info.value.coordinate.startswith("qd3")
    assert eval_budget(2.0) == 120_000
    assert calls <= eval_budget(2.0) + 10  # not run a second time to find out why


def test_compiled_fixed_step_blowup_blames_the_step_not_the_mass_matrix():
    pytest.importorskip("numba")
    proc = _cli("--backend", "compiled", "--method", "rk4", "--set", "gamma23=1e9")
    assert proc.returncode == 2
    err = proc.stderr.splitlines()[-1]
    assert "the step 0.01 s is too long" in err and "shorter --step" in err
    assert "singular" not in err and "degenerate" not in err


def test_a_non_finite_output_of_a_successful_rerun_is_named():
    from rrt_pin.simulate.scipy_runs import diagnose

    def f(t, y):
        return -y

    t = np.linspace(0.0, 1.0, 5)
    states = np.zeros((5, 2))
    states[3, 1] = np.inf
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # and no warning on the way
        error = diagnose("odepack", f, np.ones(2), t, 1e-9, 1e-11, ("q1", "qd1"), "whatever",
                         states=states)  # fmt: skip
    assert error.t == t[3] and error.coordinate == "qd1"
    assert "interpolated output became non-finite" in str(error)
    assert "successful" not in str(error)


def test_ctrl_c_exits_130_and_leaves_no_output(tmp_path):
    import signal
    import time

    out = tmp_path / "long.csv"
    proc = subprocess.Popen(
        [sys.executable, "-m", "rrt_pin", "simulate", "--method", "rk4", "--step", "1e-4",
         "--tf", "50", "--no-error-estimate", "--csv", str(out)],  # 5e5 steps: under the limit
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    time.sleep(2.0)  # well into the integration (it would take ~20 s)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 130, err
    assert err.strip().splitlines()[-1] == "rrt-pin: interrupted" and "Traceback" not in err
    assert list(tmp_path.iterdir()) == []
