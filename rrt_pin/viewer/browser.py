"""Headless Chromium driven by selenium: load the viewer page, wait for the scene, screenshot it.

Uses Debian's ``/usr/bin/chromium`` and ``/usr/bin/chromedriver`` (or the
``RRT_PIN_CHROMIUM`` / ``RRT_PIN_CHROMEDRIVER`` environment variables, or
``chromium``/``chromedriver`` on PATH). The browser runs with a fresh temporary
profile and no network beyond the viewer's own address; every process it
starts is ended on exit, Ctrl-C included. Times in seconds [s], sizes in pixels.

Everything the browser writes goes into one private folder,
``$TMPDIR/rrt-pin-chromium-XXXXXXXX/``: the throw-away profile (``profile/``),
chromedriver's log, Chromium's and chromedriver's own temporary files
(``org.chromium.Chromium.*``: both run with ``TMPDIR`` pointing at the folder),
and what Chromium would put in ``~/.config`` and ``~/.cache`` (``XDG_CONFIG_HOME``,
``XDG_CACHE_HOME``). Chromium's socket paths must fit in 107 bytes, so when
``$TMPDIR`` is longer than :data:`MAX_TMPDIR` (36) bytes the folder is made in
``/tmp`` instead. Nothing outlives us:

* closing (a normal end, an error, Ctrl-C, and SIGTERM or SIGHUP, which
  ``rrt-pin view`` turns into Ctrl-C) ends every process and removes the folder;
* a SIGKILL: a watchdog process (its own session, so a terminal's signals and
  a killed process group spare it) holds the read end of a pipe whose write end
  only this process has. When this process ends without saying "done" on it,
  the pipe closes and the watchdog kills every process whose command line names
  the folder (chromedriver, whose log is there, and every Chromium process),
  then removes it;
* the watchdog killed too (``kill -9`` of both, the OOM killer): the folder
  holds the pids of its owners (this process and the watchdog) with their start
  times; the next :class:`Chromium` of the same user, in the same temporary
  folder, ends the processes naming a folder whose owners are all dead and
  removes it (:func:`remove_stale_folders`).
"""

from __future__ import annotations

import contextlib
import os
import shutil
import signal
import stat
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from rrt_pin.core.errors import ViewerError
from rrt_pin.core.extras import MissingExtra
from rrt_pin.io.files import atomic_write_bytes

