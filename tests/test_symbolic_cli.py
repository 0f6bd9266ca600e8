"""``rrt-pin equations``: both methods, three formats, --steps, numbers, errors."""

import subprocess
import sys

import pytest

pytest.importorskip("sympy")

from rrt_pin.cli.app import main  # noqa: E402


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


@pytest.mark.parametrize("method", ["kane", "lagrange"])
@pytest.mark.parametrize("fmt", ["text", "pretty", "latex"])
def test_prints_three_equations(method, fmt, capsys):
    code, out, err = run(["equations", "--method", method, "--format", fmt], capsys)
    assert code == 0 and err == ""
    title = "Kane" if method == "kane" else "Lagrange"
    assert title in out.splitlines()[0]
    if fmt == "text":
        rows = [line for line in out.splitlines() if line.startswith("(")]
        assert [r[:4] for r in rows] == ["(1) ", "(2) ", "(3) "]
        assert "qddot1*" in rows[0] and "T01x" in rows[0]
        assert "T12y" in rows[1] and "g*" in rows[1]
        assert rows[2].startswith("(3) m3*qddot3 = F23z - g*m3*sin(q2)")
    elif fmt == "pretty":
        assert "q̈₁" in out and "q̈₃" in out and "(3)" in out
    else:
        assert r"\begin{align}" in out and r"\end{align}" in out
        assert out.count(r"\\") == 3
        assert r"\ddot{q}_{1}" in out and "T_{01x}" in out and "F_{23z}" in out


def test_both_methods_print_the_same_equations(capsys):
    _, kane, _ = run(["equations", "--method", "kane"], capsys)
    _, lagrange, _ = run(["equations", "--method", "lagrange"], capsys)
    body = [line for line in kane.splitlines() if not line.startswith("#")]
    assert body == [line for line in lagrange.splitlines() if not line.startswith("#")]


@pytest.mark.parametrize(
    "method, last", [("kane", "K*3 [eq. (28)]"), ("lagrange", "LHS3 [d/dt(∂T/∂q̇r) − ∂T/∂qr]")]
)
def test_steps(method, last, capsys):
    code, out, _ = run(["equations", "--method", method, "--steps"], capsys)
    assert code == 0
    for name in ("R10", "omega20", "alpha20", "vC2", "vC3", "aC1", "aC3", "Q2", "T1", last):
        assert any(line.startswith(name) for line in out.splitlines()), name
    # the corrected eq. (11): c2·q3, not the printed c2·q2
    vC3 = next(line for line in out.splitlines() if line.startswith("vC3 "))
    assert "q3" in vC3 and "q2)*q" not in vC3
    assert out.index("T1 [") < out.index("(1) ")


def test_steps_in_latex(capsys):
    code, out, _ = run(["equations", "--steps", "--format", "latex"], capsys)
    assert code == 0
    assert r"\begin{align*}" in out and r"\hat{\jmath}_{2}" in out and "M_{in\\,3}" in out


def test_numbers_substituted_with_set(capsys):
    code, out, _ = run(["equations", "--set", "m3=50", "--set", "g=10"], capsys)
    assert code == 0
    rows = [line for line in out.splitlines() if line.startswith("(")]
    assert rows[2].startswith("(3) 50.0*qddot3 = F23z")
    assert "500.0*sin(q2)" in rows[2]
    assert "m1" not in out.split("\n", 2)[2]


def test_scene_substitutes_numbers_and_options(tmp_path, capsys):
    scene = tmp_path / "s.toml"
    scene.write_text('[params]\nm3 = 20.0\n[options]\nmethod = "lagrange"\n', encoding="utf-8")
    code, out, _ = run(["equations", "--scene", str(scene)], capsys)
    assert code == 0
    assert "Lagrange" in out.splitlines()[0]
    assert "(3) 20.0*qddot3" in out


@pytest.mark.parametrize(
    "argv, words",
    [
        (["equations", "--method", "newton"], "invalid choice: 'newton'"),
        (["equations", "--format", "html"], "invalid choice: 'html'"),
        (["equations", "--set", "m3=nan"], "m3"),
        (["equations", "--set", "m3=-1"], "m3=-1.0"),
    ],
)
def test_bad_input_is_one_line_exit_2(argv, words, capsys):
    code, out, err = run(argv, capsys)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("rrt-pin") and words in err


def test_subprocess_bad_method():
    proc = subprocess.run(
        [sys.executable, "-m", "rrt_pin", "equations", "--method", "x"],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2 and proc.stdout == ""
    assert len(proc.stderr.splitlines()) == 1 and "Traceback" not in proc.stderr


def test_command_module_import_is_light():
    code = "import sys, rrt_pin.cli.commands.equations; print('sympy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"
