"""Generated functions lowered to LLVM IR past numba's front end (rrt_pin.compiled._straight).

Each lowered function must give numba's own bits: both compilations of the same source
are run on random inputs (NaN, infinities, signed zeros and angles past the polynomial
sine's range included) and compared bit for bit; the written-out losses of ``rhs_phys``
are checked against the definition (``applied_efforts`` and ``pin.aba``).
"""

from __future__ import annotations

import math
import re
from dataclasses import replace

import numba
import numpy as np
import pinocchio as pin
import pytest

from rrt_pin.compiled import robot_code
from rrt_pin.compiled._straight import lowered, stub, supported
from rrt_pin.robot import robots
from rrt_pin.robot.limits import applied_efforts, physical_model
from rrt_pin.simulate.physical_runs import limit_inertia

#: Every construct the lowering accepts, with ints and floats mixed as Python mixes them.
EVERY_CONSTRUCT = """\
def every(x, out):
    a = x[0]
    b = x[1]
    if abs(a) < 1e6:
        n = int(a * 3.7)
    else:
        n = 7
    n += n & 1
    m = (n + 2) & 4
    f = float(n) - b / 3.0
    k = n * 2 - 5
    if abs(a) < 2.5:
        s = sin(a) * -b
        c = cos(b) if m & 4 else -cos(a)
    elif a > b:
        s = sqrt(abs(a)) + k
        c = tanh(b) - 1
    else:
        s = 1.0
        c = a if a != b else b
    out[0] = s
    out[1] = c
    out[2] = f
    out[3] = -k
    out[4] = a if a <= b else (b if b >= 0.0 else 2)
    out[5] = abs(k) * (a == b) + (1.0 if b else 2.0)
"""


def _plain(source: str):
    """The function compiled by numba itself (its front end), as rrt-pin's modules were."""
    space = {"sin": math.sin, "cos": math.cos, "sqrt": math.sqrt, "tanh": math.tanh, "math": math}
    exec(source, space)
    name = re.match(r"def (\w+)", source)[1]
    return numba.njit(error_model="numpy")(space[name])


def _lowered(source: str):
    """The same function as rrt-pin writes it now: a jitted call of its lowered body."""
    m = re.match(r"def (\w+)\(([^)]*)\)", source)
    args = tuple(a.strip() for a in m[2].split(","))
    space = {"lowered": lowered, "jit": numba.njit(error_model="numpy"), "math": math}
    exec(stub(m[1], args, source), space)
    return space[m[1]]


def _same_bits(a: np.ndarray, b: np.ndarray) -> bool:
    return np.array_equal(a.view(np.int64), b.view(np.int64))


def test_every_construct_gives_numbas_own_bits():
    plain, low = _plain(EVERY_CONSTRUCT), _lowered(EVERY_CONSTRUCT)
    rng = np.random.default_rng(7)
    special = [0.0, -0.0, 1.0, -1.0, 2.5, -2.5, np.inf, -np.inf, np.nan, 1e300, 5e-324]
    inputs = [np.array([u, v]) for u in special for v in special]
    inputs += [rng.normal(0, s, 2) for s in (0.5, 2.0, 10.0) for _ in range(300)]
    differ = []
    for x in inputs:
        o1, o2 = np.zeros(6), np.zeros(6)
        plain(x, o1)
        low(x, o2)
        if not _same_bits(o1, o2):
            differ.append((x, o1, o2))
    assert not differ, differ[:3]
    # and the values are Python's own, for a finite input on each branch
    space = {"sin": math.sin, "cos": math.cos, "sqrt": math.sqrt, "tanh": math.tanh}
    exec(EVERY_CONSTRUCT, space)
    for x in (np.array([0.3, -1.7]), np.array([4.0, 1.5]), np.array([-4.0, 1.5])):
        ours, python = np.zeros(6), [0.0] * 6
        low(x, ours)
        space["every"](list(x), python)
        assert ours.tolist() == python


#: A lanes' function: one counted loop, indices offset by its index, max/min and math.nan.
LANES = """\
def lanes(w):
    for l in range(8):
        a = w[l]
        b = w[8 + l]
        m = max(abs(a), abs(b), 0.5)
        n = min(a, 2, b)
        w[16 + l] = (a * b + m) if m < 3.0 else math.nan
        w[l + 24] = n - m
"""


def test_a_lanes_loop_gives_numbas_own_bits():
    plain, low = _plain(LANES), _lowered(LANES)
    rng = np.random.default_rng(5)
    taken = set()
    for scale in (0.5, 2.0, 10.0):
        for _ in range(200):
            w = rng.normal(0.0, scale, 32)
            w[rng.integers(0, 16)] = rng.choice([np.nan, np.inf, -0.0, 2.0])
            a, b = w.copy(), w.copy()
            plain(a)
            low(b)
            assert _same_bits(a, b)
            taken |= set(np.isnan(a[16:24]).tolist())
    assert taken == {True, False}  # both sides of the conditional


