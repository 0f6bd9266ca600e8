"""Tolerances from the accuracy asked for: the calibration table, its choice, its checks.

The table (``rrt_pin/simulate/calibration.py``) is written by ``scripts/bench/calibrate.py``
from runs of the accuracy catalogue and two robot problems; these tests re-run the
problem that set each method's worst error at the default accuracy's rung and at the
next looser one, so a stale or too-cautious table fails.
"""

from __future__ import annotations

import json
import math
import warnings

import numpy as np
import pytest

from rrt_pin.cli.app import main
from rrt_pin.compiled import available
from rrt_pin.core.errors import InputError, RrtPinError
from rrt_pin.simulate import AccuracyWarning, calibration, methods, simulate, simulate_batch
from rrt_pin.simulate.accuracy import PROBLEMS, ROBOT_PROBLEMS, max_error, reference
from rrt_pin.simulate.options import resolve

needs_compiled = pytest.mark.skipif(not available(), reason="numba is not installed")
T = np.linspace(0.0, 1.0, 11)

ADAPTIVE = [
    (b, m.name)
    for m in methods.METHODS.values()
    if m.adaptive
    for b in ("pinocchio", "compiled")
    if m.runs_on(b)
]
#: The pairs calibrated (the others run at methods.DEFAULT_RTOL, DEFAULT_ATOL).
CALIBRATED = [key for key in ADAPTIVE if key in calibration.WORST]


def problem(name: str):
    return PROBLEMS.get(name) or ROBOT_PROBLEMS[name]


