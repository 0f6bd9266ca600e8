"""Memory estimated before allocating: Pinocchio's Data per thread, thread counts, refusals.

A 1,000-joint chain once took the library to 23.4 GB and a machine-wide OOM kill
(one ``Data`` a thread, each with four nv×nv×nv tensors), ``simulate_batch(threads=
10**6)`` to 23 GB, and 1,000 threads under a 4 GB cap to libgomp's "Thread creation
failed". Anything here that could reach a limit runs in a child process under
``RLIMIT_AS`` (``resource.setrlimit``, as ``prlimit --as`` or ``ulimit -v`` do).
"""

from __future__ import annotations

import json
import os
import resource
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core import cpus, memory
from rrt_pin.core.errors import InputError, MemoryLimitError, RrtPinError
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from tests.bad_inputs import chain_urdf

ROOT = Path(__file__).resolve().parents[1]
GB = 1 << 30


def _capped(
    args: list[str], cap: int, cwd: Path, timeout: float = 120
) -> subprocess.CompletedProcess:
    """``python args...`` in a child whose address space is capped at ``cap`` bytes."""

    def limit() -> None:
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))

    env = dict(os.environ, PYTHONPATH=str(ROOT))
    return subprocess.run(
        [sys.executable, *args], capture_output=True, text=True, env=env, cwd=cwd,
        preexec_fn=limit, timeout=timeout, check=False,
    )  # fmt: skip


def _chain_files(tmp: Path, n: int) -> list[str]:
    """A chain URDF of ``n`` joints and the flags that give it a motion."""
    (tmp / f"chain{n}.urdf").write_text(chain_urdf(n))
    zeros = ",".join(["0"] * n)
    return ["--urdf", str(tmp / f"chain{n}.urdf"), "--q0", zeros, "--qf", zeros]


# --- the estimate --------------------------------------------------------------

MEASURE = r"""
import gc, json, sys
import pinocchio as pin
from tests.bad_inputs import chain_urdf
from rrt_pin import memory

def rss():
    with open("/proc/self/status") as fh:
        return next(int(l.split()[1]) * 1024 for l in fh if l.startswith("VmRSS"))

out = {}
for arg in sys.argv[1:]:
    n, copies = map(int, arg.split("x"))
    model = pin.buildModelFromXML(chain_urdf(n))
    gc.collect()
    before = rss()
    pool = pin.ModelPool(model, copies)  # many copies: the allocator's own growth averages out
    out[n] = [(rss() - before) / copies, memory.data_bytes(model)]
    del pool
print(json.dumps(out))
"""


def test_the_data_estimate_bounds_what_pinocchio_allocates(tmp_path):
    done = _capped(["-c", MEASURE, "3x400", "60x12", "150x3"], 4 * GB, tmp_path)
    assert done.returncode == 0, done.stderr
    for n, (measured, estimate) in json.loads(done.stdout).items():
        assert 0.95 * measured <= estimate <= 1.3 * measured, (n, measured, estimate)


def test_the_estimate_grows_as_the_cube_of_the_joints():
    import pinocchio as pin

    small, large = (memory.data_bytes(pin.buildModelFromXML(chain_urdf(n))) for n in (100, 400))
    assert 50 < large / small < 64  # n³ dominates: 64 in the limit
    assert memory.data_bytes(pin.buildModelFromXML(chain_urdf(1000))) > 30e9  # the 23.4 GB run


def test_limits_read_the_address_space_cap(tmp_path):
    code = "import json; from rrt_pin import memory; print(json.dumps({l.name: l.room for l in memory.limits()}))"
    done = _capped(["-c", code], 3 * GB, tmp_path)
    assert done.returncode == 0, done.stderr
    rooms = json.loads(done.stdout)
    assert 0 < rooms["ulimit -v (RLIMIT_AS)"] < 3 * GB
    assert "MemAvailable" in rooms


# --- refusals and cuts -------------------------------------------------------------


def test_a_data_that_does_not_fit_is_refused_before_it_is_made(monkeypatch):
    import pinocchio as pin

    model = pin.buildModelFromXML(chain_urdf(100))
    monkeypatch.setattr(memory, "limits", lambda: [memory.Limit(100 << 20, "MemAvailable")])
    q = np.zeros((4, 100))
    with pytest.raises(MemoryLimitError) as info:
        inverse_dynamics(Robot.from_model(model), q, q, q, num_threads=1)
    e = info.value
    assert isinstance(e, MemoryError) and isinstance(e, RrtPinError)
    assert e.need == memory.data_bytes(model) * 2 + 100 * 16_384 * 8 + memory.THREAD_RESIDENT
    assert e.limit == 100 << 20 and e.source == "MemAvailable"
    assert str(e).startswith("inverse dynamics of a 100-joint model needs 85.7 MB (36.2 MB a copy")
    assert "more than the 52.4 MB it may use: 105 MB left under MemAvailable" in str(e)


def test_threads_are_cut_to_what_fits_with_a_warning(monkeypatch, caplog):
    per = memory.Cost(100 << 20)
    monkeypatch.setattr(memory, "limits", lambda: [memory.Limit(2 << 30, "MemAvailable")])
    with caplog.at_level("INFO", logger="rrt_pin"):
        fit = memory.threads_that_fit(64, per, what="a test", name="threads")
    # usable: 2 GiB less the reserve (256 MiB, more than 10 % of it): 1879048192 bytes
    assert fit == 1879048192 // (100 << 20) == 17
    assert "threads=64 would need 6.71 GB" in caplog.text and "using 17 threads" in caplog.text
    assert memory.threads_that_fit(17, per, what="a test", name="threads") == 17  # fits: kept


