"""The module paths of 0.3 that moved into the layered packages: deprecated aliases.

``import rrt_pin.params`` still works for one release: it warns
(:class:`DeprecationWarning`, naming the new path) and gives the module at its new
place, the same object (``rrt_pin.params is rrt_pin.robot.params``). The modules
that ``rrt_pin`` offers as public names (:data:`PUBLIC`: ``rrt_pin.robots``,
``rrt_pin.methods``, ``rrt_pin.backends``, ``rrt_pin.control``) stay importable
under those names without a warning. The three
modules that were already deprecated aliases in 0.3 (``rrt_pin.scene``,
``rrt_pin.codegen``, ``rrt_pin.viewer.scene``) give a module of their old names.
One table, :data:`MOVED`; the finder is installed by ``import rrt_pin``.
"""

from __future__ import annotations

import importlib
import importlib.machinery
import sys
import types
import warnings
from typing import Any

__all__ = ["MOVED", "PUBLIC", "RENAMED", "install"]

#: Old module path -> its place since 0.4.
MOVED: dict[str, str] = {
    "rrt_pin.errors": "rrt_pin.core.errors",
    "rrt_pin.validate": "rrt_pin.core.validate",
    "rrt_pin.text": "rrt_pin.core.text",
    "rrt_pin.expr": "rrt_pin.core.expr",
    "rrt_pin._logging": "rrt_pin.core._logging",
    "rrt_pin._quiet": "rrt_pin.core._quiet",
    "rrt_pin.cpus": "rrt_pin.core.cpus",
    "rrt_pin.memory": "rrt_pin.core.memory",
    "rrt_pin.identity": "rrt_pin.core.identity",
    "rrt_pin.extras": "rrt_pin.core.extras",
    "rrt_pin.grid": "rrt_pin.core.grid",
    "rrt_pin.backends": "rrt_pin.core.backends",
    "rrt_pin.csvio": "rrt_pin.io.csvio",
    "rrt_pin.tables": "rrt_pin.io.tables",
    "rrt_pin._read": "rrt_pin.io._read",
    "rrt_pin.params": "rrt_pin.robot.params",
    "rrt_pin.robots": "rrt_pin.robot.robots",
    "rrt_pin.model": "rrt_pin.robot.model",
    "rrt_pin.urdf": "rrt_pin.robot.urdf",
    "rrt_pin.urdf_check": "rrt_pin.robot.urdf_check",
    "rrt_pin.kernel": "rrt_pin.dynamics.kernel",
    "rrt_pin._kernel_terms": "rrt_pin.dynamics._kernel_terms",
    "rrt_pin.rnea_source": "rrt_pin.dynamics.rnea_source",
    "rrt_pin.inverse": "rrt_pin.dynamics.inverse",
    "rrt_pin.wrenches": "rrt_pin.dynamics.wrenches",
    "rrt_pin.trajectory": "rrt_pin.dynamics.trajectory",
    "rrt_pin.symbolic": "rrt_pin.dynamics.symbolic",
    "rrt_pin.methods": "rrt_pin.simulate.methods",
    "rrt_pin.integrators": "rrt_pin.simulate.integrators",
    "rrt_pin.symplectic": "rrt_pin.simulate.symplectic",
    "rrt_pin.control": "rrt_pin.simulate.control",
    "rrt_pin.metrics": "rrt_pin.simulate.metrics",
    "rrt_pin.accuracy": "rrt_pin.simulate.accuracy",
    "rrt_pin.reference": "rrt_pin.simulate.reference",
    "rrt_pin.compiled.codes": "rrt_pin.simulate.codes",
    "rrt_pin.plot": "rrt_pin.viewer.plot",
    "rrt_pin.playback": "rrt_pin.viewer.playback",
    "rrt_pin.commands": "rrt_pin.cli.commands",
    "rrt_pin.runfile": "rrt_pin.cli.runfile",
    "rrt_pin.bench": "rrt_pin.cli.bench_report",  # its measurements: rrt_pin.cli.bench_measure
    "rrt_pin.flops": "rrt_pin.cli.flops",
    # ``rrt_pin.robot``, ``rrt_pin.io`` and ``rrt_pin.cli`` are packages now that
    # offer the old modules' names (rrt_pin.robot.robot, .io.files, .cli.app).
}

#: Paths of :data:`MOVED` that are public API (``rrt_pin.__all__`` names these modules):
#: they stay, without a warning (``from rrt_pin.robots import chapter_arm``).
PUBLIC = frozenset({"rrt_pin.robots", "rrt_pin.methods", "rrt_pin.backends", "rrt_pin.control"})

#: Deprecated modules of 0.3 whose names changed too: old path -> (new path, old name
#: -> new name).
RENAMED: dict[str, tuple[str, dict[str, str]]] = {
    "rrt_pin.scene": (
        "rrt_pin.cli.runfile",
        {"Scene": "RunFile", "load_scene": "load_runfile", "MAX_SCENE_BYTES": "MAX_RUNFILE_BYTES"},
    ),
    "rrt_pin.codegen": ("rrt_pin.dynamics.rnea_source", {}),
    "rrt_pin.viewer.scene": (
        "rrt_pin.viewer.drawing",
        {"ArmScene": "RobotDrawing", "build_scene": "build_drawing"},
    ),
}


def _target(old: str) -> str | None:
    """The new path of ``old`` or of a module inside a moved package."""
    if old in MOVED or old in RENAMED:
        return MOVED.get(old) or RENAMED[old][0]
    for prefix in ("rrt_pin.symbolic.", "rrt_pin.commands."):
        if old.startswith(prefix):
            return MOVED[prefix[:-1]] + old[len(prefix) - 1 :]
    return None


class _Alias:
    """The loader of an old path (no ``importlib.abc`` base: that would import importlib.resources)."""

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> None:
        return None

    def exec_module(self, module: types.ModuleType) -> None:
        old = module.__name__
        new = _target(old)
        assert new is not None
        if old not in PUBLIC:
            warnings.warn(
                f"{old} is deprecated: import from {new}", DeprecationWarning, stacklevel=2
            )
        target = importlib.import_module(new)
        if old not in RENAMED:
            sys.modules[old] = target  # the import system returns what sys.modules holds
            return
        renames = RENAMED[old][1]
        module.__all__ = [*getattr(target, "__all__", ()), *renames]
        module.__getattr__ = lambda name: getattr(target, renames.get(name, name))  # type: ignore[method-assign]


class _Finder:
    def find_spec(self, name: str, path: Any = None, target: Any = None) -> Any:
        if _target(name) is None:
            return None
        return importlib.machinery.ModuleSpec(name, _Alias())


def install() -> None:
    """Make the old paths importable (once a process)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.insert(0, _Finder())
