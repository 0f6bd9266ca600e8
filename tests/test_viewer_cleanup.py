"""What the viewer leaves behind: clean mesh warnings, and no Chromium files after a kill.

* A mesh that does not load is one warning line naming the mesh file and the
  problem, never the C++ source locations of Pinocchio's mesh loader.
* Chromium and chromedriver write only inside the run's private folder
  (``$TMPDIR/rrt-pin-chromium-*``, their ``TMPDIR`` pointing into it), which is
  removed when the run is killed (SIGTERM, SIGKILL), and by the next run when
  the watchdog was killed too. Each browser test runs with a private TMPDIR, so
  it inspects only its own folder and processes. That TMPDIR is made in /tmp,
  not in ``tmp_path``: Chromium's socket paths must fit in 107 bytes, and a
  TMPDIR as long as pytest's would send the browser's folder to /tmp.
"""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest

from rrt_pin.cli.app import main
from rrt_pin.core.errors import UrdfError
from rrt_pin.viewer.browser import (
    FOLDER_PREFIX,
    MAX_TMPDIR,
    find_chromium,
    folder_base,
    remove_stale_folders,
)

# ---------------------------------------------------------------------------
# Mesh warnings
# ---------------------------------------------------------------------------
#: What Pinocchio 3 (coal's assimp loader) raises for an STL file that is not one.
COAL_TEXT = (
    "From file: /project/src/mesh_loader/assimp.cpp\n"
    "in function: void coal::internal::Loader::load(const std::string&)\n"
    "at line: 91\n"
    "message: Could not load resource /data/arm/bad.stl\n"
    "Failed to determine STL storage representation for /data/arm/bad.stl.\n"
    "Hint: the mesh directory may be wrong.\n"
)

_SOURCES = ("From file", "assimp.cpp", ".cpp", "in function", "at line", "coal::", "Hint")


def test_native_message_keeps_the_mesh_and_the_problem():
    from rrt_pin.core._quiet import native_message

    assert native_message(COAL_TEXT) == (
        "mesh file /data/arm/bad.stl does not load: failed to determine STL storage representation"
    )
    assert native_message("Mesh meshes/a.stl could not be found.") == (
        "mesh file meshes/a.stl could not be found"
    )
    assert native_message("at line: 3\nboom in /src/x.hpp:12 here.\n") == "boom in here"
    assert native_message("") == "an error without a message"


def _urdf(mesh: str) -> str:
    return f"""<?xml version="1.0"?>
<robot name="m">
  <link name="base"/>
  <joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <link name="arm">
    <inertial><origin xyz="0.5 0 0"/><mass value="1"/>
      <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>
    <visual><origin xyz="0.5 0 0"/><geometry><box size="1 0.1 0.1"/></geometry></visual>
    <visual><geometry><mesh filename="{mesh}"/></geometry></visual>
  </link>
</robot>
"""


def _view_warning(tmp_path: Path, mesh: str, capsys) -> str:
    urdf = tmp_path / "arm.urdf"
    urdf.write_text(_urdf(mesh))
    csv = tmp_path / "motion.csv"
    csv.write_text("t,j1\n0,0\n1,1.5\n")
    argv = ["view", "--urdf", str(urdf), "--trajectory", str(csv), "--port", "0"]
    code = main([*argv, "--serve-for", "0"])
    out, err = capsys.readouterr()
    assert code == 0 and out.startswith("http://127.0.0.1:"), err
    warnings = [line for line in err.splitlines() if "warning" in line]
    assert len(warnings) == 1, err
    for word in _SOURCES:
        assert word not in err, err
    return warnings[0]


@pytest.mark.parametrize(
    "make, problem",
    [
        (lambda p: p.write_text("not a mesh at all\n"), "failed to determine STL storage"),
        (lambda p: p.write_bytes(b""), "file is empty"),
        (lambda p: p.write_bytes(b"\x00\x01"), "file is too small"),
        (lambda p: p.mkdir(), "unable to open file"),
    ],
    ids=["garbage", "empty", "two bytes", "folder"],
)
def test_a_mesh_that_does_not_load_is_one_clean_warning(tmp_path, capsys, make, problem):
    mesh = tmp_path.resolve() / "tool.stl"
    make(mesh)
    warning = _view_warning(tmp_path, "tool.stl", capsys)
    # the reason is assimp's, in its words of this version
    assert warning.startswith(f"rrt-pin: warning: mesh file {mesh} does not load: ")
    assert warning.endswith("; drawing the URDF without its meshes")
    assert problem in warning


def test_a_missing_mesh_is_one_clean_warning(tmp_path, capsys):
    warning = _view_warning(tmp_path, "meshes/tool.stl", capsys)
    # a relative path: no word about package:// paths and ROS_PACKAGE_PATH
    assert warning == (
        "rrt-pin: warning: mesh file meshes/tool.stl could not be found; "
        "drawing the URDF without its meshes"
    )


