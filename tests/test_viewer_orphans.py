"""A killed screenshot leaves no browser and no profile behind (SIGKILL and SIGTERM).

Each run gets a private TMPDIR, so the profile, and every process whose command
line names it, are the test's own. It is made in /tmp: Chromium's socket paths
must fit in 107 bytes, and in a TMPDIR as long as pytest's ``tmp_path`` the
browser's folder would go to /tmp (``rrt_pin.viewer.browser.MAX_TMPDIR``).
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

from rrt_pin.viewer.browser import find_chromium

pytestmark = pytest.mark.skipif(find_chromium() is None, reason="needs chromium and chromedriver")


def _naming(marker: str) -> list[int]:
    pids = []
    for name in os.listdir("/proc"):
        if name.isdigit() and int(name) != os.getpid():
            try:
                with open(f"/proc/{name}/cmdline", "rb") as fh:
                    if marker.encode() in fh.read():
                        pids.append(int(name))
            except OSError:
                pass
    return pids


def _browser_pids(tmp: Path) -> list[int]:
    """chromedriver and Chromium processes of this test's profile (not the watchdog)."""
    out = []
    for pid in _naming(str(tmp / "rrt-pin-chromium-")):
        try:
            cmd = Path(f"/proc/{pid}/cmdline").read_bytes()
        except OSError:
            continue
        if b"chrom" in cmd.split(b"\0")[0]:
            out.append(pid)
    return out


def _kill_mid_screenshot(tmp: Path, sig: int) -> subprocess.Popen:
    """Start a screenshot and send ``sig`` once Chromium runs; retried if it finished first."""
    env = {**os.environ, "TMPDIR": str(tmp)}
    for _ in range(3):
        proc = subprocess.Popen(
            [sys.executable, "-m", "rrt_pin", "view", "--port", "0",
             "--screenshot", str(tmp / "shot.png")],
            env=env, cwd=tmp, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
        )  # fmt: skip
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline and proc.poll() is None:
            if len(_browser_pids(tmp)) >= 2:  # chromedriver and at least one Chromium
                proc.send_signal(sig)
                proc.wait(30)
                return proc
            time.sleep(0.02)
        proc.wait(30)
    pytest.fail("the screenshot never had its browser running long enough to be killed")


def _wait_gone(tmp: Path, seconds: float = 20.0) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if not _naming(str(tmp)) and not list(tmp.glob("rrt-pin-chromium-*")):
            return
        time.sleep(0.1)
    left = [Path(f"/proc/{p}/cmdline").read_bytes()[:80] for p in _naming(str(tmp))]
    raise AssertionError(f"left behind: processes {left}, {list(tmp.glob('rrt-pin-chromium-*'))}")


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM])
def test_killed_screenshot_leaves_nothing(sig):
    tmp = Path(tempfile.mkdtemp(prefix="rrt-test-", dir="/tmp"))
    try:
        proc = _kill_mid_screenshot(tmp, sig)
        assert proc.returncode != 0
        _wait_gone(tmp)
        assert not (tmp / "shot.png").exists()  # no partial screenshot either
    finally:  # never leave a browser on the machine, whatever failed
        for pid in _naming(str(tmp)):
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        shutil.rmtree(tmp, ignore_errors=True)
