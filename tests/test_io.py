"""The output layer never destroys nor silently corrupts what is at an output path."""

from __future__ import annotations

import errno
import os
import pickle
import shutil
import stat
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

import pytest

import rrt_pin.io.files as rio
from rrt_pin.cli.commands._common import check_writable
from rrt_pin.core.errors import InputError
from rrt_pin.io.files import (
    OutputError,
    atomic_write,
    atomic_write_bytes,
    atomic_write_text,
    check_output,
    check_outputs,
    write_outputs,
)


@pytest.fixture(params=[True, False], ids=["unnamed-temp", "named-temp"])
def temp_kind(request, monkeypatch):
    """Run a test with O_TMPFILE temporary files and with named ones."""
    if request.param and not rio._USE_TMPFILE:
        pytest.skip("no O_TMPFILE here")
    monkeypatch.setattr(rio, "_USE_TMPFILE", request.param)
    return request.param


def names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


# --- regular files ---------------------------------------------------------------------


def test_new_file_and_replacement(tmp_path, temp_kind):
    path = tmp_path / "out.csv"
    assert atomic_write_text(path, "one\n") == path
    assert path.read_text() == "one\n"
    inode = path.stat().st_ino
    atomic_write_bytes(str(path), b"two\n")
    assert path.read_bytes() == b"two\n"
    assert path.stat().st_ino != inode  # replaced by a rename, not rewritten
    assert names(tmp_path) == ["out.csv"]


@pytest.mark.parametrize("mode", [0o600, 0o640, 0o755])
def test_replaced_file_keeps_its_permission_bits(tmp_path, temp_kind, mode):
    path = tmp_path / "secret.csv"
    path.write_text("old")
    path.chmod(mode)
    atomic_write_text(path, "new")
    assert stat.S_IMODE(path.stat().st_mode) == mode
    assert path.read_text() == "new"


def test_new_file_honours_the_umask(tmp_path, temp_kind):
    old = os.umask(0o027)
    try:
        atomic_write_text(tmp_path / "a.csv", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "a.csv").stat().st_mode) == 0o640
    old = os.umask(0o002)
    try:
        atomic_write_text(tmp_path / "b.csv", "x")
    finally:
        os.umask(old)
    assert stat.S_IMODE((tmp_path / "b.csv").stat().st_mode) == 0o664


def test_replaced_file_keeps_its_owner(tmp_path, temp_kind):
    if os.geteuid() != 0:
        pytest.skip("only root can give a file away")
    path = tmp_path / "theirs.csv"
    path.write_text("old")
    os.chown(path, 65534, 65534)
    atomic_write_text(path, "new")
    assert (path.stat().st_uid, path.stat().st_gid) == (65534, 65534)


def test_named_temp_when_the_unnamed_file_cannot_be_linked(tmp_path, monkeypatch):
    if not rio._USE_TMPFILE:
        pytest.skip("no O_TMPFILE here")

    def no_link(fd, dst):
        raise OSError(errno.EXDEV, "Invalid cross-device link", dst)

    monkeypatch.setattr(rio, "_link_unnamed", no_link)
    path = tmp_path / "out.csv"
    path.write_text("old")
    path.chmod(0o600)
    atomic_write_bytes(path, b"n" * 300_000)
    assert path.read_bytes() == b"n" * 300_000
    assert stat.S_IMODE(path.stat().st_mode) == 0o600
    assert names(tmp_path) == ["out.csv"]


@pytest.mark.parametrize("error", [RuntimeError, KeyboardInterrupt, OSError])
def test_a_failing_writer_leaves_the_old_file_and_no_temp(tmp_path, temp_kind, error):
    path = tmp_path / "out.csv"
    path.write_text("precious")

    def writer(fh):
        fh.write(b"half of the new content")
        fh.flush()
        raise error("boom")

    with pytest.raises(error):
        atomic_write(path, writer)
    assert path.read_text() == "precious"
    assert names(tmp_path) == ["out.csv"]
    with pytest.raises(error):
        atomic_write(tmp_path / "new.csv", writer)
    assert names(tmp_path) == ["out.csv"]