def test_the_library_error_of_a_bad_mesh_is_clean(tmp_path):
    from rrt_pin.robot.model import build_geometry, model_from_xml

    mesh = tmp_path / "tool.stl"
    mesh.write_text("solid nothing\nendsolid nothing\n")
    xml = _urdf(str(mesh))
    with pytest.raises(UrdfError) as e:
        build_geometry(model_from_xml(xml), xml)
    message = str(e.value)
    assert message.startswith(f"URDF geometry does not load: mesh file {mesh} does not load: ")
    assert "\n" not in message and not any(word in message for word in _SOURCES)


# ---------------------------------------------------------------------------
# Stale private folders (no browser needed)
# ---------------------------------------------------------------------------
def _start_time(pid: int) -> int:
    return int(Path(f"/proc/{pid}/stat").read_bytes().rsplit(b")", 1)[1].split()[19])


def _folder(where: Path, name: str, owners: list[tuple[int, int]] | None) -> Path:
    folder = where / (FOLDER_PREFIX + name)
    (folder / "tmp" / "org.chromium.Chromium.abc123").mkdir(parents=True)
    (folder / "tmp" / "org.chromium.Chromium.abc123" / "SingletonCookie").write_text("x")
    if owners is not None:
        (folder / "owners").write_text("".join(f"{p} {s}\n" for p, s in owners))
    return folder


def _sleeper(*argv: str) -> subprocess.Popen:
    """A process whose command line names ``argv`` (as a Chromium left running would)."""
    code = "import sys, time; time.sleep(60)"
    return subprocess.Popen([sys.executable, "-c", code, *argv])


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="needs Linux /proc")
def test_stale_folders_are_removed_and_live_ones_kept(tmp_path):
    me = (os.getpid(), _start_time(os.getpid()))
    gone = subprocess.Popen(["true"])
    gone.wait()
    zombie = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    zombie_owner = (zombie.pid, _start_time(zombie.pid))
    zombie.kill()
    os.waitid(os.P_PID, zombie.pid, os.WEXITED | os.WNOWAIT)  # dead, not reaped: a zombie
    stale = {
        "dead": _folder(tmp_path, "dead", [(gone.pid, 1)]),
        "pid reused": _folder(tmp_path, "reused", [(me[0], me[1] + 1)]),
        "zombie": _folder(tmp_path, "zombie", [zombie_owner]),
        "old, no owners": _folder(tmp_path, "old", None),
        "orphan": _folder(tmp_path, "orphan", [(gone.pid, 1)]),
    }
    live = {
        "live": _folder(tmp_path, "live", [(gone.pid, 1), me]),
        "new, no owners": _folder(tmp_path, "new", None),
        "old, no owners, in use": _folder(tmp_path, "used", None),
        "another prefix": tmp_path / "chromium-dead",
        "a sibling whose name extends a stale one": _folder(tmp_path, "orphanX", [me]),
    }
    live["another prefix"].mkdir()
    for old in (stale["old, no owners"], live["old, no owners, in use"]):
        os.utime(old, (time.time() - 7200,) * 2)
    (tmp_path / "target").mkdir()
    (tmp_path / "target" / "owners").write_text(f"{gone.pid} 1\n")
    (tmp_path / (FOLDER_PREFIX + "link")).symlink_to(tmp_path / "target")
    orphan = _sleeper(f"--user-data-dir={stale['orphan']}/profile")
    bystander = _sleeper(f"--user-data-dir={live['a sibling whose name extends a stale one']}/p")
    user = _sleeper(f"--user-data-dir={live['old, no owners, in use']}/profile")
    try:
        removed = remove_stale_folders(str(tmp_path))
        assert sorted(removed) == sorted(str(p) for p in stale.values())
        assert orphan.wait(10) == -signal.SIGKILL
        assert bystander.poll() is None and user.poll() is None
        for name, path in live.items():
            assert path.is_dir(), name
        assert (tmp_path / (FOLDER_PREFIX + "link")).is_symlink()
        assert (tmp_path / "target" / "owners").exists()
    finally:
        for proc in (orphan, bystander, user, zombie):
            proc.kill()
            proc.wait()


def test_the_folder_is_made_where_chromium_can_open_its_socket(tmp_path, monkeypatch):
    short = tmp_path.resolve()
    while len(str(short)) > MAX_TMPDIR:
        short = short.parent
    monkeypatch.setattr(tempfile, "tempdir", str(short))
    assert folder_base() == str(short)
    long = tmp_path / ("x" * MAX_TMPDIR)
    long.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(long))
    assert folder_base() == "/tmp"


# ---------------------------------------------------------------------------
# A killed screenshot in a real browser
# ---------------------------------------------------------------------------
def _naming(marker: str) -> list[int]:
    pids = []
    for name in os.listdir("/proc"):
        if name.isdigit() and int(name) != os.getpid():
            try:
                if marker.encode() in Path(f"/proc/{name}/cmdline").read_bytes():
                    pids.append(int(name))
            except OSError:
                pass
    return pids


