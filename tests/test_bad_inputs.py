"""Every bad input across the CLI: one line on stderr naming the problem, exit 2, nothing written."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from rrt_pin.cli.app import main
from tests.bad_inputs import CASES, make_files

ROOT = Path(__file__).resolve().parents[1]

#: A decimal number in a message; its significant digits are counted below.
_DECIMAL = re.compile(r"(?<![\w.])(\d+\.\d+|\.\d+)(?:e[-+]?\d+)?")


def long_decimals(text: str) -> list[str]:
    """The decimals in ``text`` printed with more than 6 significant digits.

    Their last digits differ between CPUs (AVX-512 against AVX2, BLAS kernels), so
    a message that prints them makes docs/bad-input.md depend on the machine.
    """
    found = []
    for m in _DECIMAL.finditer(text):
        digits = m.group(1).replace(".", "").lstrip("0")
        if len(digits.rstrip("0")) > 6:
            found.append(m.group(0))
    return found


@pytest.mark.parametrize("case", CASES, ids=[c.problem for c in CASES])
def test_bad_input(case, tmp_path, capsys, monkeypatch):
    make_files(tmp_path)
    for module in case.missing:  # None in sys.modules makes ``import module`` fail
        monkeypatch.setitem(sys.modules, module, None)
    for name, value in case.env:
        monkeypatch.setenv(name, value)
    before = sorted(p.name for p in tmp_path.rglob("*"))
    code = main(case.args(tmp_path))
    out, err = capsys.readouterr()
    assert code == 2, err
    assert err.count("\n") == 1 and err.startswith("rrt-pin"), err
    assert case.words in err, err
    for pattern in case.machine:  # the machine's figures are found, and apart from the words
        found = re.search(pattern, err.strip())
        assert found and case.words not in found.group(0), (pattern, err)
    assert "Traceback" not in err and out == ""
    assert not long_decimals(err), f"digits a CPU may not reproduce: {err}"
    assert sorted(p.name for p in tmp_path.rglob("*")) == before


def test_bad_input_table_is_current(tmp_path):
    proc = subprocess.run(
        [sys.executable, str(ROOT / "scripts" / "bad_input_table.py"), "--check"],
        capture_output=True,
        text=True,
        cwd=ROOT,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_long_decimals_finds_what_a_cpu_may_not_reproduce():
    assert long_decimals("stopped at t=0.00225709193 s") == ["0.00225709193"]
    assert long_decimals("step 0.0009999999999999788 s") == ["0.0009999999999999788"]
    assert long_decimals("t=0.00225709 s, rtol=2.22e-14, 1,000,001 samples, L1=1e+200") == []
    assert long_decimals("version 0.3.0 in file a1.2345678") == []