#: A block's loop as the generated RNEA's: its length an integer argument.
BLOCK = """\
def block(w, m):
    for j in range(m):
        x = w[j]
        y = w[16 + j]
        w[32 + j] = abs(x * y - sin(x)) if x < y else cos(y) / x
"""


def test_a_loop_of_given_length_gives_numbas_own_bits():
    plain = _plain(BLOCK)
    body = lowered("block", ("w", "m"), BLOCK, counts=("m",))

    @numba.njit(error_model="numpy")
    def low(w, m):
        body(w, m)

    rng = np.random.default_rng(9)
    for m in (0, 1, 5, 16):
        w = rng.normal(0.0, 2.0, 48)
        w[3] = 0.0
        a, b = w.copy(), w.copy()
        plain(a, m)
        low(b, m)
        assert _same_bits(a, b)
        assert np.array_equal(b[32 + m :], w[32 + m :])  # nothing past the m-th lane
    assert supported(BLOCK, counts=("m",)) and not supported(BLOCK)
    assert not supported(BLOCK.replace("x = w[j]", "m = 2.0\n        x = w[j]"), counts=("m",))


@pytest.mark.parametrize(
    "source",
    [
        "def f(x, out):\n    for i in range(2):\n        out[i] = x[i]\n    out[0] = 1.0\n",  # more than a loop
        "def f(x, out):\n    for i in range(len(x)):\n        out[i] = x[i]\n",  # a loop not counted
        "def f(x, out):\n    for i in range(2):\n        out[2 * i] = x[i]\n",  # an index not i + N
        "def f(x, out):\n    out[0] = x[1 + 1]\n",  # an index computed outside a loop
        "def f(x, out):\n    out[0] = g(x[0])\n",  # a call of another function
        "def f(x, out):\n    i = 1\n    out[0] = x[i]\n",  # an index that is not a constant
        "def f(x, out):\n    out[0] = x[0] ** 2\n",  # an operator left out
        "def f(x, out):\n    out[0] = 0.0 < x[0] < 1.0\n",  # a chained comparison
        "def f(x, out, k=1):\n    out[0] = x[0]\n",  # a default
        "def f(x, out):\n    x = 1.0\n",  # an array rebound
        "def f(x, out):\n    return x[0]\n",  # a return
        "def f(x, out):\n    if x[0] < 1.0:\n        a = 1.0\n    out[0] = a\n",  # not on every path
        "def f(x, out):\n    a += 1.0\n    out[0] = a\n",  # read before it is assigned
    ],
)
def test_what_is_not_lowered_is_said_so(source):
    assert not supported(source)
    body = lowered("f", ("x", "out"), source)

    @numba.njit
    def f(x, out):
        body(x, out)

    with pytest.raises(Exception, match="outside the part of Python"):  # numba wraps it
        f(np.zeros(2), np.zeros(2))


#: The lanes' work array's rows, per robot's nv (read from its module's text).
_ROWS: dict[int, int] = {}


def _parts(model: pin.Model) -> dict[str, str]:
    """Each lowered function of ``model``'s module: its name and source."""
    text, _ = robot_code.module_source(model)
    _ROWS[model.nv] = int(re.search(r"^PHYS_ROWS = (\d+)$", text, re.M)[1])
    found = re.findall(r'_(\w+)_ir = lowered\(\'\w+\', \([^)]*\), """\\\n(.*?)"""\)', text, re.S)
    return dict(found)


def test_a_robots_module_lowers_every_generated_function():
    """The functions the module writer lowers (its templates stay numba's)."""
    assert set(_parts(robots.get("ur5").model)) == {
        "forward", "rhs_pd", "forward_free", "rhs_phys", "gravity", "mass_matrix", "bias",
        "closed_loop_jac", "phys_sincos", "gravity_lanes", "free_lanes",
    }  # fmt: skip


def _inputs(name: str, source: str, nv: int, rng: np.random.Generator) -> list[np.ndarray]:
    args = re.match(r"def \w+\(([^)]*)\)", source)[1].replace(" ", "").split(",")
    scale = rng.choice([0.3, 3.0, 1e9])  # 1e9 rad: past the polynomial sine, libm's
    given = {
        "y": rng.normal(0.0, 1.0, 2 * nv) * np.r_[np.full(nv, scale), np.ones(nv)],
        "tau": rng.normal(0.0, 20.0, nv),
        "c": rng.normal(0.0, 10.0, 3 * nv),
        "P": _random_physical(nv, rng),
    }
    if args == ["w"]:  # the lanes' work array: 8 lanes a row, any values (NaN past the limit)
        return [rng.normal(0.0, 1.0, robot_code.LANES * _ROWS[nv]) * scale]
    rows = {"forward": 2 * nv, "forward_free": 2 * nv, "rhs_pd": 2 * nv, "rhs_phys": 2 * nv}
    shapes = {"mass_matrix": (nv, nv), "closed_loop_jac": (nv, 1 + 2 * nv)}
    out = np.zeros(shapes.get(name, (rows.get(name, nv),)))
    return [given[a] if a != "out" else out for a in args]


