"""A sweep's folder under faults: two writers, tampered chunks, links, special files, read-only."""

from __future__ import annotations

import json
import os
import shutil
import signal
import stat
import subprocess
import sys
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.errors import InputError
from rrt_pin.sweeps.run import SweepResult, sweep
from rrt_pin.sweeps.spec import load_spec
from rrt_pin.sweeps.store import Store

ROOT = Path(__file__).resolve().parents[1]

#: 6 variants in 3 chunks of 2: a second or so to compute in this process.
SPEC = {"sweep": {"tf": 1.0, "dt": 0.1, "chunk": 2}, "vary": {"m3": [30.0, 40.0, 50.0, 60.0, 70.0,
                                                                     80.0]}}  # fmt: skip
#: The same shape, another hash.
OTHER = {**SPEC, "vary": {"m3": [31.0, 41.0, 51.0, 61.0, 71.0, 81.0]}}
TOML = "[sweep]\ntf = 1.0\ndt = 0.1\nchunk = 2\n[vary]\nm3 = [30, 40, 50, 60, 70, 80]\n"
OTHER_TOML = TOML.replace("30, 40, 50, 60, 70, 80", "31, 41, 51, 61, 71, 81")


def _run(out: Path, spec: dict = SPEC, **kw) -> SweepResult:
    return sweep(spec, out, workers=1, progress=False, **kw)


def _rows(out: Path) -> dict[str, np.ndarray]:
    """Every row as the README reads them (every file in chunks/), sorted by variant."""
    table = pq.read_table(out / "chunks").sort_by("variant")
    return {n: table.column(n).to_numpy(zero_copy_only=False) for n in table.column_names}


def _snapshot(folder: Path) -> dict[str, tuple[str, bytes | str | None]]:
    """What is in ``folder`` (names, kinds, contents of regular files; links not followed)."""
    out = {}
    for p in sorted(folder.rglob("*")):
        st = p.lstat()
        if stat.S_ISLNK(st.st_mode):
            out[str(p.relative_to(folder))] = ("link", os.readlink(p))
        elif stat.S_ISREG(st.st_mode):
            out[str(p.relative_to(folder))] = ("file", p.read_bytes())
        else:
            out[str(p.relative_to(folder))] = (stat.filemode(st.st_mode), None)
    return out


@contextmanager
def _deadline(seconds: int):
    """Fail instead of hanging (a FIFO opened for writing would block forever)."""

    def fail(*_):
        raise TimeoutError(f"blocked for {seconds} s")

    old = signal.signal(signal.SIGALRM, fail)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture(scope="module")
def done(tmp_path_factory):
    """A finished sweep of SPEC, its rows, and a finished sweep of OTHER."""
    base = tmp_path_factory.mktemp("store")
    _run(base / "ref")
    _run(base / "other", OTHER)
    return base, _rows(base / "ref")


@pytest.fixture
def copy(done, tmp_path):
    """A copy of the finished sweep of SPEC to tamper with."""
    base, rows = done
    shutil.copytree(base / "ref", tmp_path / "out", symlinks=True)
    return tmp_path / "out", rows


def _same_rows(out: Path, ref: dict[str, np.ndarray]) -> None:
    rows = _rows(out)
    assert (rows["variant"] == np.arange(6)).all()
    for name, col in ref.items():
        np.testing.assert_array_equal(rows[name], col, err_msg=name)


