"""Deprecated alias of :mod:`rrt_pin.runfile` (kept for one release).

Run files are :class:`rrt_pin.runfile.RunFile`, read by
:func:`rrt_pin.runfile.load_runfile`; their errors are
:class:`rrt_pin.errors.RunFileError`.
"""

from __future__ import annotations

import warnings

from rrt_pin.runfile import MAX_RUNFILE_BYTES, RunFile, load_runfile, resolve_params

warnings.warn(
    "rrt_pin.scene is deprecated: import from rrt_pin.runfile (RunFile, load_runfile)",
    DeprecationWarning,
    stacklevel=2,
)

__all__ = ["MAX_SCENE_BYTES", "Scene", "load_scene", "resolve_params"]

Scene = RunFile
load_scene = load_runfile
MAX_SCENE_BYTES = MAX_RUNFILE_BYTES