def test_a_failing_rename_leaves_the_old_file_and_no_temp(tmp_path, temp_kind, monkeypatch):
    path = tmp_path / "out.csv"
    path.write_text("precious")

    def replace(src, dst):
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(rio.os, "replace", replace)
    with pytest.raises(OutputError, match="input/output error"):
        atomic_write_text(path, "new")
    assert path.read_text() == "precious"
    assert names(tmp_path) == ["out.csv"]


# --- symbolic links --------------------------------------------------------------------


def test_symlink_target_is_replaced_and_the_link_kept(tmp_path, temp_kind):
    real = tmp_path / "data" / "real.csv"
    real.parent.mkdir()
    real.write_text("old")
    real.chmod(0o600)
    (tmp_path / "hop").symlink_to("data/real.csv")  # relative
    link = tmp_path / "link.csv"
    link.symlink_to(tmp_path / "hop")  # a chain of two links
    atomic_write_text(link, "new")
    assert link.is_symlink() and (tmp_path / "hop").is_symlink()
    assert real.read_text() == "new"
    assert stat.S_IMODE(real.stat().st_mode) == 0o600
    assert names(tmp_path) == ["data", "hop", "link.csv"]
    assert names(real.parent) == ["real.csv"]


def test_dangling_symlink_creates_its_target(tmp_path, temp_kind):
    (tmp_path / "d").mkdir()
    link = tmp_path / "link.csv"
    link.symlink_to("d/made.csv")
    atomic_write_text(link, "x")
    assert link.is_symlink() and (tmp_path / "d" / "made.csv").read_text() == "x"


def test_dangling_symlink_into_a_missing_folder_is_refused(tmp_path):
    link = tmp_path / "link.csv"
    link.symlink_to("nowhere/x.csv")
    for call in (lambda: check_output(link, "--csv"), lambda: atomic_write_text(link, "x")):
        with pytest.raises(OutputError, match="symbolic link to .*nowhere/x.csv.* does not exist"):
            call()
    assert names(tmp_path) == ["link.csv"] and link.is_symlink()


def test_symlink_loop_is_refused(tmp_path):
    (tmp_path / "a").symlink_to("b")
    (tmp_path / "b").symlink_to("a")
    with pytest.raises(OutputError, match="too many levels of symbolic links"):
        atomic_write_text(tmp_path / "a", "x")


# --- special files: written in place ---------------------------------------------------


def _reader(path: Path, got: list[bytes]) -> threading.Thread:
    def read():
        with open(path, "rb") as fh:
            got.append(fh.read())

    thread = threading.Thread(target=read, daemon=True)
    thread.start()
    return thread


