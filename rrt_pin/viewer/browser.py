"""Headless Chromium driven by selenium: load the viewer page, wait for the scene, screenshot it.

Uses Debian's ``/usr/bin/chromium`` and ``/usr/bin/chromedriver`` (or the
``RRT_PIN_CHROMIUM`` / ``RRT_PIN_CHROMEDRIVER`` environment variables, or
``chromium``/``chromedriver`` on PATH). The browser runs with a fresh temporary
profile and no network beyond the viewer's own address; every process it
starts is ended on exit, Ctrl-C included. Times in seconds [s], sizes in pixels.

Nothing outlives us, not even a SIGKILL: a watchdog process (its own session,
so a terminal's signals and a killed process group spare it) holds the read end
of a pipe whose write end only this process has. When this process ends without
saying "done" on it (killed), the pipe closes and the watchdog kills every process
whose command line names the throw-away profile — chromedriver (its log is in the
profile) and every Chromium process — then removes the profile.
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rrt_pin.errors import ViewerError

__all__ = [
    "BROWSER_NAMES",
    "CHROMIUM_FLAGS",
    "DRIVER_NAMES",
    "Chromium",
    "find_chromium",
    "screenshot",
]

#: Flags for a headless, offline, throw-away Chromium (plus ``--user-data-dir``).
CHROMIUM_FLAGS = (
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--enable-unsafe-swiftshader",  # software WebGL; the page is our own, local
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-dev-shm-usage",
    "--hide-scrollbars",
)

# True once meshcat's page has every object and the animation of n clips.
_READY_JS = """
const n = arguments[0];
return typeof viewer !== 'undefined' && viewer.connection !== undefined
    && viewer.connection.readyState === 1
    && viewer.animator.actions.length >= n;
"""

# Pause the page's animation at time t [s] and draw it (after two frames).
_SEEK_JS = """
const t = arguments[0], done = arguments[arguments.length - 1];
const a = viewer.animator;
a.pause();
a.seek(t);
a.display_progress(t);
viewer.set_dirty();
requestAnimationFrame(() => requestAnimationFrame(() => done(true)));
"""

_DRAWN_JS = """
const done = arguments[arguments.length - 1];
viewer.set_dirty();
requestAnimationFrame(() => requestAnimationFrame(() => done(true)));
"""


# The watchdog (run by ``python -I -c``, so it imports nothing of ours): argv[1] is
# the profile folder. It waits for EOF on stdin; unless it read b"done", it kills
# every process whose command line names the profile, until none is left, then
# removes the profile.
_WATCHDOG = r"""
import os, shutil, signal, sys, time
profile = sys.argv[1]
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
said = sys.stdin.buffer.read()
def marked():
    out = []
    for name in os.listdir("/proc") if os.path.isdir("/proc") else ():
        if name.isdigit() and int(name) != os.getpid():
            try:
                with open(f"/proc/{name}/cmdline", "rb") as fh:
                    if profile.encode() in fh.read():
                        out.append(int(name))
            except OSError:
                pass
    return out
if said != b"done":
    deadline = time.monotonic() + 15
    while time.monotonic() < deadline:
        pids = marked()
        if not pids:
            break
        for pid in pids:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        time.sleep(0.05)
    for _ in range(20):
        shutil.rmtree(profile, ignore_errors=True)
        if not os.path.exists(profile):
            break
        time.sleep(0.1)