# ---------------------------------------------------------------------- one writer
def test_a_held_lock_refuses_a_second_run_with_the_holders_pid(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(TOML)
    out = tmp_path / "out"
    holder = Store(out)
    manifest = {"spec_hash": "x", "chunk": 2, "chunks": 3, "variants": 6, "columns": {}}
    holder.start(manifest, resume=False)
    try:
        before = _snapshot(out)
        code = main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-progress"])
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1
        assert f"another sweep is writing into {str(out)!r} (pid {os.getpid()})" in err
        assert _snapshot(out) == before
        code = main(["sweep", str(spec), "--out", str(out), "--workers", "1", "--no-progress",
                     "--resume"])  # fmt: skip
        assert code == 2 and "another sweep is writing" in capsys.readouterr().err
    finally:
        holder.close()
    assert (out / "sweep.lock").read_text() == ""  # the pid goes with the lock


def test_a_lock_held_by_another_process_and_released_when_it_is_killed(tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(TOML)
    out = tmp_path / "out"
    code = (
        "import sys\nfrom rrt_pin.sweeps.store import Store\n"
        f"s = Store({str(out)!r})\n"
        "s.start({'spec_hash': 'x', 'chunk': 2, 'chunks': 3, 'variants': 6, 'columns': {}}, False)\n"
        "print('locked', flush=True)\nsys.stdin.read()\n"
    )
    holder = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdin=subprocess.PIPE,
                              stdout=subprocess.PIPE, text=True)  # fmt: skip
    try:
        assert holder.stdout.readline() == "locked\n"
        with pytest.raises(InputError, match=rf"\(pid {holder.pid}\)"):
            _run(out)
    finally:
        holder.kill()
        holder.wait()
    # SIGKILL released the lock; the holder's folder (a manifest, no chunk) is a sweep of
    # another spec now, so a new run is refused for that reason and not for the lock
    with pytest.raises(InputError, match="already holds a sweep"):
        _run(out)


def test_two_runs_started_together_into_one_folder(tmp_path):
    """The issue's race: both exited 0 and the folder held the other spec's chunks."""
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text(TOML)
    b.write_text(OTHER_TOML)
    out = tmp_path / "out"
    procs = [
        subprocess.Popen(
            [
                sys.executable,
                "-m",
                "rrt_pin",
                "sweep",
                str(s),
                "--out",
                str(out),
                "--workers",
                "1",
                "--no-progress",
            ],
            cwd=ROOT,
            text=True,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
        )  # fmt: skip
        for s in (a, b)
    ]
    results = [(*p.communicate(timeout=300), p.returncode) for p in procs]
    results = [(code, stdout, err) for stdout, err, code in results]
    codes = sorted(code for code, _, _ in results)
    assert codes == [0, 2], results
    winner = [s for s, (code, _, _) in zip((a, b), results, strict=True) if code == 0][0]
    loser_err = [err for code, _, err in results if code == 2][0]
    assert loser_err.count("\n") == 1 and "Traceback" not in loser_err
    assert "another sweep is writing into" in loser_err or "already holds a sweep" in loser_err
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["spec_hash"] == load_spec(winner).digest()
    rows = _rows(out)
    assert (rows["variant"] == np.arange(6)).all()
    assert list(rows["m3"]) == (SPEC if winner == a else OTHER)["vary"]["m3"]


# ---------------------------------------------------------------------- resume checks chunks
def _truncate(out, other):
    p = out / "chunks" / "chunk-000001.parquet"
    p.write_bytes(p.read_bytes()[:300])


def _garbage(out, other):
    (out / "chunks" / "chunk-000001.parquet").write_bytes(b"PAR1" + b"\x00" * 5000 + b"PAR1")


def _copy_of_another_chunk(out, other):
    shutil.copy(out / "chunks" / "chunk-000002.parquet", out / "chunks" / "chunk-000001.parquet")


def _another_specs_chunk(out, other):
    shutil.copy(other / "chunks" / "chunk-000001.parquet", out / "chunks" / "chunk-000001.parquet")


def _missing(out, other):
    (out / "chunks" / "chunk-000001.parquet").unlink()


def _symlink_outside(out, other):
    p = out / "chunks" / "chunk-000001.parquet"
    p.unlink()
    p.symlink_to(other / "chunks" / "chunk-000001.parquet")


def _fifo(out, other):
    p = out / "chunks" / "chunk-000001.parquet"
    p.unlink()
    os.mkfifo(p)


def _device_node(out, other):
    p = out / "chunks" / "chunk-000001.parquet"
    p.unlink()
    try:
        os.mknod(p, stat.S_IFCHR | 0o600, os.makedev(1, 3))  # like /dev/null, made here
    except PermissionError:
        pytest.skip("mknod is not permitted here")


TAMPERS = [_truncate, _garbage, _copy_of_another_chunk, _another_specs_chunk, _missing,
           _symlink_outside, _fifo, _device_node]  # fmt: skip
WHY = {
    "_truncate": "is not readable Parquet",
    "_garbage": "is not readable Parquet",
    "_copy_of_another_chunk": "does not hold variants 2 to 3 in order",
    "_another_specs_chunk": "belongs to another spec",
    "_missing": "is missing",
    "_symlink_outside": "is a symbolic link (not followed)",
    "_fifo": "is a FIFO, not a regular file",
    "_device_node": "is a device node, not a regular file",
}


@pytest.mark.parametrize("tamper", TAMPERS, ids=[t.__name__[1:] for t in TAMPERS])
def test_resume_recomputes_a_listed_chunk_that_fails_its_check(copy, done, tamper, caplog):
    out, ref = copy
    other = done[0] / "other"
    outside = _snapshot(other)
    tamper(out, other)
    with _deadline(60), caplog.at_level("INFO", logger="rrt_pin"):
        result = _run(out, resume=True)
    assert result.computed == 1 and result.computed_variants == 2
    assert WHY[tamper.__name__] in caplog.text and "chunk 1" in caplog.text
    warnings = [r for r in caplog.records if r.levelname == "WARNING"]
    assert len(warnings) == 1 and "recomputed" in warnings[0].getMessage()
    assert stat.S_ISREG((out / "chunks" / "chunk-000001.parquet").lstat().st_mode)
    _same_rows(out, ref)
    assert _snapshot(other) == outside  # a link's target is never written
    assert json.loads((out / "manifest.json").read_text())["done"] == [0, 1, 2]


def test_resume_keeps_chunks_that_pass(copy):
    out, ref = copy
    before = {p.name: p.stat().st_mtime_ns for p in (out / "chunks").iterdir()}
    result = _run(out, resume=True)
    assert result.computed == 0 and result.computed_variants == 0
    assert {p.name: p.stat().st_mtime_ns for p in (out / "chunks").iterdir()} == before
    assert "nothing to compute" in result.summary()


def test_resume_refuses_a_stray_file_in_chunks(copy):
    out, ref = copy
    shutil.copy(out / "chunks" / "chunk-000000.parquet", out / "chunks" / "copy.parquet")
    (out / "chunks" / "chunk-000099.parquet").write_bytes(b"")
    before = _snapshot(out)
    with pytest.raises(InputError, match=r"chunk-000099.parquet' is not a chunk of this sweep"):
        _run(out, resume=True)
    (out / "chunks" / "chunk-000099.parquet").unlink()
    with pytest.raises(InputError, match=r"copy.parquet' is not a chunk of this sweep") as info:
        _run(out, resume=True)
    assert "move it out of the folder" in str(info.value) and "\n" not in str(info.value)
    del before["chunks/chunk-000099.parquet"]
    assert _snapshot(out) == before


def test_the_library_reads_only_listed_chunks(copy):
    out, ref = copy
    shutil.copy(out / "chunks" / "chunk-000000.parquet", out / "chunks" / "stray.parquet")
    table = Store(out).read()
    assert table.num_rows == 6 and table.column("variant").to_pylist() == list(range(6))


def test_resume_removes_an_interrupted_runs_temporary_files(copy):
    out, ref = copy
    temp = out / "chunks" / ".chunk-000001.parquet.0123abcd.tmp"
    temp.write_bytes(b"half a chunk")
    mine = out / "chunks" / ".notes"  # hidden from Parquet readers and not ours: kept
    mine.write_text("mine")
    _run(out, resume=True)
    assert not temp.exists() and mine.read_text() == "mine"
    _same_rows(out, ref)


def test_resume_replaces_what_sits_at_an_unlisted_chunk_path(copy, done):
    """A chunk not listed as done is recomputed; a link or FIFO at its path is replaced."""
    out, ref = copy
    other = done[0] / "other"
    outside = _snapshot(other)
    manifest = json.loads((out / "manifest.json").read_text())
    (out / "manifest.json").write_text(json.dumps({**manifest, "done": [0]}))
    (out / "chunks" / "chunk-000001.parquet").unlink()
    (out / "chunks" / "chunk-000001.parquet").symlink_to(other / "chunks" / "chunk-000001.parquet")
    (out / "chunks" / "chunk-000002.parquet").unlink()
    os.mkfifo(out / "chunks" / "chunk-000002.parquet")
    with _deadline(60):
        result = _run(out, resume=True)
    assert result.computed == 2
    for k in (1, 2):
        assert stat.S_ISREG((out / "chunks" / f"chunk-00000{k}.parquet").lstat().st_mode)
    _same_rows(out, ref)
    assert _snapshot(other) == outside


def test_resume_refuses_a_folder_at_a_chunk_path(copy):
    out, ref = copy
    (out / "chunks" / "chunk-000001.parquet").unlink()
    (out / "chunks" / "chunk-000001.parquet").mkdir()
    with pytest.raises(InputError, match="chunk-000001.parquet' is a folder, not a chunk"):
        _run(out, resume=True)


# ---------------------------------------------------------------------- a new sweep adopts nothing
def test_a_new_sweep_refuses_a_folder_with_stale_chunks(done, tmp_path):
    base, _ = done
    out = tmp_path / "out"
    shutil.copytree(base / "other" / "chunks", out / "chunks")
    before = _snapshot(out)
    with pytest.raises(InputError, match=r"is not empty and holds no sweep") as info:
        _run(out)
    assert "chunks/chunk-000000.parquet" in str(info.value)
    assert _snapshot(out) == before
    with pytest.raises(InputError, match=r"is not empty and holds no sweep"):
        _run(out, resume=True)  # nothing to resume either
    assert _snapshot(out) == before


def test_a_new_sweep_takes_an_empty_folder_or_an_unstarted_one(tmp_path, done):
    _, ref = done
    empty = tmp_path / "empty"
    empty.mkdir()
    _run(empty)
    _same_rows(empty, ref)
    unstarted = tmp_path / "unstarted"  # what a run refused by its scheduler leaves
    (unstarted / "chunks").mkdir(parents=True)
    (unstarted / "sweep.lock").write_text("")
    (unstarted / ".manifest.json.0123abcd.tmp").write_text("{")
    _run(unstarted)
    _same_rows(unstarted, ref)
    assert not (unstarted / ".manifest.json.0123abcd.tmp").exists()


def test_a_symlink_at_the_manifest_is_never_followed(tmp_path, done):
    target = tmp_path / "precious.json"
    target.write_text('{"mine": 1}')
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").symlink_to(target)
    for resume in (False, True):
        with pytest.raises(InputError, match="manifest.json': it is a symbolic link"):
            _run(out, resume=resume)
    assert target.read_text() == '{"mine": 1}'
    assert os.listdir(out) == ["manifest.json"]


def test_a_fifo_at_the_manifest_is_refused(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    os.mkfifo(out / "manifest.json")
    with _deadline(30), pytest.raises(InputError, match="is a FIFO, not a regular file"):
        _run(out, resume=True)


def test_what_appears_during_a_run_is_replaced_or_refused_never_written_through(tmp_path):
    """A link put at the manifest mid-run is replaced; one at a chunk's path stops the run."""
    target = tmp_path / "precious"
    target.write_bytes(b"mine")
    out = tmp_path / "out"

    def plant(k, chunk):
        if k == 0:
            (out / "manifest.json").unlink()
            (out / "manifest.json").symlink_to(target)
            (out / "chunks" / "chunk-000001.parquet").symlink_to(target)

    with pytest.raises(InputError, match="chunk-000001.parquet' appeared while this sweep"):
        _run(out, on_chunk=plant)
    assert target.read_bytes() == b"mine"
    assert os.readlink(out / "chunks" / "chunk-000001.parquet") == str(target)

    fifo_out = tmp_path / "fifo"

    def fifo(k, chunk):
        if k == 0:
            os.mkfifo(fifo_out / "chunks" / "chunk-000001.parquet")

    with _deadline(60), pytest.raises(InputError, match="appeared while this sweep"):
        sweep(SPEC, fifo_out, workers=1, progress=False, on_chunk=fifo)
    assert json.loads((fifo_out / "manifest.json").read_text())["done"] == [0]


def test_a_link_planted_at_the_manifest_mid_run_is_replaced(tmp_path, done):
    _, ref = done
    target = tmp_path / "precious"
    target.write_bytes(b"mine")
    out = tmp_path / "out"

    def plant(k, chunk):
        if k == 1:
            (out / "manifest.json").unlink()
            (out / "manifest.json").symlink_to(target)

    _run(out, on_chunk=plant)
    assert target.read_bytes() == b"mine"
    assert stat.S_ISREG((out / "manifest.json").lstat().st_mode)
    _same_rows(out, ref)


# ---------------------------------------------------------------------- OS errors, one line
@pytest.fixture
def read_only(tmp_path):
    """A tmpfs holding an empty folder and a finished-looking sweep folder, remounted read-only."""
    where = tmp_path / "ro"
    where.mkdir()
    proc = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=1m,mode=0755", "tmpfs", str(where)],
                          capture_output=True, text=True)  # fmt: skip
    if proc.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {proc.stderr.strip()}")
    try:
        (where / "empty").mkdir()
        proc = subprocess.run(["mount", "-o", "remount,ro", str(where)], capture_output=True,
                              text=True)  # fmt: skip
        if proc.returncode != 0:
            pytest.skip(f"cannot remount read-only: {proc.stderr.strip()}")
        yield where
    finally:
        if subprocess.run(["umount", str(where)], capture_output=True).returncode != 0:
            subprocess.run(["umount", "-l", str(where)], capture_output=True)


@pytest.mark.parametrize(
    "name, words",
    [
        ("new", "cannot create the sweep folder '{ro}/new': read-only file system"),
        ("empty", "cannot write into the sweep folder '{ro}/empty': read-only file system"),
    ],
)
def test_a_read_only_folder_is_one_line(read_only, tmp_path, capsys, name, words):
    spec = tmp_path / "s.toml"
    spec.write_text(TOML)
    for resume in ([], ["--resume"]):
        code = main(["sweep", str(spec), "--out", str(read_only / name), "--workers", "1",
                     "--no-progress", *resume])  # fmt: skip
        err = capsys.readouterr().err
        assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
        assert words.format(ro=read_only) in err


def test_library_out_must_be_a_path(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    for out, words in ((None, "not NoneType"), (["a"], "not list"), ("", "must not be empty"),
                       ("  ", "must not be empty")):  # fmt: skip
        with pytest.raises(InputError, match=words):
            _run(out)
    assert os.listdir(tmp_path) == []


@pytest.mark.parametrize(
    "text, words",
    [
        ("[]", "a JSON list, not an object"),
        ("3", "a JSON int, not an object"),
        ('{"spec_hash": "x", "chunk": 2}', "it has no 'done'"),
        ('{"spec_hash": 3, "chunk": 2, "done": []}', "'spec_hash' must be a string, not int"),
        ('{"spec_hash": "x", "chunk": true, "done": []}', "'chunk' must be an integer, not bool"),
        ('{"spec_hash": "x", "chunk": 0, "done": []}', "'chunk' is 0, not >= 1"),
        ('{"spec_hash": "x", "chunk": 2, "done": "all"}', "'done' must be a list, not str"),
        ('{"spec_hash": "x", "chunk": 2, "done": [-1]}', "'done' lists -1"),
        ('{"spec_hash": "x", "chunk": 2, "done": [null]}', "'done' lists None"),
        ("{", "not JSON"),
        ("[" * 100_000, "not JSON"),
        ('"\udcff"', "not JSON"),
    ],
)
def test_a_manifest_of_the_wrong_shape_is_one_line(tmp_path, text, words):
    out = tmp_path / "out"
    out.mkdir()
    (out / "manifest.json").write_text(text, errors="surrogateescape")
    for resume in (False, True):
        with pytest.raises(InputError, match="is not a sweep's manifest") as info:
            _run(out, resume=resume)
        assert words in str(info.value) and "\n" not in str(info.value)


# ---------------------------------------------------------------------- summaries
def test_the_rate_after_resume_counts_only_this_runs_variants(copy):
    out, _ = copy
    (out / "chunks" / "chunk-000002.parquet").unlink()
    result = _run(out, resume=True)
    assert result.computed == 1 and result.computed_variants == 2
    text = SweepResult(out, 3000, 15, 3, 2.0, computed_variants=600).summary()
    assert "computed 3 of 15 chunks (600 variants) in 2" in text
    assert "(300 variants/s in this run)" in text
    assert "(1,500 variants/s)" in SweepResult(out, 3000, 15, 15, 2.0, 3000).summary()


def test_an_inverse_sweep_prints_no_settling_count(tmp_path):
    spec = {"sweep": {"task": "inverse", "tf": 1.0, "dt": 0.1}, "vary": {"m3": [30.0, 40.0]}}
    result = _run(tmp_path / "inv", spec)
    assert result.settled is None and "settled" not in result.summary()


def test_a_finished_sweep_leaves_no_pid_and_no_temporary_file(done):
    base, _ = done
    assert (base / "ref" / "sweep.lock").read_text() == ""
    names = sorted(p.name for p in (base / "ref").rglob("*"))
    assert names == sorted(["sweep.lock", "manifest.json", "chunks", "chunk-000000.parquet",
                            "chunk-000001.parquet", "chunk-000002.parquet"])  # fmt: skip


def test_the_plot_in_the_folder_replaces_a_link_never_writes_through_it(copy, tmp_path):
    from rrt_pin.sweeps.plot import plot_metric

    out, _ = copy
    target = tmp_path / "precious"
    target.write_bytes(b"mine")
    (out / "final_error_q1.png").symlink_to(target)
    path = plot_metric(out, "final_error_q1")
    assert path == out / "final_error_q1.png" and target.read_bytes() == b"mine"
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and not path.is_symlink()


def test_workers_takes_numpy_integers_and_refuses_the_rest(tmp_path):
    result = sweep(SPEC, tmp_path / "np", workers=np.int64(1), progress=False)
    assert result.computed == 3
    for workers, words in ((np.float64(2.0), "not float64"), (True, "not bool"),
                           ("2", "not str"), (np.int32(0), "workers=0 must be")):  # fmt: skip
        with pytest.raises(InputError, match=words) as info:
            sweep(SPEC, tmp_path / "refused", workers=workers, progress=False)
        assert "np." not in str(info.value)
    assert not (tmp_path / "refused").exists()


def test_a_file_system_without_hard_links_still_takes_a_sweep(tmp_path, done, monkeypatch):
    """FAT and some FUSE file systems refuse ``link``: a rename after a check takes its place."""
    import errno

    _, ref = done

    def no_links(*args, **kwargs):
        raise PermissionError(errno.EPERM, "Operation not permitted")

    monkeypatch.setattr(os, "link", no_links)
    out = tmp_path / "out"
    _run(out)
    _same_rows(out, ref)
    assert not [p for p in out.rglob(".*")]  # no temporary file left
    target = tmp_path / "precious"
    target.write_bytes(b"mine")

    def plant(k, chunk):
        if k == 0:
            (tmp_path / "again" / "chunks" / "chunk-000001.parquet").symlink_to(target)

    with pytest.raises(InputError, match="appeared while this sweep"):
        _run(tmp_path / "again", on_chunk=plant)
    assert target.read_bytes() == b"mine"