def test_fifo_is_written_in_place(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    thread = _reader(fifo, got)
    atomic_write_bytes(fifo, b"a" * 200_000)  # more than a pipe's buffer
    thread.join(10)
    assert got == [b"a" * 200_000]
    assert stat.S_ISFIFO(fifo.lstat().st_mode)
    assert names(tmp_path) == ["pipe"]


def test_fifo_through_a_symlink(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    (tmp_path / "link").symlink_to("pipe")
    got: list[bytes] = []
    thread = _reader(fifo, got)
    atomic_write_text(tmp_path / "link", "hello")
    thread.join(10)
    assert got == [b"hello"]
    assert (tmp_path / "link").is_symlink() and stat.S_ISFIFO(fifo.lstat().st_mode)


def test_a_failing_writer_sends_nothing_to_a_fifo(tmp_path):
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    thread = _reader(fifo, got)

    def writer(fh):
        fh.write(b"partial")
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        atomic_write(fifo, writer)
    with open(fifo, "wb"):
        pass  # release the reader: it must have got nothing
    thread.join(10)
    assert got == [b""]


def test_character_device_is_written_in_place(tmp_path):
    node = tmp_path / "null"
    try:
        os.mknod(node, 0o600 | stat.S_IFCHR, os.makedev(1, 3))  # our own /dev/null node
    except PermissionError:
        pytest.skip("mknod not permitted")
    try:
        with open(node, "wb") as fh:
            fh.write(b"")
    except OSError:
        pytest.skip("device nodes cannot be opened on this file system (nodev)")
    before = node.lstat()
    atomic_write_text(node, "discarded")
    after = node.lstat()
    assert stat.S_ISCHR(after.st_mode) and after.st_rdev == before.st_rdev
    assert after.st_ino == before.st_ino and names(tmp_path) == ["null"]
    check_outputs([(node, "--csv"), (node, "--plot")])  # the same device twice is harmless


def test_proc_fd_of_a_pipe_is_written_in_place(tmp_path):
    r, w = os.pipe()
    try:
        link = tmp_path / "fd-link"
        link.symlink_to(f"/proc/self/fd/{w}")  # as /dev/fd/N or >(...) would
        atomic_write_text(f"/proc/self/fd/{w}", "one ")
        atomic_write_text(link, "two")
        os.close(w)
        w = -1
        assert os.read(r, 100) == b"one two"
        assert link.is_symlink() and names(tmp_path) == ["fd-link"]
    finally:
        os.close(r)
        if w >= 0:
            os.close(w)


def test_proc_fd_of_a_file_writes_the_open_file(tmp_path):
    path = tmp_path / "out.csv"
    with open(path, "wb") as fh:  # as the shell's 3>out.csv
        inode = path.stat().st_ino
        atomic_write_text(f"/proc/self/fd/{fh.fileno()}", "through the descriptor")
    assert path.read_text() == "through the descriptor" and path.stat().st_ino == inode
    assert names(tmp_path) == ["out.csv"]


def test_proc_fd_of_a_file_opened_to_append_appends(tmp_path):
    log = tmp_path / "run.log"
    log.write_text("line 1\n")
    with open(log, "ab") as fh:  # as the shell's 3>>run.log: written through, not truncated
        atomic_write_text(f"/proc/self/fd/{fh.fileno()}", "line 2\n")
    assert log.read_text() == "line 1\nline 2\n"


def test_a_closed_descriptor_is_refused(tmp_path):
    r, w = os.pipe()
    os.close(r)
    os.close(w)
    with pytest.raises(OutputError, match=f"file descriptor {w} is not open"):
        check_output(f"/proc/self/fd/{w}", "--csv")


def test_socket_is_refused(tmp_path):
    import socket

    path = tmp_path / "sock"
    with socket.socket(socket.AF_UNIX) as s:
        s.bind(str(path))
        with pytest.raises(OutputError, match="it is a socket"):
            atomic_write_text(path, "x")
    assert stat.S_ISSOCK(path.lstat().st_mode)


# --- stdout ----------------------------------------------------------------------------


def test_dash_is_stdout(tmp_path, capfd, monkeypatch):
    monkeypatch.chdir(tmp_path)
    check_output("-", "--csv")
    check_writable("-", "--csv")
    print("before", end=" ")
    atomic_write_text("-", "t,q1\n0,1\n")
    atomic_write(Path("-"), lambda fh: fh.write(b"bytes\n"))
    out, err = capfd.readouterr()
    assert out == "before t,q1\n0,1\nbytes\n" and err == ""
    assert names(tmp_path) == []


# --- one-line errors -------------------------------------------------------------------


@pytest.mark.parametrize(
    "relative, words",
    [
        ("nofolder/x.csv", "folder '{tmp}/nofolder' does not exist"),
        ("", "it is a folder"),
        ("sub", "it is a folder"),
        ("sub/", "it is a folder"),
        ("new/", "a path ending in '/' names a folder"),
        ("x" * 300 + ".csv", "the file name is 304 bytes long, over the 255"),
        ("file.txt/x.csv", "'{tmp}/file.txt' is not a folder"),
    ],
    ids=["missing folder", "tmp", "folder", "folder/", "slash", "name too long", "file as folder"],
)
def test_low_severity_problems_are_one_line_input_errors(tmp_path, relative, words):
    (tmp_path / "sub").mkdir()
    (tmp_path / "file.txt").write_text("keep")
    path = str(tmp_path / relative) if relative else str(tmp_path)
    if relative.endswith("/"):
        path += "/"
    before = names(tmp_path)
    for call in (
        lambda: check_writable(path, "--csv"),
        lambda: atomic_write_text(path, "x", flag="--csv"),
        lambda: write_outputs([(path, "--csv", lambda fh: fh.write(b"x"))]),
    ):
        with pytest.raises(InputError) as info:
            call()
        message = str(info.value)
        assert "\n" not in message
        assert message.startswith(f"cannot write --csv {path!r}: ")
        assert words.replace("{tmp}", str(tmp_path)) in message
        assert isinstance(info.value, OSError) and info.value.errno is not None
    assert names(tmp_path) == before
    assert (tmp_path / "file.txt").read_text() == "keep"


def test_output_error_is_an_oserror_for_old_callers_and_pickles():
    e = OutputError(
        "cannot write --csv 'x': no space left on device", errno.ENOSPC, "no space", "x"
    )
    assert isinstance(e, InputError) and isinstance(e, OSError)
    assert (e.errno, e.strerror, e.filename) == (errno.ENOSPC, "no space", "x")
    back = pickle.loads(pickle.dumps(e))
    assert str(back) == str(e) and back.errno == errno.ENOSPC


def test_full_disk_keeps_the_old_file_and_leaves_no_temp(tiny_fs, temp_kind):
    path = tiny_fs / "out.csv"
    path.write_text("old content")
    big = b"x" * 1_000_000
    with pytest.raises(OutputError) as info:
        atomic_write_bytes(path, big, flag="--csv")
    assert info.value.errno == errno.ENOSPC
    assert str(info.value) == (
        f"cannot write --csv {str(path)!r}: no space left on device; the old file is unchanged"
    )
    assert path.read_text() == "old content"
    assert names(tiny_fs) == ["out.csv"]
    with pytest.raises(OutputError, match="no space left on device"):
        atomic_write_bytes(tiny_fs / "new.csv", big)
    assert names(tiny_fs) == ["out.csv"]


def test_full_disk_mid_way_through_a_writer(tiny_fs, temp_kind):
    path = tiny_fs / "out.csv"
    path.write_text("old content")

    def writer(fh):
        for _ in range(1000):
            fh.write(b"y" * 4096)

    with pytest.raises(OutputError, match="no space left on device"):
        atomic_write(path, writer)
    assert path.read_text() == "old content" and names(tiny_fs) == ["out.csv"]


def test_read_only_file_system(tiny_fs):
    path = tiny_fs / "out.csv"
    path.write_text("old")
    proc = subprocess.run(["mount", "-o", "remount,ro", str(tiny_fs)], capture_output=True)
    if proc.returncode != 0:
        pytest.skip("cannot remount read-only")
    for target in (path, tiny_fs / "new.csv"):
        for call in (
            lambda t=target: check_writable(str(t), "--plot"),
            lambda t=target: atomic_write_text(t, "new", flag="--plot"),
        ):
            with pytest.raises(InputError, match=r"^cannot write --plot .*: read-only file system"):
                call()
    assert path.read_text() == "old" and names(tiny_fs) == ["out.csv"]


def test_folder_not_writable_by_another_user():
    if os.geteuid() != 0 or not hasattr(os, "fork"):
        pytest.skip("needs root to become another user")
    base = Path(tempfile.mkdtemp(prefix="rrt-io-"))  # /tmp/pytest-of-root is 0700
    try:
        base.chmod(0o755)
        (base / "theirs.csv").write_text("old")
        (base / "theirs.csv").chmod(0o644)
        pid = os.fork()
        if pid == 0:  # pragma: no cover - the child
            code = 1
            try:
                os.setgid(65534)
                os.setuid(65534)
                code = 0
                for name, words in (("new.csv", "is not writable"), ("theirs.csv", "not writable")):
                    try:
                        check_output(str(base / name), "--csv")
                        code = 2
                    except OutputError as e:
                        code = code if words in str(e) else 3
            finally:
                os._exit(code)
        _, status = os.waitpid(pid, 0)
        assert os.waitstatus_to_exitcode(status) == 0
        assert (base / "theirs.csv").read_text() == "old"
    finally:
        shutil.rmtree(base)


# --- several outputs of one run --------------------------------------------------------


def test_write_outputs_writes_all_and_skips_none(tmp_path, temp_kind):
    a, b = tmp_path / "a.csv", tmp_path / "b.png"
    b.write_bytes(b"old png")
    written = write_outputs(
        [
            (a, "--csv", lambda fh: fh.write(b"csv")),
            (None, "--other", lambda fh: 1 / 0),
            (str(b), "--plot", lambda fh: fh.write(b"png")),
        ]
    )
    assert written == [a, b]
    assert a.read_bytes() == b"csv" and b.read_bytes() == b"png"
    assert names(tmp_path) == ["a.csv", "b.png"]


@pytest.mark.parametrize("failing", [0, 1, 2])
def test_one_failing_output_changes_no_other(tmp_path, temp_kind, failing):
    paths = [tmp_path / "a.csv", tmp_path / "b.png", tmp_path / "c.json"]
    for p in paths:
        p.write_bytes(f"old {p.name}".encode())
    inodes = [p.stat().st_ino for p in paths]

    def writer(i):
        def write(fh):
            fh.write(b"new")
            if i == failing:
                raise RuntimeError(f"writer {i} failed")

        return write

    with pytest.raises(RuntimeError, match=f"writer {failing} failed"):
        write_outputs([(p, f"--o{i}", writer(i)) for i, p in enumerate(paths)])
    assert [p.read_bytes() for p in paths] == [f"old {p.name}".encode() for p in paths]
    assert [p.stat().st_ino for p in paths] == inodes
    assert names(tmp_path) == ["a.csv", "b.png", "c.json"]


def test_a_full_disk_for_one_output_changes_no_other(tiny_fs, tmp_path, temp_kind):
    kept = tmp_path / "plot.png"
    kept.write_bytes(b"old plot")
    (tiny_fs / "out.csv").write_text("old csv")
    with pytest.raises(OutputError, match="--csv .*no space left on device"):
        write_outputs(
            [
                (kept, "--plot", lambda fh: fh.write(b"new plot")),
                (tiny_fs / "out.csv", "--csv", lambda fh: fh.write(b"z" * 1_000_000)),
            ]
        )
    assert kept.read_bytes() == b"old plot" and (tiny_fs / "out.csv").read_text() == "old csv"
    assert names(tmp_path) == ["plot.png", "tiny"] and names(tiny_fs) == ["out.csv"]


def test_a_failing_rename_puts_back_the_outputs_already_replaced(tmp_path, temp_kind, monkeypatch):
    first, second, new = tmp_path / "a.csv", tmp_path / "b.png", tmp_path / "c.txt"
    first.write_text("old a")
    second.write_text("old b")
    real_replace = os.replace

    def replace(src, dst):
        if os.fspath(dst) == str(second):
            raise OSError(errno.EIO, "Input/output error")
        return real_replace(src, dst)

    monkeypatch.setattr(rio.os, "replace", replace)
    with pytest.raises(OutputError, match="--plot .*input/output error"):
        write_outputs(
            [
                (first, "--csv", lambda fh: fh.write(b"new a")),
                (new, "--log", lambda fh: fh.write(b"new c")),
                (second, "--plot", lambda fh: fh.write(b"new b")),
            ]
        )
    assert first.read_text() == "old a" and second.read_text() == "old b"
    assert names(tmp_path) == ["a.csv", "b.png"]


@pytest.mark.parametrize("how", ["same path", "symlink", "hard link", "relative", "new file"])
def test_two_outputs_naming_the_same_file_are_refused(tmp_path, monkeypatch, how):
    monkeypatch.chdir(tmp_path)
    target = tmp_path / "out.csv"
    if how != "new file":
        target.write_text("precious")
    other = {
        "same path": str(target),
        "symlink": str(tmp_path / "link"),
        "hard link": str(tmp_path / "hard"),
        "relative": "./sub/../out.csv",
        "new file": str(target),
    }[how]
    (tmp_path / "sub").mkdir()
    if how == "symlink":
        (tmp_path / "link").symlink_to(target)
    if how == "hard link":
        os.link(target, tmp_path / "hard")
    before = names(tmp_path)
    outputs = [(str(target), "--csv", lambda fh: fh.write(b"a")), (other, "--plot", print)]
    with pytest.raises(InputError, match=r"^--csv and --plot name the same file "):
        check_outputs([(p, f) for p, f, _ in outputs])
    with pytest.raises(InputError, match=r"^--csv and --plot name the same file "):
        write_outputs(outputs)
    assert names(tmp_path) == before
    if how != "new file":
        assert target.read_text() == "precious"


def test_stdout_twice_is_refused(capfd):
    with pytest.raises(InputError, match="--csv and --plot name the same file '-'"):
        write_outputs([("-", "--csv", print), ("-", "--plot", print)])
    assert capfd.readouterr().out == ""


# --- through the CLI -------------------------------------------------------------------


def test_cli_urdf_through_a_symlink_and_to_stdout(tmp_path, capfd, monkeypatch):
    from rrt_pin.cli.app import main

    monkeypatch.chdir(tmp_path)  # a broken '-' would land here

    real = tmp_path / "arm.urdf"
    real.write_text("old")
    real.chmod(0o600)
    (tmp_path / "link.urdf").symlink_to("arm.urdf")
    assert main(["urdf", "-o", str(tmp_path / "link.urdf")]) == 0
    assert (tmp_path / "link.urdf").is_symlink() and real.read_text().startswith("<?xml")
    assert stat.S_IMODE(real.stat().st_mode) == 0o600
    capfd.readouterr()
    assert main(["urdf", "-o", "-"]) == 0
    assert capfd.readouterr().out == real.read_text()
    assert names(tmp_path) == ["arm.urdf", "link.urdf"]


def test_io_imports_only_the_standard_library():
    code = (
        "import sys; import rrt_pin.io.files; "
        "print(sorted(m for m in sys.modules if m.split('.')[0] in "
        "{'numpy', 'pinocchio', 'matplotlib', 'scipy'}))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_a_long_output_to_a_fifo_is_spooled_to_disk_not_memory(tmp_path, monkeypatch):
    """Past the spool size the staged bytes go to a temporary file, sent in chunks."""
    monkeypatch.setattr(rio, "_SPOOL_BYTES", 1000)
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "spool"))
    (tmp_path / "spool").mkdir()
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    thread = _reader(fifo, got)
    blocks = [bytes([65 + k % 26]) * 100_000 for k in range(30)]  # 3 MB in blocks
    seen: list[bool] = []

    def writer(fh):
        for b in blocks:
            fh.write(b)
        seen.append(fh._rolled)  # SpooledTemporaryFile: now a real file, not BytesIO

    atomic_write(fifo, writer)
    thread.join(10)
    assert seen == [True]
    assert got == [b"".join(blocks)]
    assert names(tmp_path / "spool") == []  # the temporary file is gone


def test_a_failing_writer_past_the_spool_sends_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr(rio, "_SPOOL_BYTES", 10)
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    got: list[bytes] = []
    thread = _reader(fifo, got)

    def writer(fh):
        fh.write(b"x" * 10_000)
        raise RuntimeError("boom")

    with pytest.raises(RuntimeError):
        atomic_write(fifo, writer)
    with open(fifo, "wb"):
        pass
    thread.join(10)
    assert got == [b""]


def test_check_space_refuses_what_does_not_fit(tmp_path, monkeypatch):
    free = shutil.disk_usage(tmp_path).free
    rio.check_space(tmp_path / "a.csv", 1000, "--csv")
    rio.check_space(None, 10**30, "--csv")
    with pytest.raises(OutputError) as info:
        rio.check_space(tmp_path / "a.csv", free * 2 + 10**9, "--csv")
    assert info.value.errno == errno.ENOSPC
    assert str(info.value).startswith(f"cannot write --csv '{tmp_path / 'a.csv'}': no space left")
    rio.check_space("-", 1000, "--csv")  # small: stays in memory, nothing to check
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    with pytest.raises(OutputError, match="no space left on device"):
        rio.check_space("-", free * 2 + 10**9, "--csv")  # staged in the temporary folder
    assert names(tmp_path) == []
