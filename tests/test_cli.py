"""The CLI's contracts shared by every command: one-line errors, exit 2, nothing written."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

import rrt_pin
from rrt_pin.cli.app import main
from rrt_pin.robot.params import Params
from rrt_pin.robot.urdf import urdf_xml


def run(argv, capsys):
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_urdf_to_stdout_and_file(tmp_path, capsys):
    code, out, err = run(["urdf"], capsys)
    assert code == 0 and out == urdf_xml(Params())
    target = tmp_path / "arm.urdf"
    code, out, err = run(["urdf", "-o", str(target), "--set", "m3=50", "--set", "q1f=pi/4"], capsys)
    assert code == 0 and out == ""
    assert target.read_text() == urdf_xml(Params(m3=50.0, q1f=0.7853981633974483))


@pytest.mark.parametrize(
    "argv, words",
    [
        (["urdf", "--set", "m1=-1"], "m1=-1.0: must be > 0"),
        (["urdf", "--set", "L2=nan"], "L2=nan: must be finite"),
        (["urdf", "--set", "I3x=inf"], "I3x=inf: must be finite"),
        (["urdf", "--set", "I3x=100"], "triangle inequality"),
        (["urdf", "--set", "mass=1"], "unknown parameter; valid names: L1, L2, m1"),
        (["urdf", "--set", "m1"], "expected NAME=VALUE"),
        (["urdf", "--set", "m1=heavy"], "m1='heavy' is not a number"),
        (["urdf", "--min-inertia", "-1"], "must be >= 0"),
        (["urdf", "--bogus"], "unrecognized arguments: --bogus"),
        (["nosuchcommand"], "invalid choice"),
    ],
)
def test_bad_input_is_one_line_exit_2_nothing_written(tmp_path, capsys, argv, words):
    target = tmp_path / "out.urdf"
    full = argv + (["-o", str(target)] if argv[0] == "urdf" else [])
    code, out, err = run(full, capsys)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and words in err, err
    assert list(tmp_path.iterdir()) == []


def test_existing_file_is_left_untouched_on_error(tmp_path, capsys):
    target = tmp_path / "keep.urdf"
    target.write_text("precious")
    code, _, _ = run(["urdf", "-o", str(target), "--set", "m2=0"], capsys)
    assert code == 2 and target.read_text() == "precious"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.urdf"]


def test_scene_file_and_set_precedence(tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text("[params]\nm3 = 50\nL2 = 1.0\n")
    code, out, _ = run(["urdf", "--scene", str(scene), "--set", "m3=45"], capsys)
    assert code == 0 and out == urdf_xml(Params(m3=45.0, L2=1.0))


def test_scene_option_must_belong_to_the_command(tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text("[options]\nfps = 30\n")  # view's option: urdf ignores it
    code, out, _ = run(["urdf", "--scene", str(scene)], capsys)
    assert code == 0 and out == urdf_xml(Params())
    scene.write_text("[urdf]\nfps = 30\n")  # urdf's own table: refused
    code, _, err = run(["urdf", "--scene", str(scene)], capsys)
    assert code == 2 and "[urdf] 'fps' is not an option of 'rrt-pin urdf'" in err


def test_scene_options_are_defaults_that_flags_override(tmp_path, capsys):
    scene = tmp_path / "scene.toml"
    scene.write_text("[options]\nmin_inertia = 0.5\n")
    code, out, _ = run(["urdf", "--scene", str(scene)], capsys)
    assert code == 0 and out == urdf_xml(Params(), min_inertia=0.5)
    code, out, _ = run(["urdf", "--scene", str(scene), "--min-inertia", "0"], capsys)
    assert code == 0 and out == urdf_xml(Params())


def test_subprocess_exit_status_and_no_traceback():
    proc = subprocess.run(
        [sys.executable, "-m", "rrt_pin", "urdf", "--set", "m1=-1"], capture_output=True, text=True
    )
    assert proc.returncode == 2
    assert proc.stdout == ""
    assert proc.stderr == "rrt-pin: error: parameter m1=-1.0: must be > 0\n"


def test_help_mentions_si_units(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    assert info.value.code == 0
    assert "SI units" in capsys.readouterr().out


def test_import_is_light():
    code = "import sys, rrt_pin, rrt_pin.cli.app; print(sorted(m for m in ('pinocchio', 'numpy', 'meshcat', 'sympy', 'matplotlib', 'numba') if m in sys.modules))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


@pytest.mark.parametrize(
    "requested, built, loaded, aot, task, method, work, expected",
    [
        # The chapter's 15,001 samples from the JIT's cache: ~0.7 s to save ~1 ms over the
        # arm's numpy kernel (the same efforts, and no import of Pinocchio)
        ("auto", True, False, False, "inverse", None, 15_001, "symbolic"),
        ("auto", True, True, False, "inverse", None, 15_001, "compiled"),  # start-up paid
        ("auto", True, False, False, "inverse", None, 10_000_000, "compiled"),
        ("auto", False, False, False, "inverse", None, 10_000_000, "symbolic"),  # not built
        ("pinocchio", True, True, False, "inverse", None, 10_000_000, "pinocchio"),
        ("symbolic", False, False, False, "inverse", None, 15_001, "symbolic"),
        # a method left unnamed is the chosen backend's default
        ("auto", True, True, False, "simulate", None, 1e6, "compiled"),
        # odepack runs on Pinocchio only
        ("auto", True, True, False, "simulate", "odepack", 1e6, "pinocchio"),
        ("auto", True, False, False, "simulate", "DOP853", 15.0, "pinocchio"),
        ("auto", True, True, False, "simulate", "DOP853", 15.0, "compiled"),
        ("auto", True, False, False, "simulate", "DOP853", 1e5, "compiled"),
        ("auto", True, False, False, "simulate", "DOP853", 1e3, "pinocchio"),  # 0.74 s vs 0.48
        # Built ahead of time: loads in milliseconds, so compiled whatever the job
        ("auto", True, False, True, "inverse", None, 1, "compiled"),
        ("auto", True, False, True, "inverse", None, 15_001, "compiled"),
        ("auto", False, False, True, "inverse", None, 200_000, "compiled"),
        ("auto", True, False, True, "simulate", "DOP853", 15.0, "compiled"),
        ("auto", True, False, True, "simulate", None, 15.0, "compiled"),
        ("compiled", True, False, True, "simulate", "DOP853", 15.0, "compiled"),
        ("compiled", True, False, True, "inverse", None, 10, "compiled"),
    ],
)
def test_auto_backend_picks_compiled_only_when_built_and_faster(
    monkeypatch, requested, built, loaded, aot, task, method, work, expected
):
    import rrt_pin.compiled as compiled
    from rrt_pin.cli.commands._common import resolve_backend
    from rrt_pin.compiled import _aot
    from rrt_pin.robot.robots import chapter_arm

    robot = chapter_arm()
    monkeypatch.setattr(_aot, "_loaded", None)  # what this process loaded is patched below
    monkeypatch.setattr(compiled, "is_compiled", lambda: built)
    monkeypatch.setattr(compiled, "is_loaded", lambda: loaded and built)
    monkeypatch.setattr(compiled, "aot_built", lambda: aot)
    loads = []
    monkeypatch.setattr(compiled, "ensure_compiled", lambda: loads.append(1) or _FakeReport())
    assert resolve_backend(requested, robot, task, method, work=work) == expected
    # numba is imported and the JIT loaded only when compiled runs without the
    # ahead-of-time module (which the run loads on first use)
    jit = expected == "compiled" and not aot
    assert loads == ([1] if jit else [])


def test_auto_is_one_policy_that_the_cli_follows(monkeypatch):
    """``backends.choose`` decides; the CLI only loads what it chose and says why."""
    import re

    import numpy as np

    from rrt_pin.cli.commands._common import resolve_backend
    from rrt_pin.core import backends
    from rrt_pin.dynamics import inverse
    from rrt_pin.robot.robots import chapter_arm

    arm = chapter_arm()
    asked = []

    def chose(*a, **k):
        asked.append(a[1])
        return backends.Choice("symbolic", "test")

    monkeypatch.setattr(backends, "choose", chose)
    assert resolve_backend("auto", arm, "inverse", work=1) == "symbolic"
    # the library's default follows the same policy
    monkeypatch.delenv("RRT_PIN_BACKEND", raising=False)
    monkeypatch.setattr(inverse.kernel, "inverse_dynamics", lambda *a: np.full((1, 3), 7.0))
    assert (
        inverse.inverse_dynamics(arm, np.zeros(3), np.zeros(3), np.zeros(3)).tolist() == [7.0] * 3
    )
    assert asked == ["inverse", "inverse"]
    monkeypatch.undo()
    choice = backends.choose(arm, "inverse", None, 0.0)
    assert choice.name in ("pinocchio", "compiled") and choice.reason
    # no other module decides "auto": it is compared with a name in one place only
    package = Path(rrt_pin.__file__).parent
    deciding = [
        str(path.relative_to(package))
        for path in package.rglob("*.py")
        if re.search(r"""[!=]=\s*["']auto["']""", path.read_text(encoding="utf-8"))
    ]
    assert deciding == ["core/backends.py"], deciding


