"""The bounded expression evaluator, parse_number, and Params' refusal of overflow."""

from __future__ import annotations

import math
import subprocess
import sys
from fractions import Fraction
from pathlib import Path

import numpy as np
import pytest

from rrt_pin.cli.runfile import load_runfile, resolve_params
from rrt_pin.core.errors import OverrideError, ParameterError, RunFileError
from rrt_pin.core.expr import MAX_LENGTH, ExpressionError, evaluate
from rrt_pin.robot.params import Params, parse_number, parse_overrides

ROOT = Path(__file__).resolve().parents[1]

HOSTILE = ["9**9**9", "10**10**10", "(" * 10000 + "1" + ")" * 10000, "2**2**2**2**2**2**2"]


@pytest.mark.parametrize(
    "text, value",
    [
        ("pi/3", math.pi / 3),
        ("-2*tau", -2 * math.tau),
        ("e**2", math.e**2),
        ("(1 + 2) * 3", 9.0),
        ("2**-1", 0.5),
        ("--1", 1.0),
        ("+4/8", 0.5),
        ("2**0.5", math.sqrt(2)),
        ("(" * 40 + "1" + ")" * 40, 1.0),
        ("1e308*1.5", 1.5e308),
    ],
)
def test_allowed_expressions(text, value):
    assert evaluate(text) == value
    assert parse_number(text) == value


@pytest.mark.parametrize(
    "text, words",
    [
        ("9**9**9", "overflows"),
        ("10**10**10", "overflows"),
        ("1e200*1e200", "overflows"),
        ("10**400", "overflows"),
        ("1" * 150 + "**3", "overflows"),
        ("(" * 10000 + "1" + ")" * 10000, "characters long"),
        ("-" * 150 + "1", "nested more than"),
        ("1j", "complex"),
        ("2+3j", "complex"),
        ("(-8)**(1/3)", "not real"),
        ("0**-1", "zero raised to a negative power"),
        ("1/0", "division by zero"),
        ("True", "not a number"),
        ("'1'", "not a number"),
        ("x", "unknown name 'x'"),
        ("abs(-1)", "only numbers"),
        ("1 if 1 else 2", "only numbers"),
        ("__import__('os')", "only numbers"),
        ("", "empty"),
        ("1 +", "invalid syntax"),
    ],
)
def test_refused_expressions(text, words):
    with pytest.raises(ExpressionError, match=words):
        evaluate(text)
    with pytest.raises(OverrideError) as info:
        parse_number(text, "L1")
    message = str(info.value)
    assert message.startswith("L1=") and "\n" not in message and len(message) < 200


def test_evaluation_is_in_floats():
    # Integer literals never become big ints: 2**1023 is a float, 2**1024 overflows.
    assert evaluate("2**1023") == 2.0**1023
    with pytest.raises(ExpressionError, match="overflows"):
        evaluate("2**1024")
    assert isinstance(evaluate("7*6"), float)


def test_long_text_is_refused_before_parsing():
    with pytest.raises(OverrideError, match=f"at most {MAX_LENGTH}"):
        parse_number("1" * (MAX_LENGTH + 1))
    assert parse_number(" " * 500 + "1") == 1.0


def test_plain_floats_still_parse_including_nan_and_inf():
    assert math.isnan(parse_number("nan")) and parse_number("-inf") == -math.inf
    assert parse_number("1e-3") == 1e-3
    with pytest.raises(OverrideError, match="too large"):
        parse_number(10**400)  # type: ignore[arg-type]


def test_hostile_expressions_finish_in_a_subprocess():
    # The old evaluator computed 9**9**9 with Python ints (minutes) and RecursionError'd on
    # deep parentheses: run them in a child with a generous timeout.
    code = (
        "import sys\n"
        "from rrt_pin.robot.params import parse_number\n"
        "from rrt_pin.core.errors import OverrideError\n"
        f"for text in {HOSTILE!r}:\n"
        "    try:\n"
        "        parse_number(text, 'L1')\n"
        "    except OverrideError as e:\n"
        "        print('refused' if 'is not a number' in str(e) else str(e))\n"
        "    else:\n"
        "        sys.exit('accepted ' + text[:20])\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=10,
        cwd=ROOT,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
    )
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.split() == ["refused"] * len(HOSTILE), proc.stdout


def test_overrides_and_scene_strings_use_the_bounded_evaluator(tmp_path):
    with pytest.raises(OverrideError, match="L1='9\\*\\*9\\*\\*9' is not a number"):
        parse_overrides(["L1=9**9**9"])
    path = tmp_path / "s.toml"
    path.write_text('[params]\nm3 = "10**10**10"\n')
    with pytest.raises(RunFileError, match="s.toml.*m3='10\\*\\*10\\*\\*10'.*overflows"):
        load_runfile(path)


# Params ---------------------------------------------------------------------
@pytest.mark.parametrize(
    "kwargs, name, words",
    [
        ({"L1": 1e200}, "L1", "rod inertia I1x = m1·L1²/3 overflows"),
        ({"L2": 1e155}, "L2", "overflows"),
        ({"m1": 1e300, "L1": 1e5}, "m1", "overflows"),
        ({"L1": 1e308, "I1x": 1.0, "I1y": 1.0}, "L1", "LB = 2·L1 overflows"),
        ({"I3x": 1e308, "I3y": 1e308, "I3z": 1e308}, "I3x", "overflows"),
        ({"m1": 10**400}, "m1", "too large for a float"),
        ({"g": -(10**5000)}, "g", "too large for a float"),
        ({"m1": True}, "m1", "not a boolean"),
        ({"q10": False}, "q10", "not a boolean"),
        ({"m1": np.bool_(True)}, "m1", "not a boolean"),
        ({"m1": 1j}, "m1", "real number"),
        ({"m1": "90"}, "m1", "real number"),
        ({"g": None}, "g", "real number"),
        ({"m1": np.zeros(3)}, "m1", "scalar"),
        ({"m1": np.array(1 + 1j)}, "m1", "scalar"),
        ({"g": np.float32("nan")}, "g", "finite"),
    ],
)
def test_params_refuse_overflow_and_non_reals(kwargs, name, words):
    with pytest.raises(ParameterError) as info:
        Params(**kwargs)
    assert info.value.name == name and words in str(info.value)
    assert "\n" not in str(info.value) and len(str(info.value)) < 200


def test_overflow_through_set_and_scene():
    with pytest.raises(ParameterError, match="L1=1e\\+200"):
        resolve_params(None, parse_overrides(["L1=1e200"]))


def test_params_accept_numpy_scalars_and_0d_arrays():
    p = Params(
        m1=np.float32(2.5), L1=np.array(0.3), m2=np.int64(3), m3=Fraction(1, 2), g=np.float64(9)
    )
    assert (p.m1, p.L1, p.m2, p.m3, p.g) == (2.5, pytest.approx(0.3), 3.0, 0.5, 9.0)
    assert all(type(v) is float for v in p.as_dict().values())
    assert p.I1x == pytest.approx(2.5 * 0.3**2 / 3)


def test_explicit_rod_inertias_with_a_huge_length_survive_overrides():
    p = Params(L1=1e160, I1x=1.0, I1y=1.0)
    assert p.with_overrides({"m3": 2.0}).I1x == 1.0


def test_importing_params_stays_cheap():
    code = "import sys, rrt_pin.robot.params, rrt_pin.core.expr; print('numpy' in sys.modules)"
    proc = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=ROOT,
        env={"PYTHONPATH": str(ROOT), "PATH": "/usr/bin:/bin"},
    )
    assert proc.stdout.strip() == "False", proc.stderr