@pytest.mark.parametrize("threads", [257, 1000, 10**6])
def test_more_threads_than_the_maximum_are_refused_by_name(threads):
    arm = chapter_arm()
    q0s = np.tile(arm.defaults.q0, (4, 1))
    with pytest.raises(InputError, match=rf"^threads={threads}: at most 256 threads"):
        from rrt_pin.simulate import simulate_batch

        simulate_batch(arm, None, q0s, None, [0.0, 0.1], threads=threads)
    q = np.zeros((4, 3))
    with pytest.raises(InputError, match=rf"^num_threads={threads}: at most 256 threads"):
        inverse_dynamics(arm, q, q, q, num_threads=threads)


def test_the_maximum_follows_large_machines(monkeypatch):
    monkeypatch.setattr(cpus.os, "cpu_count", lambda: 128)
    assert cpus.max_threads() == 512 and cpus.check_threads("threads", 512) == 512
    monkeypatch.setattr(cpus.os, "cpu_count", lambda: 2)
    assert cpus.max_threads() == cpus.MAX_THREADS == 256


# --- in child processes under a cap -------------------------------------------------


def test_the_cli_refuses_a_chain_too_large_for_the_cap_in_one_line(tmp_path):
    out = tmp_path / "out.csv"
    args = ["-m", "rrt_pin", "inverse", *_chain_files(tmp_path, 400), "--tf", "1"]
    done = _capped([*args, "--csv", str(out)], 2 * GB, tmp_path)
    assert done.returncode == 2, done.stderr
    err = done.stderr
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("rrt-pin: error: inverse dynamics of a 400-joint model needs 4.2"), err
    assert "left under ulimit -v (RLIMIT_AS)" in err
    assert not out.exists()


def test_a_controller_too_large_for_the_cap_is_refused_before_its_data(tmp_path):
    # The regulator's own Data (rrt_pin/simulate/control.py) is checked before it is made.
    ones = ",".join(["1"] * 300)
    args = ["-m", "rrt_pin", "simulate", *_chain_files(tmp_path, 300), "--kp", ones, "--kd", ones]
    done = _capped([*args, "--tf", "0.01", "--csv", str(tmp_path / "o.csv")], 1 * GB, tmp_path)
    assert done.returncode == 2, done.stderr
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr, done.stderr
    assert done.stderr.startswith("rrt-pin: error:"), done.stderr
    assert "a controller of a 300-joint model needs" in done.stderr, done.stderr
    assert not (tmp_path / "o.csv").exists()


def test_a_raw_memory_error_in_any_command_is_one_line(monkeypatch, capsys):
    from rrt_pin.cli.commands import inverse

    def exhausted(args):
        raise MemoryError("std::bad_alloc")

    monkeypatch.setattr(inverse, "run", exhausted)
    assert main(["inverse", "--csv", "never.csv"]) == 2
    out, err = capsys.readouterr()
    assert err.count("\n") == 1 and err.startswith("rrt-pin: error: out of memory (std::bad_alloc)")
    assert out == ""


BATCH = r"""
import json, logging, sys
import numpy as np
logging.basicConfig(level=logging.WARNING, format="%(message)s")
from rrt_pin.simulate.control import chapter_controller
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate import simulate_batch

p = Params()
q0s = np.tile(p.q0, (256, 1))
t = np.linspace(0.0, 0.5, 6)
runs = [simulate_batch(chapter_arm(p), chapter_controller(p), q0s, None, t, backend=sys.argv[1],
                       threads=k, estimate_error=False) for k in (256, 1)]
print(json.dumps({"threads": runs[0].threads, "same": bool(np.array_equal(runs[0].q, runs[1].q))}))
"""


@pytest.mark.parametrize("backend", ["pinocchio", "compiled"])
def test_256_threads_under_a_small_cap_are_cut_and_the_batch_runs(tmp_path, backend):
    if backend == "compiled":
        pytest.importorskip("numba")
    done = _capped(["-c", BATCH, backend], int(1.5 * GB), tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    got = json.loads(done.stdout)
    assert 1 <= got["threads"] < 256 and got["same"], got
    assert "threads=256 would need" in done.stderr and "left under ulimit -v" in done.stderr


def test_an_asked_thread_count_is_cut_to_the_pools_that_fit(tmp_path):
    code = r"""
import json, logging
import numpy as np, pinocchio as pin
logging.basicConfig(level=logging.WARNING, format="%(message)s")
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.robot.robot import Robot
from tests.bad_inputs import chain_urdf

model = Robot.from_model(pin.buildModelFromXML(chain_urdf(150)))  # a Data: ~115 MB
rng = np.random.default_rng(3)
q, qd, qdd = (rng.uniform(-1, 1, (64 * 256, 150)) for _ in range(3))
many = inverse_dynamics(model, q, qd, qdd, num_threads=64)  # 7.4 GB of copies asked
one = inverse_dynamics(model, q, qd, qdd, num_threads=1)
print(json.dumps(bool(np.array_equal(many, one))))
"""
    done = _capped(["-c", code], 2 * GB, tmp_path, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    assert json.loads(done.stdout) is True
    assert "num_threads=64 would need" in done.stderr and "using" in done.stderr
