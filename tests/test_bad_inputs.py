"""Every bad input across the CLI: one line on stderr naming the problem, exit 2, nothing written."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from rrt_pin.cli import main
from tests.bad_inputs import CASES, make_files

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("case", CASES, ids=[c.problem for c in CASES])
def test_bad_input(case, tmp_path, capsys, monkeypatch):
    make_files(tmp_path)
    for module in case.missing:  # None in sys.modules makes ``import module`` fail
        monkeypatch.setitem(sys.modules, module, None)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    code = main(case.args(tmp_path))
    out, err = capsys.readouterr()
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("rrt-pin"), err
    assert case.words in err, err
    assert "Traceback" not in err and out == ""
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_bad_input_table_is_current(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "bad_input_table.py"), "--check"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
