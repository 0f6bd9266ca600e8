"""The default backend (``auto``): compiled code wherever it is built and gives the same numbers.

The session sets ``RRT_PIN_BACKEND=pinocchio`` (tests/conftest.py); these tests remove it.
Fresh processes show what a user's first call gets: nothing compiled unasked, and code
built ahead of time loaded without numba.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrt_pin import simulate, time_grid
from rrt_pin.core import backends
from rrt_pin.core.errors import InputError
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate.control import chapter_controller

ROOT = Path(__file__).resolve().parents[1]


def _env(cache: Path | None = None, **more: str) -> dict[str, str]:
    """This process's environment without the session's default backend."""
    env = {k: v for k, v in os.environ.items() if k != "RRT_PIN_BACKEND"}
    if cache is not None:
        env["RRT_PIN_CACHE_DIR"] = str(cache)
    env.update(more)
    return env


def _run(code: str, env: dict[str, str]) -> dict:
    """Run ``code`` in a fresh interpreter; the JSON it prints last."""
    proc = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, env=env, cwd=ROOT
    )
    assert proc.returncode == 0, proc.stderr
    return json.loads(proc.stdout.strip().splitlines()[-1])


def test_the_default_is_auto_unless_the_variable_names_a_backend(monkeypatch):
    monkeypatch.delenv("RRT_PIN_BACKEND", raising=False)
    assert backends.default() == "auto"
    monkeypatch.setenv("RRT_PIN_BACKEND", "compiled")
    assert backends.default() == "compiled"
    monkeypatch.setenv("RRT_PIN_BACKEND", "fastest")
    with pytest.raises(InputError, match="RRT_PIN_BACKEND='fastest' is not one of"):
        backends.default()


_FIRST_USE = """
import json, logging, sys
import numpy as np
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin import simulate, time_grid
from rrt_pin.simulate.control import chapter_controller
arm = chapter_arm()
p = arm.params
rng = np.random.default_rng(1)
q, qd, qdd = (rng.uniform(-1.0, 1.0, (500, 3)) for _ in range(3))
tau = inverse_dynamics(arm, q, qd, qdd)
numba_after_inverse = "numba" in sys.modules
run = simulate(arm, chapter_controller(p), (p.q10, p.q20, p.q30), None, time_grid(2.0, 0.01))
ref = inverse_dynamics(arm, q, qd, qdd, backend="pinocchio")
print(json.dumps({
    "numba": numba_after_inverse, "backend": run.backend, "method": run.method,
    "worst": float(np.max(np.abs(tau - ref) / (1.0 + np.abs(ref)))),
    "q": run.q[-1].tolist(),
}))
"""


def test_a_fresh_process_without_built_code_never_compiles(tmp_path):
    cache = tmp_path / "cache"
    got = _run(_FIRST_USE, _env(cache))
    assert got["backend"] == "pinocchio" and got["method"] == "odepack"
    assert not got["numba"]
    # no machine code was written: nothing compiled
    made = [p for p in cache.rglob("*") if p.suffix in (".nbi", ".nbc", ".so")]
    assert made == []


def test_code_built_ahead_of_time_is_the_default_and_gives_the_same_numbers(tmp_path):
    from rrt_pin import compiled

    compiled.ensure_compiled()  # the JIT and the module built ahead of time, this checkout's cache
    if not compiled.aot_built():
        pytest.fail("the ahead-of-time module was not built (a C compiler is needed)")
    got = _run(_FIRST_USE, _env())
    assert got["backend"] == "compiled" and got["method"] == "DOP853"
    assert not got["numba"], "the module built ahead of time loads without numba"
    assert got["worst"] <= 1e-13
    # the same run on the engine of record, here: both within the accuracy asked (1e-8)
    p = chapter_arm().params
    ref = simulate(chapter_arm(), chapter_controller(p), (p.q10, p.q20, p.q30), None,
                   time_grid(2.0, 0.01), backend="pinocchio", estimate_error=False)  # fmt: skip
    assert np.max(np.abs(np.array(got["q"]) - ref.q[-1])) <= 2e-8


_GENERATED = """
import json, logging, sys
logging.basicConfig(level=25, format="%(message)s")  # the notes a CLI user sees
import numpy as np
from rrt_pin.robot.robots import get
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.compiled import rnea
robot = get("double_pendulum")
rng = np.random.default_rng(2)
q, qd, qdd = (rng.uniform(-1.0, 1.0, (300, robot.nv)) for _ in range(3))
tau = inverse_dynamics(robot, q, qd, qdd, backend=sys.argv[1] if len(sys.argv) > 1 else None)
kernel = rnea._MODELS.get(robot.model)
ref = inverse_dynamics(robot, q, qd, qdd, backend="pinocchio")
print(json.dumps({
    "numba": "numba" in sys.modules,
    "origin": None if kernel is None else kernel[1].origin,
    "worst": float(np.max(np.abs(tau - ref) / (1.0 + np.abs(ref)))),
}))
"""


def test_a_robots_generated_kernel_is_built_ahead_of_time_and_chosen_without_numba(tmp_path):
    cache = tmp_path / "cache"
    env = _env(cache, RRT_PIN_AOT="1")
    # before anything is built: Pinocchio, and nothing compiled
    first = _run(_GENERATED, env)
    assert first["origin"] is None and not first["numba"]
    # asked for: compiled, and built ahead of time beside the JIT
    proc = subprocess.run(
        [sys.executable, "-c", _GENERATED.replace("sys.argv[1] if len(sys.argv) > 1 else None",
                                                  "'compiled'")],
        capture_output=True, text=True, env=env, cwd=ROOT,
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    assert "ahead of time once" in proc.stderr  # announced
    modules = list((cache / "generated" / "aot").glob("*.so"))
    assert len(modules) == 1
    # then the default: the module, no numba, Pinocchio's efforts
    later = _run(_GENERATED, env)
    assert later["origin"] == "ahead of time" and not later["numba"]
    assert later["worst"] <= 1e-12
    # a damaged module is never loaded: deleted, and the default falls back
    modules[0].write_bytes(modules[0].read_bytes()[:1000])
    damaged = _run(_GENERATED, env)
    assert damaged["origin"] is None and not damaged["numba"]
    assert not modules[0].exists()


def test_auto_keeps_what_compiled_cannot_run_on_pinocchio(monkeypatch):
    from rrt_pin import compiled

    monkeypatch.delenv("RRT_PIN_BACKEND", raising=False)
    monkeypatch.setattr(compiled, "state_for", lambda *a, **k: (True, False, True))
    arm = chapter_arm()
    p = arm.params
    law = chapter_controller(p)
    t = time_grid(0.2, 0.01)
    q0 = (p.q10, p.q20, p.q30)
    assert backends.choose(arm, "simulate", None, 0.2, controllers=[law]).name == "compiled"

    def mine(t, q, qd):  # a user's own law: compiled cannot run Python
        return law.efforts(t, q, qd)

    choice = backends.choose(arm, "simulate", None, 0.2, controllers=[mine])
    assert choice.name == "pinocchio" and "not function" in choice.reason
    run = simulate(arm, mine, q0, None, t, estimate_error=False)
    assert run.backend == "pinocchio"
    # a method only Pinocchio runs keeps it there; the default method follows the backend
    assert backends.choose(arm, "simulate", "LSODA", 0.2, controllers=[law]).name == "pinocchio"
    monkeypatch.setitem(sys.modules, "numba", None)
    monkeypatch.setattr(backends, "_FOUND", set())
    without = backends.choose(arm, "simulate", None, 1e6, controllers=[law])
    assert without.name == "pinocchio" and "numba is not installed" in without.reason
    # the arm's inverse dynamics then goes to its numpy kernel: no import, the same efforts
    assert backends.choose(arm, "inverse", None, 1e9).name == "symbolic"


def test_the_cli_records_which_backend_ran_and_why(tmp_path):
    out = tmp_path / "run.json"
    for env, backend, why in (
        (_env(tmp_path / "cache"), "symbolic", "auto: the same efforts"),  # nothing built
        ({**_env(), "RRT_PIN_BACKEND": "pinocchio"}, "pinocchio", "RRT_PIN_BACKEND=pinocchio"),
    ):
        proc = subprocess.run(
            [sys.executable, "-m", "rrt_pin", "inverse", "--tf", "1", "--dt", "0.5",
             "--json", str(out)],
            capture_output=True, text=True, env=env, cwd=tmp_path,
        )  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        meta = json.loads(out.read_text())["metadata"]
        assert meta["backend"] == backend and meta["backend_reason"].startswith(why), meta


def test_a_loop_of_short_jobs_loads_the_compiled_code_once_its_start_up_pays(monkeypatch):
    """Rent or buy: a job too short to pay compiled's start-up runs on Pinocchio, but once
    this process's such jobs have cost that start-up more than compiled would have, auto
    takes compiled; a job of another robot or task counts its own."""
    from rrt_pin import compiled
    from rrt_pin.robot.robots import get
    from rrt_pin.simulate.control import pd_gravity_controller

    def scene(name):
        robot = get(name)
        return robot, pd_gravity_controller(robot, kp=100.0, kd=20.0, qf=np.zeros(robot.nv))

    monkeypatch.delenv("RRT_PIN_BACKEND", raising=False)
    monkeypatch.setattr(compiled, "state_for", lambda *a, **k: (False, False, True))
    robot, law = scene("ur5")
    fast = backends.BACKENDS["compiled"]
    work = 1.0  # simulated seconds: far too short for compiled's start-up alone
    first = backends.choose(robot, "simulate", None, work, controllers=[law])
    assert first.name == "pinocchio"
    sec = dict(first.estimates)
    running = backends.estimated_seconds(fast, "simulate", work, True, False, False, robot.nv)
    startup = sec["compiled"] - running
    saving = sec["pinocchio"] - running
    assert 0 < saving < startup  # the premise: one job does not pay the start-up
    calls = [first] + [backends.choose(robot, "simulate", None, work, controllers=[law])
                       for _ in range(int(startup / saving) + 2)]  # fmt: skip
    names = [c.name for c in calls]
    switch = names.index("compiled")
    assert set(names[:switch]) == {"pinocchio"} and set(names[switch:]) == {"compiled"}
    assert (switch - 1) * saving < startup <= switch * saving * (1 + 1e-12)
    assert "start-up pays" in calls[switch].reason
    # another robot, or another task, has spent nothing yet
    other, its_law = scene("panda")
    assert backends.choose(other, "simulate", None, work, controllers=[its_law]).name == "pinocchio"
    assert backends.choose(robot, "inverse", None, 100.0).name != "compiled"
