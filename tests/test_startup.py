"""Start-up: a run imports only what it uses; the install step writes the package's bytecode,
so a process that may not write it compiles nothing; the lean ODEPACK route gives scipy's bits."""

from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import subprocess
import sys
from pathlib import Path

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


ROOT = Path(__file__).resolve().parents[1]

#: Runs the default jobs with PYTHONDONTWRITEBYTECODE=1 and prints the files of the modules
#: compiled from source, one a line: importlib's SourceLoader compiles them in this method
#: only when no current .pyc exists.
_COUNT_COMPILED = """\
import importlib._bootstrap_external as be, sys
compiled = []
source_to_code = be.SourceLoader.source_to_code
def counting(self, data, path, *args, **kwargs):
    compiled.append(str(path))
    return source_to_code(self, data, path, *args, **kwargs)
be.SourceLoader.source_to_code = counting
from rrt_pin.cli.app import main
assert main(["inverse", "--csv", "i.csv"]) == 0
assert main(["simulate", "--csv", "s.csv"]) == 0
print("\\n".join(compiled))
"""


def _compiled_at_import(checkout: Path) -> list[str]:
    """rrt_pin's files that the default inverse and simulate jobs compile from source."""
    env = {**os.environ, "PYTHONDONTWRITEBYTECODE": "1"}
    proc = subprocess.run([sys.executable, "-c", _COUNT_COMPILED], cwd=checkout, env=env,
                          capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    package = checkout / "rrt_pin"
    return [p for p in proc.stdout.splitlines() if Path(p).is_relative_to(package)]


def _stale_bytecode(package: Path) -> list[str]:
    """Modules of ``package`` whose .pyc is missing or not current for their source."""
    stale = []
    for source in sorted(package.rglob("*.py")):
        pyc = Path(importlib.util.cache_from_source(str(source)))
        stat = source.stat()
        header = pyc.read_bytes()[:16] if pyc.exists() else b""
        current = (
            header[:4] == importlib.util.MAGIC_NUMBER
            and int.from_bytes(header[4:8], "little") == 0  # checked by timestamp
            and int.from_bytes(header[8:12], "little") == int(stat.st_mtime) & 0xFFFFFFFF
            and int.from_bytes(header[12:16], "little") == stat.st_size & 0xFFFFFFFF
        )
        if not current:
            stale.append(str(source.relative_to(package)))
    return stale


def test_the_install_step_writes_the_bytecode_a_process_may_not(tmp_path):
    """scripts/_venv.sh (what scripts/test, scripts/demo and CI run) compiles every module, so
    that with PYTHONDONTWRITEBYTECODE=1 the default jobs compile none of rrt_pin's at import."""
    checkout = tmp_path / "clone"
    (checkout / "scripts").mkdir(parents=True)
    shutil.copy(ROOT / "scripts" / "_venv.sh", checkout / "scripts")
    shutil.copy(ROOT / "pyproject.toml", checkout)
    shutil.copytree(ROOT / "rrt_pin", checkout / "rrt_pin",
                    ignore=shutil.ignore_patterns("__pycache__"))  # fmt: skip
    # A .venv whose install is recorded as done: the step under test is what follows it.
    bin_dir = checkout / ".venv" / "bin"
    bin_dir.mkdir(parents=True)
    (bin_dir / "python").write_text(f'#!/bin/sh\nexec "{sys.executable}" "$@"\n')
    (bin_dir / "python").chmod(0o755)
    digest = hashlib.sha256((checkout / "pyproject.toml").read_bytes()).hexdigest()[:16]
    (checkout / ".venv" / ".rrt-pin-installed").write_text(f"{digest} test\n")

    before = _compiled_at_import(checkout)
    assert any(p.endswith(os.path.join("rrt_pin", "cli", "app.py")) for p in before), before
    assert _stale_bytecode(checkout / "rrt_pin")  # nothing was written: the flag was set

    proc = subprocess.run(["bash", "-c", "source scripts/_venv.sh test"], cwd=checkout,
                          capture_output=True, text=True)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "installing" not in proc.stderr  # the recorded install was taken as done
    assert _stale_bytecode(checkout / "rrt_pin") == []
    assert _compiled_at_import(checkout) == []


#: What the chapter's default jobs never need: the optional parts and their libraries, the
#: TOML parser (no --config), importlib.metadata (the version is a module constant).
NOT_FOR_DEFAULT_JOBS = {
    "rrt_pin.sweeps", "rrt_pin.viewer", "rrt_pin.dynamics.symbolic", "rrt_pin.cli.bench_report",
    "rrt_pin.cli.bench_measure", "rrt_pin.cli.flops", "rrt_pin.simulate.reference",
    "rrt_pin.simulate.accuracy", "matplotlib", "meshcat", "sympy", "dask",
    "pandas", "pyarrow", "tqdm", "selenium", "tomllib", "tomli", "importlib.metadata",
    "rrt_pin.cli.runfile", "rrt_pin.dynamics.kinematics",  # no --config, no --frames
}  # fmt: skip
#: ... and what each job needs least: the other's dynamics.
NOT_FOR = {
    "inverse": {"scipy", "rrt_pin.simulate.api", "rrt_pin.simulate.integrators"},
    "simulate": {"rrt_pin.dynamics.inverse", "rrt_pin.dynamics.wrenches"},
}


@pytest.mark.parametrize("command", ["inverse", "simulate"])
def test_default_jobs_import_only_their_own_command_and_what_it_runs(command, tmp_path):
    from rrt_pin.cli.commands import COMMANDS

    modules = _modules_after([command, "--csv", "out.csv"], tmp_path)
    assert f"rrt_pin.cli.commands.{command}" in modules and "numpy" in modules
    others = {f"rrt_pin.cli.commands.{c}" for c in COMMANDS if c != command}
    assert modules & others == set()
    assert modules & (NOT_FOR_DEFAULT_JOBS | NOT_FOR[command]) == set()


@pytest.mark.parametrize(
    ("argv", "command"),
    [
        (["inverse", "--csv", "x.csv"], "inverse"),
        (["-v", "-qq", "--quiet", "simulate", "--tf", "1"], "simulate"),
        (["--verbose", "urdf"], "urdf"),
        (["-h", "inverse"], None),  # the top-level help lists every command
        (["--version"], None),
        (["nosuchcommand"], None),  # argparse's error lists the valid ones
        (["--csv", "inverse"], None),
        ([], None),
    ],
)
def test_only_a_plainly_named_command_gets_a_parser_alone(argv, command):
    from rrt_pin.cli import app

    assert app._command_of(argv) == command
    _, subparsers = app.build_parser(command)
    assert len(subparsers) == (1 if command else len(app.COMMANDS))


def test_a_run_files_options_of_other_commands_still_pass(tmp_path):
    """[options] may hold any command's option: with --config every subparser is built."""
    run = tmp_path / "run.toml"
    run.write_text('[options]\nmethod = "rk4"\n[inverse]\ndt = 0.01\n')
    modules = _modules_after(["-q", "inverse", "--config", str(run), "--csv", "i.csv"], tmp_path)
    assert "tomllib" in modules or "tomli" in modules
    assert "rrt_pin.cli.commands.simulate" in modules  # its options were checked against


def test_default_simulate_skips_scipy_integrate(tmp_path):
    modules = _modules_after(["simulate", "--backend", "pinocchio", "--csv", "s.csv"], tmp_path)
    assert "scipy.integrate._odepack" in modules
    assert "scipy.integrate" not in modules and "scipy.special" not in modules
    assert "scipy" not in modules  # found through its spec: scipy/__init__ never runs
    # odepack's family alone: not the fixed-step or symplectic integrators' modules
    assert {"rrt_pin.simulate.integrators", "rrt_pin.simulate.symplectic"} & modules == set()
    assert "importlib.metadata" not in modules


#: Loads the lean ODEPACK route after numpy and prints the process's threads before and
#: after, then the OpenBLAS variable as the process sees it afterwards.
_THREADS_AFTER_LOAD = """\
import os, numpy
from rrt_pin.simulate import _odepack
before = len(os.listdir("/proc/self/task"))
_odepack.load()
print(before, len(os.listdir("/proc/self/task")), os.environ.get("OPENBLAS_NUM_THREADS"))
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts threads in /proc")
def test_lean_odeint_starts_no_blas_threads_and_leaves_the_environment():
    """scipy's OpenBLAS loads with one thread (no pool spinning beside the run), env restored."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    proc = subprocess.run([sys.executable, "-c", _THREADS_AFTER_LOAD], env=env, cwd=ROOT,
                          capture_output=True, text=True, check=True)  # fmt: skip
    before, after, variable = proc.stdout.split()
    assert after == before and variable == "None"
    # A user's setting is theirs: kept, and the library loads with it.
    env["OPENBLAS_NUM_THREADS"] = "2"
    proc = subprocess.run([sys.executable, "-c", _THREADS_AFTER_LOAD], env=env, cwd=ROOT,
                          capture_output=True, text=True, check=True)  # fmt: skip
    assert proc.stdout.split()[2] == "2"


