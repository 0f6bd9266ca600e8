"""Missing optional extras: one error type, and an install hint that works where the user is."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path

import pytest

from rrt_pin.core.errors import RrtPinError
from rrt_pin.core.extras import EXTRAS, MissingExtra, install_hint, require

ROOT = Path(__file__).resolve().parents[1]


def _extras_in_pyproject() -> set[str]:
    import tomllib

    data = tomllib.loads((ROOT / "pyproject.toml").read_text(encoding="utf-8"))
    return set(data["project"]["optional-dependencies"])


def test_every_named_extra_is_declared():
    assert set(EXTRAS) <= _extras_in_pyproject()


@pytest.mark.parametrize("where", ["root", "elsewhere"])
def test_hint_names_this_python_and_this_checkout(where, tmp_path, monkeypatch):
    monkeypatch.chdir(ROOT if where == "root" else tmp_path)
    words = shlex.split(install_hint("viewer"))
    python, dash_m, pip, install, editable, target = words
    assert (dash_m, pip, install, editable) == ("-m", "pip", "install", "-e")
    # The interpreter named is the one running, reached from the working directory.
    assert Path(python).resolve() == Path(sys.executable).resolve()
    assert target.endswith("[viewer]")
    checkout = Path(target[: -len("[viewer]")])
    assert (checkout / "pyproject.toml").is_file()
    assert checkout.resolve() == ROOT
    if where == "elsewhere":
        assert Path(python).is_absolute() and checkout.is_absolute()
    else:
        assert str(checkout) == "."


def test_require_imports_or_raises_one_error(monkeypatch):
    assert require("json", "plot").dumps([1]) == "[1]"
    monkeypatch.setitem(sys.modules, "matplotlib", None)
    with pytest.raises(MissingExtra) as info:
        require("matplotlib", "plot", "plots")
    # Both an ImportError (library users' except clauses) and an rrt-pin error (one CLI line).
    assert isinstance(info.value, ImportError) and isinstance(info.value, RrtPinError)
    assert info.value.extra == "plot" and info.value.module == "matplotlib"
    assert str(info.value).startswith("matplotlib not found (needed for plots): ")
    assert "\n" not in str(info.value)
