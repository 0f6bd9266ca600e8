"""Scene files: a TOML description of one run's setup.

A scene holds parameter values (the seed's symbols) and command options::

    # seed.toml
    [params]            # any field of rrt_pin.params.Params, SI units
    m3 = 50.0
    q1f = "pi/3"        # strings may be small expressions (pi, tau, e, + - * / **)

    [options]           # defaults for the command's long options
    tf = 15.0           # [s]
    dt = 0.001          # [s]

Precedence: the seed's values < the scene file < ``--set`` and explicit flags.
"""

from __future__ import annotations

import math
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rrt_pin.errors import SceneError
from rrt_pin.params import PARAM_DOCS, Params, param_names, parse_number

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

__all__ = ["Scene", "load_scene", "resolve_params"]


@dataclass(frozen=True)
class Scene:
    """A parsed scene file: parameter overrides and command-option defaults."""

    params: dict[str, float] = field(default_factory=dict)
    options: dict[str, Any] = field(default_factory=dict)


def load_scene(path: str | Path) -> Scene:
    """Read a TOML scene file.

    Raises:
        SceneError: the file cannot be read or parsed, has an unknown table or
            parameter, or a value that is not a finite number where one is due.
    """
    path = Path(path)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except OSError as e:
        raise SceneError(f"cannot read scene file {str(path)!r}: {e.strerror}") from e
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as e:
        raise SceneError(f"scene file {str(path)!r} is not valid TOML: {e}") from e
    unknown = sorted(set(data) - {"params", "options"})
    if unknown:
        raise SceneError(
            f"scene file {str(path)!r}: unknown table {unknown[0]!r}; valid: params, options"
        )
    raw = data.get("params", {})
    if not isinstance(raw, dict):
        raise SceneError(f"scene file {str(path)!r}: 'params' must be a table")
    params: dict[str, float] = {}
    for name, value in raw.items():
        if name not in PARAM_DOCS:
            raise SceneError(
                f"scene file {str(path)!r}: unknown parameter {name!r}; "
                f"valid names: {', '.join(param_names())}"
            )
        if isinstance(value, str):
            value = parse_number(value, name)
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise SceneError(f"scene file {str(path)!r}: {name}={value!r} is not a number")
        params[name] = float(value)
    options = data.get("options", {})
    if not isinstance(options, dict):
        raise SceneError(f"scene file {str(path)!r}: 'options' must be a table")
    for name, value in options.items():
        if isinstance(value, float) and not math.isfinite(value):
            raise SceneError(f"scene file {str(path)!r}: option {name}={value!r} must be finite")
    return Scene(params=params, options=dict(options))


def resolve_params(scene: Scene | None = None, overrides: dict[str, float] | None = None) -> Params:
    """The seed's parameters, updated by a scene, then by ``--set`` overrides."""
    values: dict[str, float] = {}
    if scene is not None:
        values.update(scene.params)
    values.update(overrides or {})
    return Params().with_overrides(values)
