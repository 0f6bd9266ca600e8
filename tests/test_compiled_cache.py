"""The compiled backend's disk cache: damaged files, a full or read-only disk, a fresh clone.

Every scenario runs the backend in a subprocess (the parent's loaded machine code
must not interfere) with its own cache directory, and checks that it succeeds,
computes the right efforts, says at most one line on stderr, and that
``is_compiled()`` before the run agreed with what the run then paid.

Full compilations (30–50 s each) are few: one to fill the shared cache, one
after every file is damaged, one on a full disk, one in a fresh clone; the
other scenarios damage a single function's files or load from a copy. They run
side by side (:func:`scenarios`): the full disk's beside the shared cache's, then
the damaged cache's beside the fresh clone's, each test waiting for its own.
"""

from __future__ import annotations

import contextlib
import importlib.util
import json
import os
import shutil
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

pytestmark = pytest.mark.skipif(
    importlib.util.find_spec("numba") is None, reason="numba not installed (rrt-pin[fast])"
)

REPO = Path(__file__).resolve().parents[1]
TIGHT = 1e-12
#: A cheap function of the backend (about 0.5 s to compile), damaged alone.
SMALL = "mass_matrix_batch"

# Uses the backend like the CLI (logging configured as in rrt_pin.cli.app), or like a
# library (no logging: the warning goes through `warnings`), and prints a JSON summary.
PROBE = r"""
import json, logging, sys
if sys.argv[1] == "cli":
    logging.basicConfig(level=logging.WARNING, format="rrt-pin: %(message)s", stream=sys.stderr)
import numpy as np
import rrt_pin
import rrt_pin.compiled as compiled
from rrt_pin.dynamics.inverse import inverse_dynamics
from rrt_pin.robot.params import Params
from rrt_pin.robot.robots import chapter_arm

before = compiled.is_compiled()
report = compiled.ensure_compiled()
rng = np.random.default_rng(13)
q = np.column_stack([rng.uniform(-3, 3, 7), rng.uniform(-3, 3, 7), rng.uniform(-0.5, 1, 7)])
qd, qdd = rng.normal(0, 2, (7, 3)), rng.normal(0, 5, (7, 3))
params = Params()
got = compiled.inverse_dynamics(q, qd, qdd, params)
ref = inverse_dynamics(chapter_arm(params), q, qd, qdd, backend="pinocchio")
error = float((np.abs(got - ref).max(axis=1) / np.abs(ref).max(axis=1)).max())
print(json.dumps({
    "package": rrt_pin.__file__,
    "before": before,
    "from_cache": report.from_cache,
    "cache_dir": None if report.cache_dir is None else str(report.cache_dir),
    "origins": report.origins,
    "error": error,
}))
"""


def _env(cache: Path, root: Path, **extra: str) -> dict[str, str]:
    env = {k: v for k, v in os.environ.items() if k not in ("NUMBA_CACHE_DIR", "PYTHONPATH")}
    env.update(RRT_PIN_CACHE_DIR=str(cache), PYTHONPATH=str(root), **extra)
    env.setdefault("XDG_CACHE_HOME", str(cache.parent / "xdg-unused"))
    return env


class Probe:
    """The backend run from the package under ``root`` with cache base ``cache``, in a child.

    Started at once (a compilation from scratch runs beside the others);
    :meth:`result` waits for it.
    """

    def __init__(self, cache: Path, root: Path = REPO, mode: str = "cli", **extra: str) -> None:
        self.root = root
        self.process = subprocess.Popen(
            [sys.executable, "-c", PROBE, mode],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            env=_env(cache, root, **extra),
            cwd=cache.parent,  # not the repository: '' on sys.path must not shadow `root`
        )

    def result(self) -> tuple[dict, list[str]]:
        """The probe's summary and its stderr lines (after checking it succeeded,
        imported the package from ``root`` and matched Pinocchio)."""
        stdout, stderr = self.process.communicate(timeout=600)
        assert self.process.returncode == 0, stderr
        assert "Traceback" not in stderr, stderr
        data = json.loads(stdout)
        assert Path(data["package"]).is_relative_to(self.root), data["package"]
        assert data["error"] <= TIGHT
        return data, stderr.strip().splitlines()


