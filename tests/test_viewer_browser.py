"""The viewer in a real browser: headless Chromium (Debian's chromium + chromedriver).

Skipped with a reason where Chromium is missing, except in CI (CI=true), where
a missing browser fails the tests.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from rrt_pin.viewer.browser import find_chromium

pytestmark = pytest.mark.browser

FPS = 30.0
SIZE = (800, 500)


@pytest.fixture(scope="module")
def chromium_paths():
    paths = find_chromium()
    if paths is None:
        reason = "headless Chromium not found (apt-get install chromium chromium-driver)"
        if os.environ.get("CI") == "true":
            pytest.fail(f"{reason}; CI must run the browser tests")
        pytest.skip(reason)
    return paths


@pytest.fixture(scope="module")
def served(chromium_paths):
    """The seed's eq. (30) motion, served; yields (server, scene)."""
    from rrt_pin.dynamics.trajectory import rest_to_rest
    from rrt_pin.robot.model import build_geometry, rrt_model
    from rrt_pin.robot.params import Params
    from rrt_pin.robot.urdf import urdf_xml
    from rrt_pin.viewer import build_drawing, keyframe_times
    from rrt_pin.viewer.meshcat_scene import scene_commands
    from rrt_pin.viewer.server import ViewerServer

    p = Params()
    model = rrt_model(p)
    t = keyframe_times(p.Tp, FPS)
    q = rest_to_rest(p.q0, p.qf, p.Tp, t).q
    drawing = build_drawing(model, build_geometry(model, urdf_xml(p)), t, q, FPS, ghost_q=p.qf)
    with ViewerServer(port=0) as server:
        for command in scene_commands(drawing):
            server.send(command)
        yield server, drawing


@pytest.fixture(scope="module")
def browser(served, chromium_paths):
    from rrt_pin.viewer.browser import Chromium

    server, scene = served
    with Chromium(SIZE, chromium_paths) as b:
        b.open(server.url, clips=len(scene.keyframes.frames))
        yield b


def _visible(server, path: str, visible: bool) -> None:
    from meshcat.commands import SetProperty
    from meshcat.path import Path

    server.send(SetProperty("visible", visible, Path().append(path)))


def _pixels(png: bytes) -> tuple[np.ndarray, np.ndarray]:
    """RGB (H, W, 3) and HSV (H, W, 3) arrays, values 0..255."""
    import io

    from PIL import Image

    image = Image.open(io.BytesIO(png)).convert("RGB")
    return np.asarray(image).astype(int), np.asarray(image.convert("HSV")).astype(int)


# Colours of the URDF's links, as hue [0..255 = 0..360°] and minimum saturation.
LINK_HUES = {
    "orange link 1 (0.95 0.5 0.1)": (21, 0.75),  # 25.5°
    "blue link 2 (0.15 0.4 0.85)": (155, 0.75),  # 218.6°
    "green slider (0.2 0.7 0.3)": (94, 0.6),  # 132°
}


def _hue_mask(hsv: np.ndarray, hue: int, min_sat: float, tol: int = 6) -> np.ndarray:
    dh = np.abs(hsv[..., 0] - hue)
    dh = np.minimum(dh, 256 - dh)
    return (dh <= tol) & (hsv[..., 1] >= 255 * min_sat) & (hsv[..., 2] >= 40)


def _shot(browser, server, t: float, arm: bool = True, ghost: bool = False) -> bytes:
    _visible(server, "/meshcat/arm", arm)
    _visible(server, "/meshcat/ghost", ghost)
    browser.seek(t)
    return browser.png()


def test_screenshot_shows_the_arm_in_its_colours(served, browser):
    server, _ = served
    with_arm = _shot(browser, server, 0.0, arm=True)
    without = _shot(browser, server, 0.0, arm=False)
    rgb1, hsv1 = _pixels(with_arm)
    rgb0, hsv0 = _pixels(without)
    assert rgb1.shape == (SIZE[1], SIZE[0], 3)
    changed = np.abs(rgb1 - rgb0).max(axis=2) > 30
    assert changed.sum() > 5000  # the arm covers a good part of the picture
    for name, (hue, sat) in LINK_HUES.items():
        arm_pixels = (_hue_mask(hsv1, hue, sat) & changed).sum()
        before = _hue_mask(hsv0, hue, sat).sum()
        assert arm_pixels > 300, f"{name}: only {arm_pixels} pixels with the arm"
        assert arm_pixels > 5 * before, f"{name}: {arm_pixels} with the arm, {before} without"
    _visible(server, "/meshcat/arm", True)


def _js_placement(browser, link: str) -> np.ndarray:
    """World placement of an arm link in the page, relative to the drawing's root (4×4)."""
    elements = browser.execute(
        """
        const node = viewer.scene_tree.find(["meshcat", "arm", arguments[0]]).object;
        const root = viewer.scene_tree.find(["meshcat"]).object;
        viewer.scene.updateMatrixWorld(true);
        const rel = root.matrixWorld.clone().invert().multiply(node.matrixWorld);
        return Array.from(rel.elements);
        """,
        link,
    )
    return np.array(elements).reshape(4, 4).T  # three.js stores columns


