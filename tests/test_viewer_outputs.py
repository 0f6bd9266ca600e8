"""--screenshot onto a full or read-only disk: one line, exit 2, nothing partial left."""

from __future__ import annotations

import subprocess

import pytest

from rrt_pin.cli.app import main
from rrt_pin.viewer.browser import find_chromium

pytestmark = pytest.mark.skipif(find_chromium() is None, reason="needs chromium and chromedriver")


def test_screenshot_on_a_full_disk(tiny_fs, capsys):
    (tiny_fs / "filler").write_bytes(b"x" * (64 * 1024 - 4096))  # less room than a PNG
    assert main(["view", "--port", "0", "--screenshot", str(tiny_fs / "shot.png")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "no space left on device" in err, err
    assert sorted(p.name for p in tiny_fs.iterdir()) == ["filler"]


def test_screenshot_on_a_read_only_disk_is_refused_before_the_browser(tiny_fs, capsys):
    if subprocess.run(["mount", "-o", "remount,ro", str(tiny_fs)], capture_output=True).returncode:
        pytest.skip("cannot remount read-only")
    import rrt_pin.viewer.browser as browser

    started = []
    real = browser.Chromium.__init__

    def spy(self, *a, **k):
        started.append(1)
        real(self, *a, **k)

    browser.Chromium.__init__ = spy
    try:
        assert main(["view", "--port", "0", "--screenshot", str(tiny_fs / "shot.png")]) == 2
    finally:
        browser.Chromium.__init__ = real
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "read-only file system" in err.lower(), err
    assert started == [] and list(tiny_fs.iterdir()) == []
