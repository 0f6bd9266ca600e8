"""A damaged ahead-of-time module is never loaded: checked against its record, then rebuilt.

A truncated ``rrt_pin_dynamics_aot-*.so`` once killed every ``--backend compiled``
run with SIGBUS (exit 135, nothing said) until deleted by hand: the loader maps the
file and a page beyond its end faults. Every run here that could load a damaged
module does so in a child process, on a private copy of the cache.
"""

from __future__ import annotations

import csv
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("numba") is None, reason="numba not installed (rrt-pin[fast])"
)

from rrt_pin.compiled import _aot  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def fake_build(tmp_path, monkeypatch):
    """``_aot.build()`` into ``tmp_path/fp`` with a child that writes a stand-in module."""
    target = tmp_path / "fp" / "rrt_pin_dynamics_aot-0.so"
    monkeypatch.setattr(_aot, "module_path", lambda: target)
    monkeypatch.setattr(_aot, "_loaded", None)
    monkeypatch.setattr(_aot, "_failed", False)
    monkeypatch.setattr(_aot, "_noted", False)
    body = b"not an ELF file: importing it fails, never maps past its end\n" * 100

    def child(args, **kwargs):
        work = Path(args[-1])
        (
            work / ("rrt_pin_dynamics_aot" + _aot.importlib.machinery.EXTENSION_SUFFIXES[0])
        ).write_bytes(body)
        return subprocess.CompletedProcess(args, 0, "", "")

    monkeypatch.setattr(_aot.subprocess, "run", child)
    return target, body


def test_a_build_records_the_size_and_sha256_of_the_module(fake_build):
    target, body = fake_build
    assert _aot.build() and _aot.is_built()
    record = json.loads(target.with_name(target.name + ".json").read_text())
    assert record["size"] == len(body) and target.read_bytes() == body
    assert _aot.damage(target) is None


@pytest.mark.parametrize(
    "damage, words",
    [
        (lambda p: p.write_bytes(p.read_bytes()[:100]), "has 100 bytes, 6100 when built"),
        (lambda p: p.write_bytes(p.read_bytes() + b"x"), "has 6101 bytes, 6100 when built"),
        (lambda p: p.write_bytes(b"y" * p.stat().st_size), "contents changed since it was built"),
        (lambda p: p.with_name(p.name + ".json").unlink(), "no record of its size and SHA-256"),
        (lambda p: p.with_name(p.name + ".json").write_text("[1, 2]"), "no record"),
    ],
    ids=["truncated", "grown", "same size, other bytes", "record missing", "record garbage"],
)
def test_a_damaged_module_is_deleted_unread_and_said_once(fake_build, damage, words, caplog):
    target, _ = fake_build
    assert _aot.build()
    damage(target)
    with caplog.at_level("INFO", logger="rrt_pin"):
        assert _aot.load() is None
        assert _aot.load() is None  # once per process
    assert not target.exists() and not target.with_name(target.name + ".json").exists()
    notes = [r.getMessage() for r in caplog.records if "not loaded" in r.getMessage()]
    assert len(notes) == 1 and words in notes[0], notes
    assert not _aot.is_built()
    assert _aot.build() and _aot.is_built()  # the next build replaces it


def test_a_truncated_module_is_not_counted_as_built(fake_build):
    target, _ = fake_build
    assert _aot.build()
    with open(target, "r+b") as fh:
        fh.truncate(10)
    assert not _aot.is_built() and not target.exists()


# --- the CLI on a private copy of a real cache, in a child process --------------


@pytest.fixture(scope="module")
def real_cache():
    """The fingerprint folder of this checkout's compiled cache, with its module built."""
    from rrt_pin import compiled

    report = compiled.ensure_compiled()  # loads (or compiles) the JIT, builds the module once
    if report.cache_dir is None or not _aot.is_built():
        pytest.skip("no disk cache or no ahead-of-time module (no C compiler?)")
    return Path(report.cache_dir)


def _private_copy(real: Path, tmp_path: Path) -> tuple[Path, Path]:
    base = tmp_path / "cache"
    shutil.copytree(real, base / real.name, ignore=shutil.ignore_patterns(".aot-*"))
    (module,) = (base / real.name).glob("rrt_pin_dynamics_aot-*.so")
    return base, module


