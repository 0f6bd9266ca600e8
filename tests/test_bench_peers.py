"""scripts/bench/peers.py without its peers: one line naming the 'bench' extra, exit 2.

The peers themselves (mujoco, drake) are never needed here: they are hidden from the
script even where they are installed.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
MODULE = "scripts.bench.peers"  # run as python -m scripts.bench.peers from the checkout

_HIDDEN = """
import runpy, sys
for name in {hidden!r}:
    sys.modules[name] = None  # importlib.util.find_spec(name) is then None
sys.path.insert(0, {root!r})
sys.argv = [{module!r}, "--quick"]
runpy.run_module({module!r}, run_name="__main__", alter_sys=True)
"""


def _run(hidden: tuple[str, ...]) -> subprocess.CompletedProcess:
    code = _HIDDEN.format(hidden=hidden, module=MODULE, root=str(ROOT))
    return subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120
    )


def test_missing_peers_name_the_bench_extra_in_one_line():
    proc = _run(("mujoco", "pydrake"))
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    assert "mujoco, drake not installed" in lines[0]
    assert "pip install -e" in lines[0] and "[bench]'" in lines[0]


def test_missing_numba_adds_the_fast_extra():
    proc = _run(("mujoco", "pydrake", "numba"))
    assert proc.returncode == 2, proc.stderr
    assert "mujoco, drake, numba not installed" in proc.stderr
    assert "[bench,fast]'" in proc.stderr