def test_two_animation_times_show_two_poses(served, browser):
    server, scene = served
    kf = scene.keyframes
    masks = []
    for k in (0, 225, 450):  # t = 0, 7.5 s, 15 s
        png = _shot(browser, server, kf.t[k], arm=True)
        # the page's pose is the keyframe's (the animation runs in the page)
        for i, link in enumerate(kf.frames):
            assert np.allclose(_js_placement(browser, link), kf.transforms[k, i], atol=1e-5)
        _, hsv = _pixels(png)
        masks.append(_hue_mask(hsv, *LINK_HUES["orange link 1 (0.95 0.5 0.1)"]))
    first, middle, last = masks
    overlap = (first & last).sum() / max((first | last).sum(), 1)
    assert first.sum() > 300 and last.sum() > 300
    assert overlap < 0.5, f"link 1 barely moved on screen: overlap {overlap:.2f}"
    assert (middle ^ first).sum() > 300 and (middle ^ last).sum() > 300


def test_the_page_plays_and_loops_by_itself(served, browser):
    _, scene = served
    browser.seek(scene.keyframes.duration - 0.2)
    start = browser.execute("viewer.animator.play(); return viewer.animator.time;")
    assert start == pytest.approx(scene.keyframes.duration - 0.2)
    deadline = time.monotonic() + 10
    # no Python in the loop: the page's clock runs the animation past the end and
    # starts over (repetitions = Infinity)
    while browser.execute("return viewer.animator.time;") > 1.0:
        assert time.monotonic() < deadline, "the animation did not loop"
        time.sleep(0.05)
    assert browser.execute("return viewer.animator.playing;")
    browser.seek(0.0)
    assert not browser.execute("return viewer.animator.playing;")


def test_two_browsers_watch_at_once(served, browser, chromium_paths):
    from rrt_pin.viewer.browser import Chromium

    server, scene = served
    with Chromium(SIZE, chromium_paths) as second:
        second.open(server.url, clips=len(scene.keyframes.frames))
        assert server.n_clients == 2
        orange = LINK_HUES["orange link 1 (0.95 0.5 0.1)"]
        for b in (browser, second):
            b.seek(0.0)
            assert _hue_mask(_pixels(b.png())[1], *orange).sum() > 300
        # a live change reaches both pages
        _visible(server, "/meshcat/arm", False)
        _visible(server, "/meshcat/ghost", False)
        for b in (browser, second):
            deadline = time.monotonic() + 10
            while b.execute('return viewer.scene_tree.find(["meshcat", "arm"]).object.visible'):
                assert time.monotonic() < deadline
                time.sleep(0.05)
            b.seek(0.0)
            assert _hue_mask(_pixels(b.png())[1], *orange).sum() < 100
        _visible(server, "/meshcat/arm", True)
        _visible(server, "/meshcat/ghost", True)
    deadline = time.monotonic() + 10
    while server.n_clients != 1:
        assert time.monotonic() < deadline
        time.sleep(0.05)


def _descendants(pid: int):
    import psutil

    try:
        return psutil.Process(pid).children(recursive=True)
    except psutil.NoSuchProcess:
        return []


def _watch(pid: int, seen: dict, names: set[str]) -> None:
    """Add ``pid``'s descendants to ``seen`` and every one's name now to ``names``.

    Every name is read again at each call: one read mid-exec is the launcher's ("exe").
    """
    import psutil

    for p in _descendants(pid):
        seen.setdefault(p.pid, p)
    for p in seen.values():
        try:
            names.add(p.name())
        except psutil.NoSuchProcess:
            pass


def _all_gone(procs, timeout: float = 15.0) -> list:
    import psutil

    _, alive = psutil.wait_procs(procs, timeout=timeout)
    return [p for p in alive if p.is_running() and p.status() != psutil.STATUS_ZOMBIE]


def test_cli_screenshot_is_written_and_leaves_no_process(tmp_path, chromium_paths):
    import psutil
    from PIL import Image

    out = tmp_path / "view.png"
    proc = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "rrt_pin",
            "view",
            "--port",
            "0",
            "--screenshot",
            str(out),
            "--screenshot-time",
            "7.5",
            "--screenshot-size",
            "640x400",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    seen: dict[int, psutil.Process] = {}
    names: set[str] = set()
    try:
        while proc.poll() is None:
            _watch(proc.pid, seen, names)
            time.sleep(0.05)
        assert proc.returncode == 0, proc.stderr.read()
    finally:
        proc.kill()
    assert {"chromedriver", "chromium"} <= names  # the browser ran, as children of rrt-pin
    assert _all_gone(list(seen.values())) == []
    assert proc.stdout.read().startswith("http://127.0.0.1:")
    assert "wrote" in proc.stderr.read()
    image = Image.open(out)
    assert image.format == "PNG" and image.size == (640, 400)
    assert [p.name for p in tmp_path.iterdir()] == ["view.png"]  # no temporary file left


def test_sigint_during_a_screenshot_ends_chromium_too(tmp_path, chromium_paths):
    import psutil

    out = tmp_path / "never.png"
    names: set[str] = set()
    proc = subprocess.Popen(
        [sys.executable, "-m", "rrt_pin", "view", "--port", "0", "--screenshot", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    seen: dict[int, psutil.Process] = {}
    try:
        deadline = time.monotonic() + 60
        while "chromium" not in names:
            assert proc.poll() is None, proc.stderr.read()
            assert time.monotonic() < deadline
            _watch(proc.pid, seen, names)
            time.sleep(0.02)
        for p in _descendants(proc.pid):
            seen.setdefault(p.pid, p)
        os.kill(proc.pid, signal.SIGINT)
        code = proc.wait(30)
    finally:
        proc.kill()
    assert code == 130, proc.stderr.read()
    assert "rrt-pin: interrupted" in proc.stderr.read()
    assert _all_gone(list(seen.values())) == []
    assert not out.exists() and list(tmp_path.iterdir()) == []