def _simulate(base: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env.update(RRT_PIN_CACHE_DIR=str(base), PYTHONPATH=str(ROOT))
    out = tmp_path / "run.csv"
    return subprocess.run(
        [sys.executable, "-m", "rrt_pin", "simulate", "-v", "--backend", "compiled", "--tf", "2",
         "--no-error-estimate", "--csv", str(out)],
        capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300, check=False,
    )  # fmt: skip


def _rows(path: Path) -> int:
    with open(path, newline="") as fh:
        return sum(1 for _ in csv.reader(fh)) - 1


@pytest.mark.parametrize("how", ["truncated", "garbage"])
def test_the_cli_runs_on_a_damaged_module_and_ignores_it(real_cache, tmp_path, how):
    base, module = _private_copy(real_cache, tmp_path)
    if how == "truncated":
        with open(module, "r+b") as fh:  # 100 kB of 0.8 MB: importing it faulted (SIGBUS)
            fh.truncate(100_000)
    else:
        size = module.stat().st_size
        module.write_bytes(b"\x7fELF" + b"\0" * (size - 4))  # same size, other bytes
    (module.parent / "AOT_FAILED").write_text("this test: no rebuild\n")
    done = _simulate(base, tmp_path)
    assert done.returncode == 0, (done.returncode, done.stderr)
    assert "not loaded" in done.stderr and "Traceback" not in done.stderr
    assert _rows(tmp_path / "run.csv") == 201  # --tf 2 at the default output step
    assert not module.exists()  # deleted unread; the JIT ran


@pytest.mark.slow
def test_a_truncated_module_is_rebuilt_by_the_next_run(real_cache, tmp_path):
    base, module = _private_copy(real_cache, tmp_path)
    with open(module, "r+b") as fh:
        fh.truncate(100_000)
    done = _simulate(base, tmp_path)
    assert done.returncode == 0, (done.returncode, done.stderr)
    assert "not loaded: it has 100000 bytes" in done.stderr
    assert module.stat().st_size > 100_000
    assert _aot.damage(module) is None  # rebuilt, with its record
    again = _simulate(base, tmp_path)
    assert again.returncode == 0 and "not loaded" not in again.stderr


# --- the generated RNEA kernels' numba files --------------------------------------------

_KERNEL = r"""
import json, sys
import numpy as np
import pinocchio as pin
from tests.bad_inputs import chain_urdf
from rrt_pin.compiled import rnea

model = pin.buildModelFromXML(chain_urdf(3))
kernel = rnea.kernel_for(model)
rng = np.random.default_rng(1)
q, qd, qdd = (rng.normal(size=(64, 3)) for _ in range(3))
tau, finite = rnea.inverse_dynamics(model, q, qd, qdd, num_threads=1)
data = model.createData()
ref = np.array([pin.rnea(model, data, *row) for row in zip(q, qd, qdd)])
print(json.dumps({"origin": kernel.origin, "err": float(np.max(np.abs(tau - ref))),
                  "finite": bool(finite)}))
"""


def _kernel_run(base: Path) -> dict:
    env = dict(os.environ, RRT_PIN_CACHE_DIR=str(base), PYTHONPATH=str(ROOT))
    done = subprocess.run(
        [sys.executable, "-c", _KERNEL], capture_output=True, text=True, env=env, cwd=ROOT,
        timeout=300, check=False,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout.strip().splitlines()[-1])


@pytest.mark.parametrize("damage", ["truncated", "altered", "unrecorded"])
def test_a_generated_kernels_damaged_numba_files_are_compiled_again(tmp_path, damage):
    first = _kernel_run(tmp_path)
    assert first["origin"] == "compiled" and first["err"] < 1e-12 and first["finite"]
    assert _kernel_run(tmp_path)["origin"] == "loaded"  # its files match their record
    data = sorted((tmp_path / "generated").rglob("*.nbc"))
    assert len(data) == 1
    blob = data[0].read_bytes()
    if damage == "truncated":
        data[0].write_bytes(blob[: len(blob) // 3])
    elif damage == "altered":  # same size, other bytes in the machine code's middle
        middle = len(blob) // 2
        data[0].write_bytes(blob[:middle] + bytes(b ^ 0xFF for b in blob[middle:middle + 64])
                            + blob[middle + 64:])  # fmt: skip
    else:
        for record in (tmp_path / "generated").glob("*.cache.json"):
            record.unlink()
    again = _kernel_run(tmp_path)
    assert again["origin"] == "compiled" and again["err"] < 1e-12 and again["finite"]
    assert _kernel_run(tmp_path)["origin"] == "loaded"