def quiet(p, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", AccuracyWarning)
        return p.run(estimate_error=False, **kw)


def test_the_table_covers_the_default_and_explicit_runge_kutta_methods():
    assert set(calibration.WORST) <= set(ADAPTIVE)
    needed = {("pinocchio", "odepack"), *((b, m) for b in ("pinocchio", "compiled")
                                           for m in ("RK45", "DOP853"))}  # fmt: skip
    assert needed <= set(calibration.WORST)
    assert needed <= set(calibration.COMPANIONS) <= set(calibration.WORST)
    assert calibration.SAFETY >= 1.0 and calibration.ATOL_RATIO == 100.0
    for key, rungs in calibration.WORST.items():
        rtols = [r[0] for r in rungs]
        assert rtols == sorted(rtols, reverse=True), key  # loosest first
        assert all(isinstance(r[2], str) and r[2] for r in rungs), key


@pytest.mark.parametrize("backend,method", CALIBRATED)
def test_the_chosen_rung_is_the_loosest_meeting_the_accuracy_with_the_safety(backend, method):
    rungs = calibration.WORST[(backend, method)]
    rtol, atol = methods._tolerances(backend, method, methods.ACCURACY)
    assert atol == pytest.approx(rtol / 100.0)
    assert methods.tolerances(backend, method)[0] <= rtol  # shared: the tightest backend's
    i = [r[0] for r in rungs].index(rtol)
    bound = methods.ACCURACY / calibration.SAFETY
    assert all(worst <= bound for _, worst, _ in rungs[i:])
    assert i == 0 or rungs[i - 1][1] > bound


@pytest.mark.parametrize("backend,method", CALIBRATED)
def test_the_table_matches_the_problems(backend, method):
    """The worst problem of the default's rung, re-measured here, keeps the accuracy.

    Only the bound is asserted: the error itself moves with the CPU's last digits (on
    long-1000s DOP853's jumps 15× between neighbouring tolerances), the bound has the
    measured safety factor's room.
    """
    if backend == "compiled" and not available():
        pytest.skip("numba is not installed")
    rungs = calibration.WORST[(backend, method)]
    rtol, _ = methods._tolerances(backend, method, methods.ACCURACY)
    r, worst, name = next(rung for rung in rungs if rung[0] == rtol)
    p = problem(name)
    try:
        run = quiet(p, backend=backend, method=method, rtol=r, atol=r / 100.0)
    except RrtPinError as e:  # a robot problem without example-robot-data
        pytest.skip(str(e))
    error = max_error(run.q, reference(p).q)
    assert error <= methods.ACCURACY, f"{name} at rtol {r:g}: {error:.3g}"
    assert worst * calibration.SAFETY <= methods.ACCURACY  # the table's own claim


def test_tolerances_loosen_with_the_accuracy():
    for backend, method in CALIBRATED:
        tight = methods.tolerances(backend, method, 1e-10)[0]
        default = methods.tolerances(backend, method, 1e-8)[0]
        loose = methods.tolerances(backend, method, 1e-5)[0]
        assert tight <= default <= loose, (backend, method)
        assert tight < loose, (backend, method)
    rtol, atol = methods.tolerances("pinocchio", "no-such-method", 1e-8)
    assert (rtol, atol) == (methods.DEFAULT_RTOL, methods.DEFAULT_ATOL)


def test_defaults_of_the_registry_are_the_calibrated_ones():
    for m in methods.METHODS.values():
        if m.adaptive:
            assert (m.rtol, m.atol) == methods.tolerances(m.backends[0], m.name)


# --- resolve: accuracy, explicit tolerances ---------------------------------------------
def test_an_explicit_rtol_or_atol_wins():
    o = resolve(T, accuracy=1e-4, rtol=1e-9)
    assert (o.rtol, o.atol, o.accuracy) == (1e-9, pytest.approx(1e-11), 1e-4)
    o = resolve(T, rtol=1e-6)
    assert (o.rtol, o.accuracy) == (1e-6, 1e-6)  # no better than its tolerance
    o = resolve(T, atol=1e-9)
    assert o.atol == 1e-9 and o.rtol == methods.tolerances("pinocchio", "odepack")[0]
    o = resolve(T, backend="pinocchio", method="DOP853", accuracy=1e-5)
    assert (o.rtol, o.atol) == methods.tolerances("pinocchio", "DOP853", 1e-5)
    assert o.accuracy == 1e-5
    assert resolve(T).accuracy == methods.ACCURACY
    fixed = resolve(T, method="rk4", accuracy=1e-3)
    assert fixed.rtol is None and fixed.accuracy == 1e-3


@pytest.mark.parametrize("bad", [0, 0.0, 1, 1.0, -1e-8, 2.0, math.nan, math.inf, True, "1e-8"])
def test_accuracy_is_validated(bad):
    with pytest.raises(InputError, match=r"^accuracy="):
        resolve(T, accuracy=bad)


def test_simulate_and_batch_take_accuracy():
    p = PROBLEMS["chapter"]
    arm = p.arm
    t = p.times()[:101]
    law = p.controller(arm)
    run = simulate(arm, law, arm.defaults.q0, None, t, accuracy=1e-5)
    assert run.rtol == methods.tolerances("pinocchio", "odepack", 1e-5)[0]
    assert run.estimate.accuracy == 1e-5
    q0s = np.array([arm.defaults.q0])
    batch = simulate_batch(arm, law, q0s, None, t, accuracy=1e-5, threads=1)
    assert batch.rtol == run.rtol and batch.estimate.accuracy == 1e-5
    with pytest.raises(InputError, match="accuracy="):
        simulate(arm, law, arm.defaults.q0, None, t, accuracy=1.5)
    with pytest.raises(InputError, match="accuracy="):
        simulate_batch(arm, law, q0s, None, t, accuracy=-1.0)


# --- the catalogue keeps the accuracy asked for ------------------------------------------
@needs_compiled
@pytest.mark.parametrize("accuracy", [1e-5, 1e-10])
def test_compiled_catalogue_keeps_other_accuracies(accuracy):
    for name, p in PROBLEMS.items():
        if "compiled" not in p.backends:
            continue
        run = p.run(backend="compiled", accuracy=accuracy, estimate_error=False)
        assert max_error(run.q, reference(p).q) <= accuracy, name


@pytest.mark.parametrize("name", ["chapter", "slider-150s", "light-joint3", "fast-motion"])
def test_pinocchio_default_keeps_a_looser_accuracy(name):
    p = PROBLEMS[name]
    run = p.run(accuracy=1e-5, estimate_error=False)
    assert run.rtol > methods.get("odepack").rtol  # looser than the default's
    assert max_error(run.q, reference(p).q) <= 1e-5


@pytest.mark.parametrize("name", list(ROBOT_PROBLEMS))
@pytest.mark.parametrize("backend", ["pinocchio", "compiled"])
def test_robot_problems_keep_the_default_accuracy(name, backend):
    if backend == "compiled" and not available():
        pytest.skip("numba is not installed")
    p = ROBOT_PROBLEMS[name]
    try:
        run = p.run(backend=backend)
    except RrtPinError as e:
        pytest.skip(str(e))
    error = max_error(run.q, reference(p).q)
    assert error <= methods.ACCURACY
    assert 0.3 * error <= max(run.error_estimate, 1e-11) <= 3.0 * max(error, 1e-11)


# --- the command line --------------------------------------------------------------------
def test_cli_accuracy_chooses_the_tolerances_and_records_them(tmp_path, capsys):
    out = tmp_path / "run.json"
    assert main(["simulate", "--tf", "2", "--accuracy", "1e-5", "--json", str(out)]) == 0
    text = capsys.readouterr().out
    rtol, atol = methods.tolerances("pinocchio", "odepack", 1e-5)
    assert f"rtol {rtol:g}, atol {atol:g}, chosen for accuracy 1e-05 rad or m" in text
    meta = json.loads(out.read_text())["metadata"]
    assert (meta["accuracy"], meta["rtol"], meta["tolerances"]) == (1e-5, rtol, "chosen for "
                                                                    "the accuracy")  # fmt: skip
    assert main(["simulate", "--tf", "2", "--rtol", "1e-7", "--json", str(out)]) == 0
    meta = json.loads(out.read_text())["metadata"]
    assert (meta["accuracy"], meta["rtol"], meta["tolerances"]) == (1e-7, 1e-7, "given")
    assert "chosen for accuracy" not in capsys.readouterr().out


def test_cli_help_names_the_accuracy_and_its_units(capsys):
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "--accuracy X" in text and "[rad or m], in (0, 1)" in text