def test_solve_ivp_methods_still_import_it(tmp_path):
    modules = _modules_after(["simulate", "--method", "RK45", "--tf", "1", "--csv", "s.csv"],
                             tmp_path)  # fmt: skip
    assert "scipy.integrate" in modules


#: Runs a command in-process, then prints the process's threads and the OpenBLAS variable.
_THREADS_AFTER_RUN = """\
import os, sys
from rrt_pin.cli.app import main
assert main(sys.argv[1:]) == 0
print(len(os.listdir("/proc/self/task")), os.environ.get("OPENBLAS_NUM_THREADS"))
"""


@pytest.mark.skipif(not Path("/proc/self/task").is_dir(), reason="counts threads in /proc")
@pytest.mark.parametrize("command", ["inverse", "simulate"])
def test_a_command_starts_no_blas_thread_pool(command, tmp_path):
    """numpy's and scipy's OpenBLAS load with one thread: the process ends with one thread,
    the variable is gone again (children get the default), and a user's setting is kept."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    argv = [sys.executable, "-c", _THREADS_AFTER_RUN, "-q", command, "--backend", "pinocchio",
            "--tf" if command == "simulate" else "--dt", "1" if command == "simulate" else "0.1",
            "--csv", "out.csv"]  # fmt: skip
    proc = subprocess.run(argv, env=env, cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1].split() == ["1", "None"]
    env["OPENBLAS_NUM_THREADS"] = "1"
    proc = subprocess.run(argv, env=env, cwd=tmp_path, capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.splitlines()[-1].split() == ["1", "1"]


#: Runs the CLI as the program (main() on sys.argv) or as a library call (main(argv)); a
#: handler registered before it runs after its own at exit and prints the frozen objects.
_FROZEN_AT_EXIT = """\
import atexit, gc, os, sys
atexit.register(lambda: os.write(1, f"frozen {gc.get_freeze_count()}\\n".encode()))
from rrt_pin.cli.app import main
sys.argv = ["rrt-pin", "-q", "inverse", "--backend", "pinocchio", "--dt", "0.1", "--csv", "i.csv"]
main() if PROGRAM else main(sys.argv[1:])
"""


@pytest.mark.parametrize("program", [True, False])
def test_the_program_exits_without_collecting_every_object(program, tmp_path):
    """As the program, the CLI freezes the heap at exit (no last walks over every object);
    called with argv, it leaves the caller's garbage collection alone."""
    code = _FROZEN_AT_EXIT.replace("PROGRAM", str(program))
    proc = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, capture_output=True,
                          text=True)  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    frozen = int(proc.stdout.split("frozen ")[-1])
    assert (frozen > 1000) if program else (frozen == 0)


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


_AUTO_LOOK = """
import sys
import numpy as np
from rrt_pin.core import backends
from rrt_pin.robot import robots
from rrt_pin.simulate.control import pd_gravity_controller
ur5 = robots.get("ur5")
law = pd_gravity_controller(ur5, kp=100.0, kd=20.0, qf=np.zeros(6))
choice = backends.choose(ur5, "simulate", "BDF", 5.0, controllers=[law], numeric_jacobian=True)
print(choice.name, "rrt_pin.compiled.robot_runs" in sys.modules)
"""


def test_auto_looks_at_a_robots_code_without_importing_its_runs(tmp_path):
    """Where nothing is built, auto's look at a robot's compiled entries (which one its laws
    and method take) imports none of the runs' machinery: the job runs on Pinocchio."""
    env = {**os.environ, "RRT_PIN_CACHE_DIR": str(tmp_path / "empty")}
    proc = subprocess.run([sys.executable, "-c", _AUTO_LOOK], env=env, cwd=ROOT,
                          capture_output=True, text=True, check=True)  # fmt: skip
    assert proc.stdout.split() == ["pinocchio", "False"], proc.stdout + proc.stderr
