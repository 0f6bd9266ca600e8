"""The optional extras of rrt-pin, and one install hint that works where the user is.

Each optional part imports its libraries through :func:`require`, so that a
missing one is a :class:`MissingExtra` (an :class:`ImportError` and a
:class:`~rrt_pin.core.errors.RrtPinError`: the CLI prints it as one line, exit 2)
whose hint names the command that installs it *here*: from a checkout (rrt-pin
is installed in editable mode from its source tree), the checkout's own pip
and path; otherwise ``pip install 'rrt-pin[extra]'``.
"""

from __future__ import annotations

import importlib
import os
import sys
from pathlib import Path
from types import ModuleType

from rrt_pin.core.errors import RrtPinError

__all__ = ["EXTRAS", "MissingExtra", "install_hint", "require"]

#: Extra -> what it is for (the extras themselves are declared in pyproject.toml).
EXTRAS: dict[str, str] = {
    "plot": "plots (matplotlib)",
    "viewer": "the browser viewer and screenshots (meshcat, selenium)",
    "symbolic": "the symbolic derivations and the 30-digit references (sympy, mpmath)",
    "fast": "the compiled backend (numba)",
    "sweep": "sweeps (dask.distributed, pyarrow, tqdm, pandas)",
    "parquet": "Parquet outputs and data frames (pyarrow, pandas)",
    "robots": "robots by name: --robot ur5, panda … (example-robot-data's URDFs)",
}


class MissingExtra(RrtPinError, ImportError):
    """An optional library is not installed.

    Attributes:
        module: the module that failed to import.
        extra: the extra that installs it.
    """

    def __init__(self, module: str, extra: str, purpose: str | None = None) -> None:
        self.module = module
        self.extra = extra
        what = f" (needed for {purpose})" if purpose else ""
        super().__init__(f"{module} not found{what}: {install_hint(extra)}")


def _checkout() -> Path | None:
    """The source tree rrt_pin runs from, when it is one (a pyproject.toml beside the package)."""
    root = Path(__file__).resolve().parents[2]  # rrt_pin/core/extras.py -> the checkout
    if (root / "pyproject.toml").is_file() and (root / "rrt_pin" / "__init__.py").is_file():
        return root
    return None


def _short(path: Path) -> str:
    """``path`` relative to the working directory when it is inside it, else absolute."""
    try:
        rel = os.path.relpath(path)
    except ValueError:  # another drive (Windows)
        return str(path)
    return str(path) if rel.startswith("..") else rel


def install_hint(extra: str) -> str:
    """The command that installs ``extra`` for the Python running now."""
    root = _checkout()
    if root is None:
        return f"pip install 'rrt-pin[{extra}]'"
    python = _short(Path(sys.executable))
    target = "." if _short(root) == "." else _short(root)
    return f"{python} -m pip install -e '{target}[{extra}]'"


def require(module: str, extra: str, purpose: str | None = None) -> ModuleType:
    """Import ``module`` or raise :class:`MissingExtra` naming ``extra``'s install command."""
    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise MissingExtra(module, extra, purpose) from e