__all__ = [
    "BROWSER_NAMES",
    "CHROMIUM_FLAGS",
    "DRIVER_NAMES",
    "FOLDER_PREFIX",
    "Chromium",
    "MAX_TMPDIR",
    "find_chromium",
    "folder_base",
    "remove_stale_folders",
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
# the private folder. It waits for EOF on stdin; unless it read b"done", it kills
# every process whose command line names the folder, until none is left, then
# removes the folder.
_WATCHDOG = r"""
import os, shutil, signal, sys, time
folder = sys.argv[1]
marker = (folder.rstrip("/") + "/").encode()
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
said = sys.stdin.buffer.read()
def marked():
    out = []
    for name in os.listdir("/proc") if os.path.isdir("/proc") else ():
        if name.isdigit() and int(name) != os.getpid():
            try:
                with open(f"/proc/{name}/cmdline", "rb") as fh:
                    if marker in fh.read():
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
        shutil.rmtree(folder, ignore_errors=True)
        if not os.path.exists(folder):
            break
        time.sleep(0.1)
"""


#: The private folders' names start with this (in the temporary folder, ``$TMPDIR``).
FOLDER_PREFIX = "rrt-pin-chromium-"
#: The file of a private folder that names its owners: ``pid start-time`` per line.
_OWNERS = "owners"
#: A private folder without owners (being made) is left alone this long [s].
_MAKING = 60.0
#: The longest temporary folder path the private folder can be made in [bytes]:
#: Chromium's singleton socket, ``FOLDER/org.chromium.Chromium.XXXXXX/SingletonSocket``
#: with ``FOLDER`` = ``TMPDIR/rrt-pin-chromium-XXXXXXXX``, must fit in a Unix socket
#: address (107 bytes), else Chromium exits at once ("Socket path too long").
MAX_TMPDIR = (
    107
    - len("/org.chromium.Chromium.XXXXXX/SingletonSocket")
    - len("/" + FOLDER_PREFIX + "XXXXXXXX")
)


def _processes_naming(folder: str, exclude: frozenset[int] = frozenset()) -> list[int]:
    """Pids of the processes whose command line names a path in ``folder`` (Linux /proc; else none)."""
    marker = (folder.rstrip(os.sep) + os.sep).encode()
    pids = []
    with contextlib.suppress(OSError):
        for name in os.listdir("/proc"):
            if name.isdigit() and int(name) not in exclude:
                with contextlib.suppress(OSError), open(f"/proc/{name}/cmdline", "rb") as fh:
                    if marker in fh.read():
                        pids.append(int(name))
    return pids


def _start_time(pid: int) -> int | None:
    """When process ``pid`` started [clock ticks since boot], None if it is not running.

    With the pid, this names one process even after the pid is reused. A
    zombie counts as not running. Where there is no /proc, 0 for any process
    that exists.
    """
    try:
        with open(f"/proc/{pid}/stat", "rb") as fh:
            fields = fh.read().rsplit(b")", 1)[1].split()
        if fields[0] in (b"Z", b"X"):  # a zombie: dead, not yet reaped
            return None
        return int(fields[19])  # field 22 of proc(5); fields[0] is field 3
    except FileNotFoundError:
        return None
    except (OSError, IndexError, ValueError):
        pass
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except OSError:
        pass
    return 0


def _add_owner(folder: str, pid: int) -> None:
    """Name process ``pid`` among the owners of the private ``folder``."""
    with open(os.path.join(folder, _OWNERS), "a", encoding="ascii") as fh:
        fh.write(f"{pid} {_start_time(pid) or 0}\n")


def _owners_alive(folder: str) -> bool | None:
    """Whether an owner of ``folder`` still runs; None when it names none (being made)."""
    try:
        with open(os.path.join(folder, _OWNERS), encoding="ascii") as fh:
            text = fh.read(4096)
    except OSError:
        return None
    owners = []
    for line in text.splitlines():
        with contextlib.suppress(ValueError):
            pid, start = (int(word) for word in line.split())
            owners.append((pid, start))
    if not owners:
        return None
    return any(_start_time(pid) in (start, 0) for pid, start in owners if pid > 0)


def folder_base() -> str:
    """Where the private folder is made: the temporary folder, or /tmp if that path is long.

    ``/tmp`` is used when the temporary folder's path (``$TMPDIR``) is longer
    than :data:`MAX_TMPDIR` bytes.

    Raises:
        ViewerError: the temporary folder's path is too long and /tmp is not usable.
    """
    base = tempfile.gettempdir()
    if len(os.fsencode(base)) <= MAX_TMPDIR:
        return base
    if os.path.isdir("/tmp") and os.access("/tmp", os.W_OK | os.X_OK):
        return "/tmp"
    raise ViewerError(
        f"the temporary folder {base!r} is {len(os.fsencode(base))} bytes long; Chromium needs "
        f"one of at most {MAX_TMPDIR} bytes (its socket paths): set TMPDIR to a shorter one"
    )


def remove_stale_folders(where: str | None = None) -> list[str]:
    """Remove the private folders of earlier runs that were killed with their watchdog.

    A folder in ``where`` (default: the temporary folder, ``$TMPDIR``) is
    stale when its name starts with :data:`FOLDER_PREFIX`, it belongs to this
    user, it is a real folder (not a link) and none of the owners it names (pid
    and start time) runs; the processes of this user whose command line names
    it (a Chromium left running) are killed first. A folder that names no owner
    (being made, or made by an older rrt-pin) is stale once it is 60 s old and
    no process names it.

    Returns:
        The folders removed.
    """
    where = where or tempfile.gettempdir()
    removed = []
    uid = os.getuid() if hasattr(os, "getuid") else None
    try:
        entries = [e for e in os.scandir(where) if e.name.startswith(FOLDER_PREFIX)]
    except OSError:
        return removed
    for entry in entries:
        try:
            info = entry.stat(follow_symlinks=False)
        except OSError:
            continue
        if not stat.S_ISDIR(info.st_mode) or (uid is not None and info.st_uid != uid):
            continue
        alive = _owners_alive(entry.path)
        users = _processes_naming(entry.path, frozenset({os.getpid()}))
        if alive or (alive is None and (users or time.time() - info.st_mtime < _MAKING)):
            continue  # in use, being made, or (named by no owner) used by a process
        for pid in users:
            with contextlib.suppress(OSError):
                if uid is None or os.stat(f"/proc/{pid}").st_uid == uid:
                    os.kill(pid, signal.SIGKILL)
        _remove(entry.path, [])
        if not os.path.lexists(entry.path):
            removed.append(entry.path)
    return removed


def _remove(folder: str, spare: list[int], seconds: float = 10.0) -> None:
    """Kill the processes naming ``folder`` (but ``spare``), then remove it."""
    deadline = time.monotonic() + seconds
    # Chromium's processes may take a moment to die after SIGKILL: until none
    # names the folder, they can still write to it (and survive rmtree).
    while (pids := _processes_naming(folder, frozenset(spare))) and time.monotonic() < deadline:
        for pid in pids:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.kill(pid, signal.SIGKILL)
        time.sleep(0.05)
    for _ in range(20):
        shutil.rmtree(folder, ignore_errors=True)
        if not os.path.lexists(folder):
            break
        time.sleep(0.05)


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
            raise MissingExtra("selenium", "viewer", "--screenshot") from e
        paths = paths or find_chromium()
        if paths is None:
            raise ViewerError(
                "headless Chromium not found: install Debian's chromium and chromium-driver "
                "(or set RRT_PIN_CHROMIUM and RRT_PIN_CHROMEDRIVER)"
            )
        base = folder_base()
        for where in dict.fromkeys((tempfile.gettempdir(), base)):
            remove_stale_folders(where)
        try:
            self._folder = tempfile.mkdtemp(prefix=FOLDER_PREFIX, dir=base)
        except OSError as e:
            raise ViewerError(
                f"cannot make a folder for Chromium in {base!r}: {e.strerror}"
            ) from None
        self._watchdog: subprocess.Popen[bytes] | None = None
        self._service: Any = None
        self.driver: Any = None
        try:
            _add_owner(self._folder, os.getpid())
            self._watchdog = subprocess.Popen(
                [sys.executable, "-I", "-c", _WATCHDOG, self._folder],
                stdin=subprocess.PIPE, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                start_new_session=True, close_fds=True,
            )  # fmt: skip
            _add_owner(self._folder, self._watchdog.pid)
            profile = os.path.join(self._folder, "profile")
            os.mkdir(profile, 0o700)
            options = webdriver.ChromeOptions()
            options.binary_location = paths.browser
            for flag in (*CHROMIUM_FLAGS, f"--window-size={size[0]},{size[1]}"):
                options.add_argument(flag)
            options.add_argument(f"--user-data-dir={profile}")
            # Its own session: a terminal's Ctrl-C reaches us, and we end the whole group.
            # Its log in the folder: chromedriver's command line names the folder too.
            # TMPDIR: chromedriver's and Chromium's own temporary files go in the folder
            # (itself, not a subfolder: see MAX_TMPDIR); XDG_*: so do Chromium's "Crash
            # Reports" settings and dconf's cache (else made in ~/.config and ~/.cache).
            env = {
                **os.environ,
                **dict.fromkeys(("TMPDIR", "TMP", "TEMP"), self._folder),
                "XDG_CONFIG_HOME": os.path.join(self._folder, "config"),
                "XDG_CACHE_HOME": os.path.join(self._folder, "cache"),
            }
            self._service = Service(
                paths.driver,
                log_output=os.path.join(self._folder, "chromedriver.log"),
                env=env,
                popen_kw={"start_new_session": True},
            )
        except OSError as e:
            self.close()
            raise ViewerError(
                f"cannot prepare Chromium's folder {self._folder!r}: {e.strerror or e}"
            ) from None
        except BaseException:
            self.close()
            raise
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

    @property
    def folder(self) -> str:
        """The private folder of this browser (its profile, log and temporary files)."""
        return self._folder

    def close(self) -> None:
        """Quit the browser and end every process it started; remove its folder."""
        process = getattr(self._service, "process", None)
        try:
            if self.driver is not None:
                with contextlib.suppress(Exception):
                    self.driver.quit()
            if self._service is not None:
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
            spare = [self._watchdog.pid] if self._watchdog is not None else []
            _remove(self._folder, spare)
            watchdog, self._watchdog = self._watchdog, None
            if watchdog is not None:
                with contextlib.suppress(OSError, ValueError):
                    watchdog.stdin.write(b"done")  # type: ignore[union-attr]
                    watchdog.stdin.close()  # type: ignore[union-attr]
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
    with Chromium(size) as browser:
        browser.open(url, clips, timeout)
        if t is not None:
            browser.seek(t)
        data = browser.png()
    return atomic_write_bytes(path, data)
