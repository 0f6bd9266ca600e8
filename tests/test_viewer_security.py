"""The viewer answers only to its own host names (DNS rebinding) and never prints a traceback."""

from __future__ import annotations

import re
import socket
import subprocess
import sys
import time

import pytest

from rrt_pin.viewer.server import ViewerServer, allowed_host

pytest.importorskip("meshcat")

WS = (
    "Upgrade: websocket\r\nConnection: Upgrade\r\n"
    "Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n"
)


def _status(port: int, path: str, host: str | None, extra: str = "") -> int:
    head = f"GET {path} HTTP/1.1\r\n" + (f"Host: {host}\r\n" if host is not None else "")
    with socket.create_connection(("127.0.0.1", port), timeout=10) as s:
        s.sendall((head + extra + "\r\n").encode())
        line = s.recv(4096).split(b"\r\n", 1)[0].decode()
    return int(line.split()[1])


@pytest.mark.parametrize(
    "header, bound, ok",
    [
        ("127.0.0.1:7000", "127.0.0.1", True),
        ("localhost:7000", "127.0.0.1", True),
        ("LOCALHOST", "127.0.0.1", True),
        ("[::1]:7000", "127.0.0.1", True),
        ("evil.example:7000", "127.0.0.1", False),  # a rebound name
        ("evil.example", "0.0.0.0", False),  # even when listening everywhere
        ("127.0.0.1.evil.example", "127.0.0.1", False),
        ("10.0.0.5:7000", "127.0.0.1", False),  # another machine's address
        ("10.0.0.5:7000", "0.0.0.0", True),  # listening everywhere: any IP literal
        ("10.0.0.5", "10.0.0.5", True),
        ("viewer.lab:7000", "viewer.lab", True),  # the --host name given
        ("", "127.0.0.1", False),
        (None, "127.0.0.1", False),
    ],
)
def test_allowed_host(header, bound, ok):
    assert allowed_host(header, bound) is ok


def test_foreign_hosts_get_403_for_page_files_and_websocket():
    with ViewerServer("127.0.0.1", 0) as server:
        p = server.port
        assert _status(p, "/static/", f"127.0.0.1:{p}") == 200
        assert _status(p, "/static/", f"localhost:{p}") == 200
        for path in ("/static/", "/static/index.html", "/favicon.ico", "/", "/elsewhere"):
            assert _status(p, path, f"evil.example:{p}") == 403, path
        assert _status(p, "/static/", None) in (400, 403)  # HTTP/1.1 without Host
        assert _status(p, "/", f"evil.example:{p}", WS) == 403
        assert _status(p, "/", f"127.0.0.1:{p}", WS + "Origin: http://evil.example\r\n") == 403
        assert _status(p, "/", f"127.0.0.1:{p}", WS + f"Origin: http://127.0.0.1:{p}\r\n") == 101
        assert server.n_clients <= 1  # only the last, legitimate one could connect


def test_malformed_paths_are_400_and_no_traceback_reaches_the_terminal(tmp_path):
    proc = subprocess.Popen(
        [sys.executable, "-m", "rrt_pin", "view", "--port", "0", "--serve-for", "20"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=tmp_path,
    )  # fmt: skip
    try:
        url = proc.stdout.readline()
        port = int(re.search(r":(\d+)/", url).group(1))
        assert _status(port, "/static/%00", f"127.0.0.1:{port}") == 400
        assert _status(port, "/static/a%00b.js", f"127.0.0.1:{port}") == 400
        assert _status(port, "/static/../../../etc/passwd", f"127.0.0.1:{port}") in (403, 404)
        assert _status(port, "/static/", f"evil.example:{port}") == 403
        time.sleep(0.3)
    finally:
        proc.terminate()
        _, err = proc.communicate(timeout=30)
    assert "Traceback" not in err and "ValueError" not in err, err
