"""The formulas ``--help`` shows for eq. (30) and eq. (31) are the ones the code computes."""

from __future__ import annotations

import math
import re

import numpy as np

from rrt_pin.cli.commands import _chapter
from rrt_pin.dynamics.trajectory import rest_to_rest
from rrt_pin.robot.params import Params
from rrt_pin.simulate.control import chapter_controller

_ENV = {"sin": math.sin, "cos": math.cos, "pi": math.pi}


def _formula(text: str, lhs: str) -> str:
    """The right-hand side printed for ``lhs`` (one line of the help)."""
    (line,) = [x for x in text.splitlines() if x.strip().startswith(f"{lhs} =")]
    # Square brackets group terms in the help; Python needs parentheses.
    return line.split("=", 1)[1].replace("[", "(").replace("]", ")")


def _values(text: str, name: str) -> tuple[float, ...]:
    """A tuple such as ``q0 = (pi/18, pi/6, 0.25 m)`` as numbers."""
    found = re.search(rf"{name} = \(([^)]*)\)", text)
    assert found, name
    return tuple(eval(v.replace(" m", ""), dict(_ENV)) for v in found.group(1).split(","))


def test_eq30_as_printed_is_the_motion():
    p = Params()
    q0 = (p.q10, p.q20, p.q30)
    qf = (p.q1f, p.q2f, p.q3f)
    assert _values(_chapter.EQ30, "q0") == q0 and _values(_chapter.EQ30, "qf") == qf
    assert f"Tp = {p.Tp:g} s" in _chapter.EQ30
    rhs = _formula(_chapter.EQ30, "q_r(t)")
    t = np.linspace(0.0, p.Tp, 37)
    motion = rest_to_rest(q0, qf, p.Tp, t)
    for r in range(3):
        for i, ti in enumerate(t):
            env = dict(_ENV, q_r0=q0[r], q_rf=qf[r], Tp=p.Tp, t=ti)
            assert math.isclose(eval(rhs, env), motion.q[i, r], rel_tol=1e-14, abs_tol=1e-15)


def test_eq31_as_printed_is_the_law():
    p = Params()
    law = chapter_controller(p)
    assert _values(_chapter.EQ31, "q0") == (p.q10, p.q20, p.q30)
    for name in ("beta01", "gamma01", "beta12", "gamma12", "beta23", "gamma23"):
        assert re.search(rf"{name} = {getattr(p, name):g}\s", _chapter.EQ31), name
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(-2, 2, 3)
        qd = rng.uniform(-2, 2, 3)
        env = dict(_ENV, **{n: getattr(p, n) for n in Params.__dataclass_fields__})
        env.update(q1=q[0], q2=q[1], q3=q[2], qd1=qd[0], qd2=qd[1], qd3=qd[2])
        printed = [eval(_formula(_chapter.EQ31, lhs), env) for lhs in ("T01x", "T12y", "F23z")]
        np.testing.assert_allclose(law.efforts(0.0, q, qd), printed, rtol=1e-13, atol=1e-12)


def test_help_shows_them(capsys):
    from rrt_pin.cli.app import main

    for command, text in (("inverse", _chapter.EQ30), ("simulate", _chapter.EQ31)):
        try:
            main([command, "--help"])
        except SystemExit:
            pass
        out = capsys.readouterr().out
        assert " ".join(text.split()) in " ".join(out.split()), command