"""


def _processes_naming(marker: str, exclude: frozenset[int] = frozenset()) -> list[int]:
    """Pids of the processes whose command line contains ``marker`` (Linux /proc; else none)."""
    pids = []
    with contextlib.suppress(OSError):
        for name in os.listdir("/proc"):
            if name.isdigit() and int(name) not in exclude:
                with contextlib.suppress(OSError), open(f"/proc/{name}/cmdline", "rb") as fh:
                    if marker.encode() in fh.read():
                        pids.append(int(name))
    return pids


@dataclass(frozen=True)
class ChromiumPaths:
    """Where the browser and its driver are.

    Attributes:
        browser: the Chromium executable.
        driver: the matching chromedriver executable.
    """

    browser: str
    driver: str


#: Executable names of Chromium or Chrome, and of their driver, in order of preference.
BROWSER_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable", "chrome")
DRIVER_NAMES = ("chromedriver", "chromium-driver")


def find_chromium() -> ChromiumPaths | None:
    """Chromium (or Chrome) and chromedriver, or None when either is missing.

    Looks at ``RRT_PIN_CHROMIUM`` / ``RRT_PIN_CHROMEDRIVER`` first, then Debian's
    ``/usr/bin`` paths, then :data:`BROWSER_NAMES` and :data:`DRIVER_NAMES` on PATH.
    """
    candidates = {
        "browser": [
            os.environ.get("RRT_PIN_CHROMIUM"),
            "/usr/bin/chromium",
            *(shutil.which(name) for name in BROWSER_NAMES),
        ],
        "driver": [
            os.environ.get("RRT_PIN_CHROMEDRIVER"),
            "/usr/bin/chromedriver",
            *(shutil.which(name) for name in DRIVER_NAMES),
        ],
    }
    found = {}
    for key, paths in candidates.items():
        for p in paths:
            if p and os.path.isfile(p) and os.access(p, os.X_OK):
                found[key] = p
                break
        else:
            return None
    return ChromiumPaths(**found)


class Chromium:
    """A headless Chromium window on the viewer page (context manager).

    Args:
        size: window size (width, height) [px].
        paths: browser and driver; :func:`find_chromium` when None.

    Raises:
        ViewerError: Chromium or chromedriver is missing or does not start.
    """

    def __init__(
        self, size: tuple[int, int] = (1280, 800), paths: ChromiumPaths | None = None
    ) -> None:
        try:
            from selenium import webdriver
            from selenium.common.exceptions import WebDriverException
            from selenium.webdriver.chrome.service import Service
        except ImportError as e:
            from rrt_pin.extras import MissingExtra

            raise MissingExtra("selenium", "viewer", "--screenshot") from e
        paths = paths or find_chromium()
        if paths is None:
            raise ViewerError(
                "headless Chromium not found: install Debian's chromium and chromium-driver "
                "(or set RRT_PIN_CHROMIUM and RRT_PIN_CHROMEDRIVER)"
            )
        self._profile = tempfile.mkdtemp(prefix="rrt-pin-chromium-")
        self._watchdog = subprocess.Popen(
            [sys.executable, "-I", "-c", _WATCHDOG, self._profile],
            stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
            start_new_session=True, close_fds=True,
        )  # fmt: skip
        options = webdriver.ChromeOptions()
        options.binary_location = paths.browser
        for flag in (*CHROMIUM_FLAGS, f"--window-size={size[0]},{size[1]}"):
            options.add_argument(flag)
        options.add_argument(f"--user-data-dir={self._profile}")
        # Its own session: a terminal's Ctrl-C reaches us, and we end the whole group.
        # Its log in the profile: chromedriver's command line names the profile too.
        self._service = Service(
            paths.driver,
            log_output=os.path.join(self._profile, "chromedriver.log"),
            popen_kw={"start_new_session": True},
        )
        self.driver: Any = None
        try:
            self.driver = webdriver.Chrome(service=self._service, options=options)
        except WebDriverException as e:
            self.close()
            first = (e.msg or str(e)).strip().splitlines()[0] if (e.msg or str(e)).strip() else ""
            raise ViewerError(f"headless Chromium does not start: {first}") from e
        except BaseException:
            self.close()
            raise
        self.size = size
        # the page's viewport, exactly (a window size would include the browser's frame)
        self.driver.execute_cdp_cmd(
            "Emulation.setDeviceMetricsOverride",
            {"width": size[0], "height": size[1], "deviceScaleFactor": 1, "mobile": False},
        )

    def open(self, url: str, clips: int, timeout: float = 30.0) -> None:
        """Load the viewer page at ``url`` and wait until it has the scene and ``clips`` animation clips.

        Raises:
            ViewerError: the scene is not there after ``timeout`` [s].
        """
        self.driver.set_script_timeout(timeout)
        self.driver.get(url)
        deadline = time.monotonic() + timeout
        while not self.driver.execute_script(_READY_JS, clips):
            if time.monotonic() > deadline:
                raise ViewerError(
                    f"the viewer page at {url} did not show the scene within {timeout:g} s"
                )
            time.sleep(0.05)
        self.driver.execute_async_script(_DRAWN_JS)

    def seek(self, t: float) -> None:
        """Pause the page's animation at time ``t`` [s] and wait until it is drawn."""
        self.driver.execute_async_script(_SEEK_JS, float(t))

    def png(self) -> bytes:
        """A screenshot of the window (PNG bytes)."""
        return self.driver.get_screenshot_as_png()

    def execute(self, script: str, *args: Any) -> Any:
        """Run JavaScript in the page and return its result."""
        return self.driver.execute_script(script, *args)

    def close(self) -> None:
        """Quit the browser and end every process it started; remove its profile."""
        process = getattr(self._service, "process", None)
        try:
            if self.driver is not None:
                with contextlib.suppress(Exception):
                    self.driver.quit()
            with contextlib.suppress(Exception):
                self._service.stop()
        finally:
            self.driver = None
            if process is not None:
                # chromedriver leads its own process group; the browsers are in it
                with contextlib.suppress(ProcessLookupError, PermissionError):
                    os.killpg(process.pid, signal.SIGKILL)
                with contextlib.suppress(Exception):
                    process.wait(5)
            # Chromium's processes may take a moment to die after SIGKILL: until none
            # names the profile, it can still be written to (and survive rmtree).
            deadline = time.monotonic() + 10
            spare = frozenset({self._watchdog.pid} if self._watchdog is not None else ())
            while (pids := _processes_naming(self._profile, spare)) and time.monotonic() < deadline:
                for pid in pids:
                    with contextlib.suppress(ProcessLookupError, PermissionError):
                        os.kill(pid, signal.SIGKILL)
                time.sleep(0.05)
            for _ in range(20):
                shutil.rmtree(self._profile, ignore_errors=True)
                if not os.path.exists(self._profile):
                    break
                time.sleep(0.05)
            watchdog, self._watchdog = self._watchdog, None
            if watchdog is not None:
                with contextlib.suppress(OSError, ValueError):
                    watchdog.stdin.write(b"done")
                    watchdog.stdin.close()
                with contextlib.suppress(Exception):
                    watchdog.wait(5)

    def __enter__(self) -> Chromium:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def screenshot(
    url: str,
    path: str | Path,
    *,
    clips: int,
    t: float | None = None,
    size: tuple[int, int] = (1280, 800),
    timeout: float = 30.0,
) -> Path:
    """Render the viewer page at ``url`` in headless Chromium and save a PNG atomically.

    Args:
        url: the viewer page.
        path: where the PNG goes.
        clips: number of animation clips the page must have before it counts
            as drawn (the number of moving links).
        t: animation time to show [s]; None leaves the animation as it plays.
        size: window size (width, height) [px].
        timeout: how long to wait for the page [s].
    """
    from rrt_pin.io import atomic_write_bytes

    with Chromium(size) as browser:
        browser.open(url, clips, timeout)
        if t is not None:
            browser.seek(t)
        data = browser.png()
    return atomic_write_bytes(path, data)