def _nothing_built(tmp_path: Path) -> dict[str, str]:
    """The environment of a process with an empty compiled cache (auto then picks pinocchio)."""
    return {**os.environ, "RRT_PIN_CACHE_DIR": str(tmp_path / "empty-cache")}


def test_auto_says_what_it_chose_with_v(tmp_path):
    proc = subprocess.run(
        [sys.executable, "-m", "rrt_pin", "-v", "inverse", "--backend", "auto", "--dt", "0.5"],
        capture_output=True, text=True, cwd=tmp_path, env=_nothing_built(tmp_path),
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "backend auto chose symbolic (the same efforts" in proc.stderr


class _FakeReport:
    def describe(self) -> str:
        return "compiled backend loaded from the cache in 0.01 s"


def test_compiled_backend_without_numba_is_one_line(monkeypatch, capsys):
    import rrt_pin.compiled as compiled

    def missing():
        raise ImportError("numba not found: pip install rrt-pin[fast]")

    monkeypatch.setattr(compiled, "ensure_compiled", missing)
    # without numba nothing built ahead of time matches either (its key names numba)
    monkeypatch.setattr(compiled, "aot_built", lambda: False)
    monkeypatch.setattr("rrt_pin.compiled._aot.load", lambda: None)
    monkeypatch.setattr(compiled, "_code", None)  # as in a process that has chosen nothing yet
    assert main(["simulate", "--backend", "compiled"]) == 2
    err = capsys.readouterr().err
    assert (
        err
        == "rrt-pin: error: backend 'compiled' is not available: numba not found: pip install rrt-pin[fast]\n"
    )


def test_negative_values_after_list_options(capsys):
    """--q0 -0.1,0.5,0.3 is a value, not an option (negative joint values are everyday)."""
    code = main(["simulate", "--q0", "-0.1,0.5,0.3", "--tf", "1", "--dt", "0.5"])
    out = capsys.readouterr().out
    assert code == 0 and "simulated the RRT arm" in out
    code = main(["inverse", "--q0", "-0.1,0.5,0.3", "--qf", "-.2,0.5,0.3", "--dt", "0.5"])
    assert code == 0


def test_an_ascii_terminal_gets_no_traceback(tmp_path):
    import os
    import subprocess
    import sys

    env = {**os.environ, "PYTHONIOENCODING": "ascii"}
    proc = subprocess.run([sys.executable, "-m", "rrt_pin", "inverse", "--dt", "0.5"],
                          capture_output=True, text=False, env=env)  # fmt: skip
    assert proc.returncode == 0 and b"Traceback" not in proc.stderr
    assert b"N\\xb7m" in proc.stdout  # the unit, escaped rather than fatal


def test_run_file_options_are_parsed_as_flags(tmp_path, capsys):
    run_file = tmp_path / "run.toml"
    run_file.write_text("[options]\nwrenches = true\ndt = 0.5\nq0 = [-0.1, 0.5, 0.3]\n")
    code = main(["inverse", "--config", str(run_file)])
    out = capsys.readouterr().out
    assert code == 0 and "|F01| at A" in out and "3 samples" not in out
    assert "31 samples" in out  # 15 s at 0.5 s


def test_a_csv_with_a_byte_order_mark_reads(tmp_path):
    from rrt_pin.io.csvio import read_csv

    path = tmp_path / "bom.csv"
    path.write_bytes("\ufefft,q1\n0,1\n".encode())
    header, data = read_csv(path, required=("t",))
    assert header == ["t", "q1"] and data.tolist() == [[0.0, 1.0]]


@pytest.mark.parametrize(
    "argv, says_wrote, says_why",
    [
        (["urdf", "-o", "{out}"], True, False),
        (["-q", "urdf", "-o", "{out}"], False, False),
        (["urdf", "-o", "{out}", "-q"], False, False),  # after the command too
        (["urdf", "--quiet", "-o", "{out}"], False, False),
        (["-v", "urdf", "-o", "{out}"], True, True),
        (["urdf", "-o", "{out}", "-v"], True, True),
    ],
)
def test_verbosity_flags_anywhere_on_the_line(argv, says_wrote, says_why, tmp_path):
    out = tmp_path / "arm.urdf"
    argv = [a.replace("{out}", str(out)) for a in argv]
    proc = subprocess.run(
        [sys.executable, "-m", "rrt_pin", *argv], capture_output=True, text=True, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr
    assert out.stat().st_size > 0  # -q hides the note, never the work
    assert (f"wrote {out}" in proc.stderr) == says_wrote, proc.stderr
    if says_why:  # -v after the command as well as before it
        argv = ["inverse", "--dt", "0.5", "--backend", "auto"]
        argv = ["-v", *argv] if argv[0] == "-v" else [*argv, "-v"]
        proc = subprocess.run([sys.executable, "-m", "rrt_pin", *argv], capture_output=True,
                              text=True, cwd=tmp_path, env=_nothing_built(tmp_path))  # fmt: skip
        assert "backend auto chose symbolic" in proc.stderr, proc.stderr


def test_verbosity_levels():
    import logging

    from rrt_pin.cli.app import verbosity_level
    from rrt_pin.core._logging import NOTICE

    assert verbosity_level(0, 0) == NOTICE
    assert verbosity_level(1, 0) == logging.INFO and verbosity_level(5, 0) == logging.DEBUG
    assert verbosity_level(0, 1) == logging.WARNING and verbosity_level(0, 9) == logging.ERROR
    assert verbosity_level(1, 1) == NOTICE
