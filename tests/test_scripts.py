"""scripts/_venv.sh: a .venv or interpreter too old for rrt-pin is named, with the way out."""

from __future__ import annotations

import shlex
import shutil
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

_FAKE_PYTHON = """#!/bin/sh
# A stand-in interpreter of version {version}: answers --version and the version check.
if [ "$1" = "--version" ]; then echo "Python {version}"; exit 0; fi
if [ "$1" = "-c" ]; then exec python3 -c "import sys; sys.version_info = ({major}, {minor}); $2"; fi
echo "fake python: unexpected $*" >&2; exit 99
"""


def _fake_python(path: Path, version: str) -> Path:
    major, minor = version.split(".")[:2]
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(_FAKE_PYTHON.format(version=version, major=major, minor=minor))
    path.chmod(0o755)
    return path


def _checkout(tmp: Path) -> Path:
    """A copy of the files _venv.sh reads: its own script and pyproject.toml."""
    (tmp / "scripts").mkdir()
    shutil.copy(ROOT / "scripts" / "_venv.sh", tmp / "scripts" / "_venv.sh")
    shutil.copy(ROOT / "pyproject.toml", tmp / "pyproject.toml")
    return tmp


def _source(tmp: Path, env_python: str | None = None) -> subprocess.CompletedProcess:
    env = {"PATH": "/usr/bin:/bin"}
    if env_python:
        env["PYTHON"] = env_python
    return subprocess.run(
        ["bash", "-c", f"source {tmp}/scripts/_venv.sh plot"],
        capture_output=True,
        text=True,
        env=env,
        timeout=60,
    )


def test_an_old_venv_is_named_with_the_way_out(tmp_path):
    tmp = _checkout(tmp_path)
    _fake_python(tmp / ".venv" / "bin" / "python", "3.9.2")
    proc = _source(tmp)
    assert proc.returncode == 2, proc.stderr
    assert "Python 3.9.2" in proc.stderr and ">= 3.10" in proc.stderr
    assert "rm -rf .venv" in proc.stderr and "PYTHON=" in proc.stderr
    assert not (tmp / ".venv" / ".rrt-pin-installed").exists()  # nothing installed


def test_an_old_interpreter_makes_no_venv(tmp_path):
    tmp = _checkout(tmp_path)
    old = _fake_python(tmp_path / "old" / "python3", "3.8.10")
    proc = _source(tmp, env_python=str(old))
    assert proc.returncode == 2, proc.stderr
    assert "Python 3.8.10" in proc.stderr and "PYTHON=python3.11" in proc.stderr
    assert not (tmp / ".venv").exists()


def test_a_recent_venv_passes_the_check(tmp_path):
    """The same check accepts a new enough interpreter (then goes on to install: stopped here)."""
    tmp = _checkout(tmp_path)
    _fake_python(tmp / ".venv" / "bin" / "python", "3.11.7")
    proc = _source(tmp)
    # Past the check, it tries to install with the fake interpreter, which refuses pip.
    assert "needs Python" not in proc.stderr
    assert "installing rrt-pin[plot] into .venv" in proc.stderr


def test_demo_writes_where_the_caller_says_and_its_suggestion_works(tmp_path):
    """scripts/demo OUTDIR is relative to the caller; the command it suggests last runs as printed.

    Uses the checkout's .venv as installed by scripts/test (its extras cover the demo's).
    """
    proc = subprocess.run(
        ["bash", str(ROOT / "scripts" / "demo"), "o//"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=300,
    )
    assert proc.returncode == 0, proc.stdout[-2000:] + proc.stderr[-2000:]
    assert "installing" not in proc.stderr  # nothing reinstalled
    for name in ("rrt.urdf", "inverse.csv", "inverse.png", "simulate.csv", "simulate.png"):
        assert (tmp_path / "o" / name).stat().st_size > 0, name
    assert "o/inverse.csv" in proc.stdout and "//" not in proc.stdout
    last = proc.stdout.strip().splitlines()[-1]
    assert last.startswith("watch it in a browser:"), last
    command = shlex.split(last.split(":", 1)[1])
    view = subprocess.run(
        [*command, "--serve-for", "0", "--port", "0"],
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert view.returncode == 0, view.stderr
    assert view.stdout.startswith("http://127.0.0.1:")