def probe(
    cache: Path, root: Path = REPO, mode: str = "cli", **extra: str
) -> tuple[dict, list[str]]:
    """Run the backend from the package under ``root`` with cache base ``cache`` and wait."""
    return Probe(cache, root, mode, **extra).result()


def _fingerprint_dir(base: Path) -> Path:
    (path,) = [p for p in base.iterdir() if p.is_dir()]
    return path


def _cache_files(path: Path) -> list[Path]:
    return sorted(p for p in path.rglob("*") if p.suffix in (".nbi", ".nbc"))


def _copy_cache(populated: Path, tmp_path: Path, name: str = "cache") -> Path:
    dest = tmp_path / name
    shutil.copytree(populated, dest)
    return _fingerprint_dir(dest)


def _assert_one_warning(lines: list[str], directory: Path) -> None:
    assert len(lines) == 1, lines
    assert "compiled-code cache" in lines[0] and str(directory) in lines[0], lines


@pytest.fixture(scope="module")
def scenarios(tmp_path_factory) -> Iterator[dict]:
    """The shared cache, and the three other compilations from scratch started beside it.

    ``populated``: a cache base filled by one compilation of the repository's
    sources (the full disk's compilation runs meanwhile); then ``damaged`` (a copy
    of it with every file truncated or garbage) and ``clone`` (a copy used by a
    fresh clone of the sources) start, and the fixture returns: each test waits
    for its own probe.
    """
    root = tmp_path_factory.mktemp("scenarios")
    started: dict = {}
    with contextlib.ExitStack() as stack:
        try:
            full = stack.enter_context(tmpfs(root / "full", "size=16k"))
        except _NoTmpfs as e:
            started["full"] = e
        else:
            started["full"] = (full, Probe(full))
        base = root / "populated" / "cache"
        base.parent.mkdir()
        data, lines = probe(base)
        assert data["before"] is False and data["from_cache"] is False
        assert set(data["origins"].values()) == {"compiled"}
        assert lines == []
        started["populated"] = base
        damaged = _copy_cache(base, root / "damaged")
        _damage_every_file(damaged)
        started["damaged"] = (damaged, Probe(damaged.parent))
        clone = root / "clone"
        shutil.copytree(
            REPO / "rrt_pin", clone / "rrt_pin", ignore=shutil.ignore_patterns("__pycache__")
        )
        shutil.copytree(base, root / "clone-cache")
        started["clone"] = (clone, root / "clone-cache", Probe(root / "clone-cache", root=clone))
        try:
            yield started
        finally:
            for value in started.values():
                if isinstance(value, tuple) and value[-1].process.poll() is None:
                    value[-1].process.kill()
                    value[-1].process.communicate()


@pytest.fixture(scope="module")
def populated(scenarios) -> Path:
    """A cache base filled by one compilation of the repository's sources."""
    return scenarios["populated"]


class _NoTmpfs(Exception):
    """Mounting a tmpfs is not permitted here."""