def _random_physical(nv: int, rng: np.random.Generator) -> np.ndarray:
    """A Physical.as_array (8, nv) with some joints free of friction, damping and limits."""
    P = np.zeros((8, nv))
    P[0] = rng.normal(0.0, 1.0, nv)
    P[1] = P[0] + rng.uniform(0.0, 2.0, nv)
    P[2] = rng.uniform(1.0, 100.0, nv)
    P[3] = rng.uniform(0.0, 2.0, nv) * (rng.random(nv) < 0.7)
    P[4] = rng.uniform(0.0, 2.0, nv) * (rng.random(nv) < 0.5)
    P[5] = rng.uniform(0.0, 1e5, nv)
    P[6] = rng.uniform(0.0, 100.0, nv)
    return P


@pytest.mark.parametrize("robot", ["ur5", "panda", "double_pendulum"])
def test_a_robots_lowered_functions_give_numbas_own_bits(robot):
    """UR5 (CRBA + LDLᵀ), Panda (ABA): the functions numba compiles fast enough here (the
    lanes' too); the closed-loop Jacobian on the double pendulum (UR5's is long for numba)."""
    model = robots.get(robot).model
    nv, rng = model.nv, np.random.default_rng(11)
    parts = _parts(model)
    names = ["closed_loop_jac", "rhs_phys"] if robot == "double_pendulum" else [
        "forward", "rhs_pd", "rhs_phys", "gravity", "mass_matrix", "bias", "phys_sincos",
        "gravity_lanes", "free_lanes",
    ]  # fmt: skip
    if robot == "panda":
        names = ["rhs_phys", "mass_matrix"]
    for name in names:
        plain, low = _plain(parts[name]), _lowered(parts[name])
        for _ in range(300):
            a = _inputs(name, parts[name], nv, rng)
            b = [x.copy() for x in a]
            plain(*a)
            low(*b)
            assert _same_bits(a[-1], b[-1]), name


def test_the_written_out_losses_are_the_definitions():
    """rhs_phys's q̈ is ABA under the saturated law plus damping, friction and the limits'
    springs, as :func:`rrt_pin.robot.limits.applied_efforts` defines them."""
    robot = robots.get("ur5")
    model, data, nv = robot.model, robot.model.createData(), robot.nv
    low = _lowered(_parts(model)["rhs_phys"])
    rng = np.random.default_rng(3)
    stated = physical_model(robot)
    for i in range(200):
        q = rng.uniform(stated.lower, stated.upper)
        k = i % nv  # one joint past a limit each time, each joint and side in turn
        q[k] = stated.lower[k] - 0.05 if (i // nv) % 2 else stated.upper[k] + 0.05
        v = rng.normal(0.0, 1.0, nv) * rng.choice([1e-4, 1.0])  # friction's tanh, both ends
        p = stated.at(limit_inertia(robot, q))
        p = replace(p, damping=rng.uniform(0, 2, nv),
                    friction=rng.uniform(0, 2, nv) * (rng.random(nv) < 0.6))  # fmt: skip
        kp, kd, qf = rng.uniform(10, 500, nv), rng.uniform(1, 50, nv), rng.normal(0, 1, nv)
        out = np.zeros(2 * nv)
        low(np.r_[q, v], np.r_[kp, kd, qf], p.as_array(), out)
        g = pin.computeGeneralizedGravity(model, data, q)
        tau = applied_efforts(g - kd * v - kp * (q - qf), q, v, p)
        expected = pin.aba(model, data, q, v, tau)
        assert np.array_equal(out[:nv], v)
        np.testing.assert_allclose(out[nv:], expected, rtol=1e-9, atol=1e-9)


def test_a_change_to_the_lowering_changes_the_modules_it_wrote(monkeypatch):
    """Numba's cache is keyed by a module's text: the lowering's fingerprint is part of it,
    so code lowered by an older ``_straight`` is not loaded after an upgrade."""
    from rrt_pin.compiled import _straight
    from rrt_pin.compiled.rnea import module_source as rnea_source_of
    from rrt_pin.dynamics.rnea_source import rnea_source

    model = robots.get("double_pendulum").model
    before = (robot_code.module_source(model)[0], rnea_source_of(rnea_source(model)))
    assert all(_straight.VERSION in text for text in before)
    monkeypatch.setattr(_straight, "VERSION", "another lowering")
    after = (robot_code.module_source(model)[0], rnea_source_of(rnea_source(model)))
    assert before[0] != after[0] and before[1] != after[1]