def _is_browser(pid: int) -> bool:
    try:
        return b"chrom" in Path(f"/proc/{pid}/cmdline").read_bytes().split(b"\0")[0]
    except OSError:
        return False


def _environ(pid: int) -> dict[str, str] | None:
    """The environment of process ``pid``, or None when it has ended since it was listed."""
    try:
        raw = Path(f"/proc/{pid}/environ").read_bytes()
    except (FileNotFoundError, ProcessLookupError):
        return None
    pairs = (item.split(b"=", 1) for item in raw.split(b"\0") if b"=" in item)
    return {k.decode(): v.decode(errors="replace") for k, v in pairs}


def _screenshot(tmp: Path) -> subprocess.Popen:
    env = {**os.environ, "TMPDIR": str(tmp)}
    return subprocess.Popen(
        [sys.executable, "-m", "rrt_pin", "view", "--port", "0",
         "--screenshot", str(tmp / "shot.png")],
        env=env, cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
    )  # fmt: skip


def _browsers_up(tmp: Path, proc: subprocess.Popen) -> list[int]:
    """The run's chromedriver and Chromium pids, once there are at least 3 of them."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline and proc.poll() is None:
        pids = [p for p in _naming(str(tmp / FOLDER_PREFIX)) if _is_browser(p)]
        if len(pids) >= 3:  # chromedriver, Chromium and one of its helpers
            return pids
        time.sleep(0.02)
    return []


def _wait_empty(tmp: Path, seconds: float = 20.0) -> None:
    """Wait until no process names ``tmp`` and it holds nothing."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not _naming(str(tmp)) and not list(tmp.iterdir()):
            return
        time.sleep(0.1)
    left = [Path(f"/proc/{p}/cmdline").read_bytes()[:80] for p in _naming(str(tmp))]
    raise AssertionError(f"left behind: processes {left}, files {sorted(tmp.rglob('*'))}")


@pytest.fixture
def private_tmp(tmp_path):
    if find_chromium() is None:
        reason = "headless Chromium not found (apt-get install chromium chromium-driver)"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{reason}; CI must run the browser tests")
        pytest.skip(reason)
    tmp = Path(tempfile.mkdtemp(prefix="rrt-test-", dir="/tmp"))  # short: see above
    assert len(str(tmp)) <= MAX_TMPDIR
    try:
        yield tmp
    finally:
        for pid in _naming(str(tmp)):  # never leave a browser on the machine, whatever failed
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        shutil.rmtree(tmp, ignore_errors=True)


@pytest.mark.browser
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_a_killed_screenshot_leaves_its_temporary_folder_empty(private_tmp, sig):
    tmp = private_tmp
    for _ in range(3):  # retried if the screenshot finished before it could be killed
        proc = _screenshot(tmp)
        pids = _browsers_up(tmp, proc)
        if pids:
            break
        proc.wait(30)
    else:
        pytest.fail("the screenshot never had its browser running long enough to be killed")
    # Chromium's own temporary files go into the run's private folder
    (folder,) = tmp.glob(FOLDER_PREFIX + "*")
    envs = [e for e in map(_environ, pids) if e is not None]  # a helper may end meanwhile
    assert len(envs) >= 2, pids  # chromedriver and Chromium at least
    for with_env in envs:
        assert with_env["TMPDIR"] == str(folder), with_env.get("TMPDIR")
        assert with_env["XDG_CONFIG_HOME"].startswith(str(folder) + "/")
    proc.send_signal(sig)
    proc.wait(30)
    assert proc.returncode != 0
    _wait_empty(tmp)  # no org.chromium.Chromium.*, no rrt-pin-chromium-*, no process
    assert not (tmp / "shot.png").exists()


@pytest.mark.browser
def test_the_next_run_cleans_up_after_a_killed_watchdog(private_tmp):
    tmp = private_tmp
    for _ in range(3):
        proc = _screenshot(tmp)
        if _browsers_up(tmp, proc):
            break
        proc.wait(30)
    else:
        pytest.fail("the screenshot never had its browser running long enough to be killed")
    (folder,) = tmp.glob(FOLDER_PREFIX + "*")
    watchdogs = [p for p in _naming(str(folder)) if not _is_browser(p) and p != proc.pid]
    assert len(watchdogs) == 1
    os.kill(watchdogs[0], signal.SIGKILL)
    proc.kill()
    proc.wait(30)
    time.sleep(0.5)
    assert folder.is_dir()  # left behind, with Chromium's processes
    second = _screenshot(tmp)
    assert second.wait(120) == 0, second.stderr.read().decode()
    (tmp / "shot.png").unlink()
    _wait_empty(tmp)