@contextlib.contextmanager
def tmpfs(path: Path, options: str) -> Iterator[Path]:
    """Mount a tmpfs on ``path`` (raises _NoTmpfs where mounting is not permitted)."""
    path.mkdir(parents=True, exist_ok=True)
    try:
        subprocess.run(
            ["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(path)],
            check=True,
            capture_output=True,
        )
    except (OSError, subprocess.CalledProcessError) as e:
        raise _NoTmpfs(f"cannot mount a tmpfs: {e}") from e
    try:
        yield path
    finally:
        subprocess.run(["umount", "-l", str(path)], check=False, capture_output=True)


# --- damaged files ------------------------------------------------------------------------
def _damage_every_file(path: Path) -> None:
    """Truncate or overwrite every cache file of ``path`` (and drop its record)."""
    (path / "READY.json").unlink()  # numba itself meets the damage (no record to check)
    files = _cache_files(path)
    assert len(files) >= 2 * 10
    for i, file in enumerate(files):
        data = file.read_bytes()
        if (i // 2) % 2 == 0:  # each function's index and data files alike
            file.write_bytes(data[: len(data) // 2])
        else:
            file.write_bytes(b"\x80\x05garbage" * (len(data) // 9 + 1))


def test_every_file_truncated_or_garbage_is_discarded_and_recompiled(scenarios):
    path, started = scenarios["damaged"]
    data, lines = started.result()
    assert data["before"] is False
    assert set(data["origins"].values()) == {"compiled"}
    assert data["cache_dir"] == str(path)
    _assert_one_warning(lines, path)
    # Repaired: the next process loads everything, silently, and was told so.
    data, lines = probe(path.parent)
    assert data["before"] is True and data["from_cache"] is True
    assert lines == []


@pytest.mark.parametrize("record", [True, False], ids=["recorded", "unrecorded"])
def test_one_damaged_data_file_is_recompiled_alone(populated, tmp_path, record):
    path = _copy_cache(populated, tmp_path)
    if not record:
        (path / "READY.json").unlink()
    (data_file,) = [f for f in _cache_files(path) if f".{SMALL}-" in f.name and f.suffix == ".nbc"]
    data = data_file.read_bytes()
    if record:  # same size, bytes flipped in the middle: only the recorded SHA-256 tells
        middle = len(data) // 2
        data_file.write_bytes(data[:middle] + bytes(b ^ 0xFF for b in data[middle:]))
    else:  # the index is intact and points to a truncated data file
        data_file.write_bytes(data[: len(data) // 3])
    data, lines = probe(path.parent)
    assert data["before"] is False  # honest: a compilation was coming
    assert data["origins"][SMALL] == "compiled"
    assert {o for name, o in data["origins"].items() if name != SMALL} == {"loaded"}
    _assert_one_warning(lines, path)
    data, lines = probe(path.parent)
    assert data["before"] is True and data["from_cache"] is True and lines == []


# --- full and read-only disks -------------------------------------------------------------
def test_full_disk_compiles_in_memory_with_one_warning(scenarios, monkeypatch):
    if isinstance(scenarios["full"], _NoTmpfs):
        pytest.skip(str(scenarios["full"]))
    full, started = scenarios["full"]
    data, lines = started.result()
    assert data["before"] is False and data["from_cache"] is False
    assert "memory" in data["origins"].values()
    assert set(data["origins"].values()) <= {"memory", "compiled"}
    _assert_one_warning(lines, full)
    assert "No space left on device" in lines[0]
    # Nothing is marked complete there, so the next run is not promised a cheap start.
    from rrt_pin.compiled import _cache

    monkeypatch.setenv("RRT_PIN_CACHE_DIR", str(full))
    _cache.cache_dir.cache_clear()
    try:
        assert not _cache.is_cached()
    finally:
        _cache.cache_dir.cache_clear()
    # numba never fell back to caching next to the sources.
    assert not list((REPO / "rrt_pin").rglob("*.nbi"))


@pytest.mark.parametrize("mode", ["cli", "library"])
def test_read_only_cache_dir_falls_back_with_one_warning(populated, tmp_path, mode):
    fallback = tmp_path / "xdg"
    shutil.copytree(populated, fallback / "rrt_pin" / "numba")
    with contextlib.ExitStack() as stack:
        try:
            ro = stack.enter_context(tmpfs(tmp_path / "ro", "ro,size=1m"))
        except _NoTmpfs as e:
            pytest.skip(str(e))
        data, lines = probe(ro, mode=mode, XDG_CACHE_HOME=str(fallback))
    assert data["before"] is True and data["from_cache"] is True
    assert Path(data["cache_dir"]).parent == fallback / "rrt_pin" / "numba"
    assert len(lines) == 1 and f"cannot write to {ro}" in lines[0], lines
    if mode == "library":
        assert "CacheWarning" in lines[0]


# --- is_compiled() in a fresh clone --------------------------------------------------------
def test_is_compiled_in_a_fresh_clone_answers_what_numba_pays(scenarios):
    clone, cache, started = scenarios["clone"]
    # Same contents, cache filled from the repository: numba recompiles here, and says so.
    data, lines = started.result()
    assert data["before"] is False
    assert data["from_cache"] is False and set(data["origins"].values()) == {"compiled"}
    assert lines == []
    data, _ = probe(cache, root=clone)
    assert data["before"] is True and data["from_cache"] is True
    # The repository's own entries are still there (another location, not superseded).
    data, _ = probe(cache, root=REPO)
    assert data["before"] is True and data["from_cache"] is True
    # Touched, not changed: whatever numba's stamp (mtime before 0.68, contents since),
    # the promise and the cost agree.
    for file in (clone / "rrt_pin").rglob("*.py"):
        st = file.stat()
        os.utime(file, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    data, _ = probe(cache, root=clone)
    assert data["before"] is data["from_cache"]


# --- the record, without numba -------------------------------------------------------------
@pytest.fixture
def private_cache(tmp_path, monkeypatch):
    from rrt_pin.compiled import _cache

    monkeypatch.setenv("RRT_PIN_CACHE_DIR", str(tmp_path / "base"))
    monkeypatch.delenv("NUMBA_CACHE_DIR", raising=False)
    _cache.cache_dir.cache_clear()
    yield _cache
    _cache.cache_dir.cache_clear()


def test_is_cached_requires_every_recorded_file_unchanged(private_cache):
    _cache = private_cache
    path = _cache.cache_dir()
    entry = path / "sub" / "f-1.py311.1.nbc"
    entry.parent.mkdir()
    entry.write_bytes(b"machine code")
    _cache.mark_ready(path, {"signatures": {}})
    record = json.loads((path / "READY.json").read_text())
    assert record["files"] == {"sub/f-1.py311.1.nbc": _cache._sha256(entry)}
    assert _cache.is_cached()
    entry.write_bytes(b"machine kode")  # same size
    assert not _cache.is_cached()
    assert _cache.discard_damaged(path) == [entry]
    assert not entry.exists() and not (path / "READY.json").exists()
    assert _cache.discard_damaged(path) == []
    (path / "READY.json").write_text("{truncated")
    assert not _cache.is_cached()


def test_fingerprint_covers_the_sources_location(private_cache):
    _cache = private_cache
    described = _cache._fingerprint_inputs()[1]
    assert set(described["sources"]) == set(_cache.JIT_MODULES)
    for module, entry in described["sources"].items():
        assert Path(entry["path"]).is_absolute() and Path(entry["path"]).is_file(), module
    assert described["toolchain"]["cpu"]


def test_superseded_cache_dirs_are_pruned(private_cache):
    _cache = private_cache
    path = _cache.cache_dir()
    _cache.mark_ready(path, {"signatures": {}})
    record = json.loads((path / "READY.json").read_text())

    def sibling(name: str, **changes) -> Path:
        other = path.parent / name
        other.mkdir()
        (other / "READY.json").write_text(json.dumps({**record, "fingerprint": name, **changes}))
        return other

    old = sibling("0" * 20)  # same checkout and toolchain, older sources
    elsewhere = sibling("1" * 20, location=["/another/checkout/kernel.py"])
    toolchain = {**record["inputs"]["toolchain"], "numba": "0.0"}
    other_numba = sibling("2" * 20, inputs={**record["inputs"], "toolchain": toolchain})
    unrecorded = path.parent / ("3" * 20)
    unrecorded.mkdir()
    assert _cache.prune_superseded(path) == [old]
    assert not old.exists()
    assert path.exists() and elsewhere.exists() and other_numba.exists() and unrecorded.exists()
