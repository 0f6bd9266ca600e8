import math

import pytest

from rrt_pin.cli.runfile import load_runfile, resolve_params
from rrt_pin.core.errors import OverrideError, ParameterError, RunFileError
from rrt_pin.robot.params import Params, param_names, parse_number, parse_overrides


def test_seed_values():
    p = Params()
    assert (p.L1, p.L2, p.LB) == (0.4, 0.7, 0.8)
    assert (p.m1, p.m2, p.m3) == (90.0, 60.0, 40.0)
    assert (p.I3x, p.I3y, p.I3z, p.g) == (5.0, 4.0, 1.0, 9.81)
    # The seed's Fig. 2: uniform rods of length 2·L, I = m·(2L)²/12 = m·L²/3 about the transverse axes.
    assert p.I1x == p.I1y == pytest.approx(90 * (2 * 0.4) ** 2 / 12, rel=1e-15)
    assert p.I2x == p.I2y == pytest.approx(60 * (2 * 0.7) ** 2 / 12, rel=1e-15)
    assert p.I1z == p.I2z == 0.0
    assert p.q0 == (math.pi / 18, math.pi / 6, 0.25)
    assert p.qf == (math.pi / 3, math.pi / 3, 0.3)
    assert p.qd0 == (0.0, 0.0, 0.0) and p.Tp == 15.0
    assert p.kd == (450.0, 200.0, 150.0) and p.kp == (300.0, 300.0, 50.0)


def test_rod_inertias_follow_mass_and_length_unless_set():
    p = Params().with_overrides({"m1": 30.0, "L2": 1.0})
    assert p.I1x == pytest.approx(30 * 0.4**2 / 3)
    assert p.I2y == pytest.approx(60 * 1.0**2 / 3)
    q = Params().with_overrides({"I1x": 2.0, "I1z": 3.0}).with_overrides({"m1": 30.0})
    assert q.I1x == 2.0 and q.I1y == pytest.approx(30 * 0.4**2 / 3)


@pytest.mark.parametrize(
    "name, value, words",
    [
        ("m1", -1.0, "> 0"),
        ("m3", 0.0, "> 0"),
        ("L1", 0.0, "> 0"),
        ("L2", -0.7, "> 0"),
        ("Tp", 0.0, "> 0"),
        ("g", math.nan, "finite"),
        ("q10", math.inf, "finite"),
        ("I3x", -1.0, ">= 0"),
        ("I3x", 10.0, "triangle"),
        ("I1z", 100.0, "triangle"),
        ("beta23", -5.0, "gain"),
        ("gamma01", -1.0, "gain"),
    ],
)
def test_bad_parameter_is_refused_by_name(name, value, words):
    with pytest.raises(ParameterError) as info:
        Params(**{name: value})
    message = str(info.value)
    assert name in message and words in message and repr(float(value)) in message
    assert info.value.name == name


def test_non_number_is_refused():
    with pytest.raises(ParameterError, match="m2"):
        Params(m2="heavy")  # type: ignore[arg-type]


def test_parse_number_expressions():
    assert parse_number("pi/3") == math.pi / 3
    assert parse_number("-2*pi") == -2 * math.pi
    assert parse_number("1e-3") == 1e-3
    assert math.isnan(parse_number("nan"))
    for bad in ("__import__('os')", "pi/0", "x", "1 if 1 else 2", ""):
        with pytest.raises(OverrideError):
            parse_number(bad)


def test_parse_overrides():
    assert parse_overrides(["m1=10", "q1f=pi/2"]) == {"m1": 10.0, "q1f": math.pi / 2}
    with pytest.raises(OverrideError, match="unknown parameter.*valid names: L1, L2"):
        parse_overrides(["mass=1"])
    with pytest.raises(OverrideError, match="NAME=VALUE"):
        parse_overrides(["m1"])


def test_scene_file(tmp_path):
    path = tmp_path / "s.toml"
    path.write_text('[params]\nm3 = 50\nq1f = "pi/4"\n[options]\ndt = 0.01\n')
    scene = load_runfile(path)
    p = resolve_params(scene, {"m3": 45.0})
    assert p.m3 == 45.0 and p.q1f == math.pi / 4
    assert scene.options == {"dt": 0.01}


@pytest.mark.parametrize(
    "text, words",
    [
        ("[params]\nmass = 1\n", "unknown parameter 'mass'"),
        ("[physics]\n", "unknown table 'physics'"),
        ("[params\n", "not valid TOML"),
        ('[params]\nm1 = "heavy"\n', "not a number"),
        ("[params]\nm1 = true\n", "not a number"),
    ],
)
def test_bad_scene_file(tmp_path, text, words):
    path = tmp_path / "bad.toml"
    path.write_text(text)
    with pytest.raises(RunFileError, match=words):
        load_runfile(path)


def test_param_names_are_the_seeds_symbols():
    names = param_names()
    for symbol in ("L1", "L2", "m1", "m3", "I3x", "g", "beta01", "gamma23", "Tp", "q1f"):
        assert symbol in names
