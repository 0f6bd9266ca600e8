"""Sweeps on Dask that must not hang: schedulers that never speak Dask, clusters that lose every
worker, and SIGTERM; each ends in one line, and what was done stays for --resume.
"""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import pyarrow.parquet as pq
import pytest

import rrt_pin.sweeps.run
from rrt_pin.cli.app import main
from rrt_pin.core.errors import ClusterError
from rrt_pin.sweeps.run import sweep

pytest.importorskip("distributed")

ROOT = Path(__file__).resolve().parents[1]
SPEC = "[sweep]\ntf = 1.0\ndt = 0.1\n[vary]\nm3 = [30, 40]\n"


class _Server:
    """A TCP port on 127.0.0.1 that accepts and then does ``reply`` (never Dask's protocol)."""

    def __init__(self, reply: bytes | None, close: bool = False) -> None:
        self.reply, self.close_after = reply, close
        self.sock = socket.create_server(("127.0.0.1", 0))
        self.sock.settimeout(0.05)  # accept() wakes up to see whether to stop
        self.stopped = threading.Event()
        self.address = f"tcp://127.0.0.1:{self.sock.getsockname()[1]}"
        self.conns: list[socket.socket] = []
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while not self.stopped.is_set():
            try:
                conn, _ = self.sock.accept()
            except TimeoutError:
                continue
            self.conns.append(conn)
            if self.reply:
                conn.sendall(self.reply)
            if self.close_after:
                conn.close()

    def stop(self) -> None:
        self.stopped.set()
        self.thread.join(timeout=5)
        self.sock.close()
        for conn in self.conns:
            conn.close()


# a frame count, one frame's length, and 5 bytes that are not msgpack
_SMALL_GARBAGE = (1).to_bytes(8, "little") + (5).to_bytes(8, "little") + b"\xc1\xc1\xc1\xc1\xc1"


@pytest.mark.parametrize(
    "reply, close, words",
    [
        (None, False, "it accepted the connection but gave no Dask handshake within 1 s"),
        (
            b"HTTP/1.1 200 OK\r\n\r\n" + b"\xff" * 64,
            False,
            "it answered, but not in Dask's protocol",
        ),
        (_SMALL_GARBAGE, False, "it answered, but not in Dask's protocol"),
        (None, True, "it closed the connection without a Dask handshake"),
    ],
    ids=["silent", "garbage", "bad msgpack", "closes"],
)
def test_a_port_that_does_not_speak_dask_is_one_line(tmp_path, capsys, monkeypatch, reply, close,
                                                      words):  # fmt: skip
    monkeypatch.setattr(rrt_pin.sweeps.run, "CONNECT_TIMEOUT", 1.0)
    spec = tmp_path / "s.toml"
    spec.write_text(SPEC)
    server = _Server(reply, close)
    try:
        code = main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--no-progress",
                     "--scheduler", server.address])  # fmt: skip
    finally:
        server.stop()
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "Traceback" not in err, err
    assert f"cannot reach the Dask scheduler '{server.address}': {words}" in err, err
    assert not (tmp_path / "out").exists()


def test_a_scheduler_without_workers_is_given_up_on(tmp_path):
    from distributed import LocalCluster

    with LocalCluster(n_workers=0, processes=True, dashboard_address=":0") as cluster:
        with pytest.raises(ClusterError) as info:
            sweep({"sweep": {"tf": 1.0, "dt": 0.1}, "vary": {"m3": [30.0, 40.0]}},
                  tmp_path / "out", scheduler=cluster.scheduler_address, progress=False,
                  worker_timeout=0.5)  # fmt: skip
    message = str(info.value)
    assert f"the Dask cluster '{cluster.scheduler_address}' has had no worker for 0.5 s" in message
    assert info.value.seconds == 0.5 and "\n" not in message


def test_a_cluster_that_loses_every_worker_stops_and_resume_finishes(tmp_path):
    """One worker (no nanny to restart it) killed after the first chunk: one line, then resume."""
    from distributed import LocalCluster

    spec = {"sweep": {"tf": 1.0, "dt": 0.1, "chunk": 2}, "vary": {"m3": [30.0, 35.0, 40.0, 45.0,
                                                                           50.0, 55.0, 60.0, 65.0]}}  # fmt: skip
    out = tmp_path / "out"
    with LocalCluster(n_workers=0, processes=True, dashboard_address=":0") as cluster:
        worker = subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", cluster.scheduler_address,
             "--no-nanny", "--nthreads", "1", "--no-dashboard"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT,
        )  # fmt: skip
        try:
            killed = []

            def kill_after_first(k: int, chunk: dict) -> None:
                if not killed:
                    os.kill(worker.pid, signal.SIGKILL)
                    worker.wait(timeout=30)
                    killed.append(k)

            with pytest.raises(ClusterError) as info:
                sweep(spec, out, scheduler=cluster.scheduler_address, workers=1, progress=False,
                      on_chunk=kill_after_first, worker_timeout=1.0)  # fmt: skip
        finally:
            if worker.poll() is None:
                worker.kill()
                worker.wait(timeout=30)
    assert "has had no worker for 1 s" in str(info.value)
    assert "the chunks done are kept" in str(info.value)
    kept = sorted(p.name for p in (out / "chunks").glob("chunk-*.parquet"))
    assert 1 <= len(kept) < 4  # the first chunk at least, not all
    result = sweep(spec, out, workers=1, resume=True, progress=False)
    assert result.computed == 4 - len(kept)
    table = pq.read_table(out / "chunks")
    assert sorted(table.column("variant").to_pylist()) == list(range(8))


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM], ids=["SIGINT", "SIGTERM"])
def test_a_signal_ends_a_sweep_with_one_line_and_the_resume_hint(tmp_path, signum):
    spec = tmp_path / "s.toml"
    spec.write_text("[sweep]\ntf = 1.0\ndt = 0.1\nchunk = 1\n[vary]\nm3 = { linspace = "
                    "[30, 60, 4000] }\n")  # fmt: skip
    out = tmp_path / "out"
    proc = subprocess.Popen(
        [sys.executable, "-m", "rrt_pin", "sweep", str(spec), "--out", str(out), "--workers", "1",
         "--no-progress"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT,
    )  # fmt: skip
    try:
        deadline = time.monotonic() + 120
        while not list(out.glob("chunks/chunk-*.parquet")):  # a chunk stored: the sweep runs
            assert proc.poll() is None, proc.communicate()
            assert time.monotonic() < deadline, "no chunk within 120 s"
            time.sleep(0.05)
        proc.send_signal(signum)
        stdout, stderr = proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
    assert proc.returncode == 130, stderr
    assert stderr == (f"rrt-pin: interrupted; the chunks done are kept in {str(out)!r}: "
                      "add --resume to continue\n"), stderr  # fmt: skip
    assert stdout == ""
