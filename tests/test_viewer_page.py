"""The viewer page names the robot, says what is drawn and when; show(); --zmq-url; Chromium's names."""

from __future__ import annotations

import re
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

pytest.importorskip("meshcat")

from rrt_pin.viewer.page import LegendEntry, page_html  # noqa: E402


def test_page_html_has_title_legend_and_readout_escaped():
    index = "<html><head><title>MeshCat</title></head><body><div id=x></div></body></html>"
    page = page_html(index, "arm <b>&</b>", [LegendEntry("path of <link3>", "#d81b9a", "line")])
    assert "<title>arm &lt;b&gt;&amp;&lt;/b&gt;</title>" in page
    assert "path of &lt;link3&gt;" in page and "background:#d81b9a" in page
    assert 'id="rrt-pin-time"' in page and "requestAnimationFrame" in page
    assert page.count("<body>") == 1
    assert page.index('id="rrt-pin-overlay"') > page.index("<body>")


def test_show_serves_a_result_and_closes():
    from rrt_pin import show
    from rrt_pin.robot.params import Params
    from rrt_pin.robot.robots import chapter_arm
    from rrt_pin.simulate import simulate
    from rrt_pin.simulate.control import chapter_controller

    p = Params()
    run = simulate(chapter_arm(p), chapter_controller(p), p.q0, p.qd0, np.linspace(0, 2, 21),
                   estimate_error=False)  # fmt: skip
    url = show(run, port=0)
    try:
        assert isinstance(url, str) and url.startswith("http://127.0.0.1:")
        body = urllib.request.urlopen(url, timeout=10).read().decode()
        assert "<title>RRT arm: motion</title>" in body and "target qf" in body
        assert "<iframe" in url._repr_html_() and url in url._repr_html_()
    finally:
        url.close()
    with pytest.raises(OSError):
        urllib.request.urlopen(url, timeout=2)


def test_a_result_remembers_its_robot_for_show_and_is_pickled_without_it():
    import pickle

    from rrt_pin import show
    from rrt_pin.robot.robots import get
    from rrt_pin.simulate import simulate
    from rrt_pin.simulate.control import pd_gravity_controller

    ur5 = get("ur5")
    qf = np.full(6, 0.2)
    run = simulate(ur5, pd_gravity_controller(ur5, 100.0, 20.0, qf), np.zeros(6), None,
                   np.linspace(0, 0.5, 6), estimate_error=False)  # fmt: skip
    assert run.robot is ur5 and run.q.shape == (6, 6)
    url = show(run, port=0)  # no robot=: the result's own
    try:
        body = urllib.request.urlopen(url, timeout=10).read().decode()
        assert "motion</title>" in body and "RRT arm" not in body
    finally:
        url.close()
    back = pickle.loads(pickle.dumps(run))
    assert back.robot is None and np.array_equal(back.q, run.q) and back.q_names == run.q_names


def test_show_needs_a_robot_for_other_results():
    from rrt_pin import show
    from rrt_pin.core.errors import InputError

    class Result:
        t = np.linspace(0, 1, 3)
        q = np.zeros((3, 6))
        q_names = tuple(f"q_j{i}" for i in range(6))

    with pytest.raises(InputError, match="needs robot="):
        show(Result())
    with pytest.raises(InputError, match="needs a result with t and q"):
        show(object())


def test_page_in_a_browser_shows_title_legend_and_running_time():
    from rrt_pin.viewer.browser import Chromium, find_chromium

    if find_chromium() is None:
        pytest.skip("needs chromium and chromedriver")
    proc = subprocess.Popen(
        [sys.executable, "-m", "rrt_pin", "view", "--port", "0", "--serve-for", "60"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        url = proc.stdout.readline().strip()
        with Chromium((800, 600)) as browser:
            browser.open(url, clips=1)
            title = browser.execute("return document.title")
            overlay = browser.execute("return document.getElementById('rrt-pin-overlay').innerText")
            first = browser.execute("return document.getElementById('rrt-pin-time').textContent")
            time.sleep(0.6)
            later = browser.execute("return document.getElementById('rrt-pin-time').textContent")
        assert title.startswith("RRT arm") and "eq. (30)" in title  # view plays eq. (30)
        for words in ("arm (moving)", "target qf (translucent ghost)", "path of link3"):
            assert words in overlay, overlay
        pattern = r"t = (\d+\.\d\d) s of 15\.00 s"
        assert re.fullmatch(pattern, first) and re.fullmatch(pattern, later), (first, later)
        assert first != later  # the animation plays and the readout follows it
    finally:
        proc.terminate()
        proc.wait(30)


def test_zmq_url_sends_to_the_users_meshcat_server():
    import zmq
    from meshcat.servers.zmqserver import start_zmq_server_as_subprocess

    def scene_html() -> str:
        sock = zmq.Context.instance().socket(zmq.REQ)
        sock.setsockopt(zmq.RCVTIMEO, 10_000)
        sock.connect(zmq_url)
        sock.send(b"get_scene")
        try:
            return sock.recv().decode()
        finally:
            sock.close(0)

    server, zmq_url, web_url = start_zmq_server_as_subprocess()
    try:
        empty = scene_html()
        proc = subprocess.run([sys.executable, "-m", "rrt_pin", "view", "--zmq-url", zmq_url],
                              capture_output=True, text=True, timeout=120)  # fmt: skip
        assert proc.returncode == 0, proc.stderr
        assert proc.stdout.strip() == web_url  # that server's page, where the user looks
        scene = scene_html()
        # The page embeds the scene it holds: now the arm's shapes and its keyframes.
        assert len(scene) > len(empty) + 100_000
    finally:
        server.kill()
        server.wait(10)


def test_zmq_url_with_no_server_is_one_line_not_a_hang():
    start = time.monotonic()
    proc = subprocess.run(
        [sys.executable, "-m", "rrt_pin", "view", "--zmq-url", "tcp://127.0.0.1:9"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1, proc.stderr
    assert "no meshcat server answered" in proc.stderr and "meshcat-server" in proc.stderr
    assert time.monotonic() - start < 60


def test_chrome_and_chromium_are_found_under_their_usual_names(tmp_path, monkeypatch):
    import os

    from rrt_pin.viewer import browser

    for name in ("google-chrome", "chromium-driver"):
        exe = tmp_path / name
        exe.write_text("#!/bin/sh\n")
        exe.chmod(0o755)
    monkeypatch.setenv("PATH", str(tmp_path))
    monkeypatch.delenv("RRT_PIN_CHROMIUM", raising=False)
    monkeypatch.delenv("RRT_PIN_CHROMEDRIVER", raising=False)
    real = os.path.isfile
    monkeypatch.setattr(
        browser.os.path, "isfile", lambda p: not str(p).startswith("/usr/bin/") and real(p)
    )
    found = browser.find_chromium()
    assert found is not None
    assert found.browser == str(tmp_path / "google-chrome")
    assert found.driver == str(tmp_path / "chromium-driver")
