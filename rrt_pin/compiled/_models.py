"""Which generated code a model has on disk, found without generating it (no numba, no codegen).

Generating a robot's source (:mod:`rrt_pin.dynamics.rnea_source`) takes longer than a
default run may spend deciding on its backend (``docs/benchmarks.md``). So when a kernel
is loaded or compiled, the SHA-256 of its source is recorded under a key of its model (the model
pickled, plus the generators' own sources and the toolchain, :func:`model_key`), in
``generated/index/<kind>-<key>``. :func:`recall` answers "which source would this model
generate" from that record (a file read); a record made by other generators,
another Python or numba, is simply not found (the key differs), never wrong.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import sys
import threading
from functools import lru_cache
from pathlib import Path
from typing import Any

from rrt_pin.core.identity import IdentityCache

__all__ = ["model_key", "recall", "remember"]

#: The modules whose text decides a generated source (any change: other keys).
_GENERATORS = (
    "rrt_pin.dynamics.rnea_source",
    "rrt_pin.dynamics.forward_source",
    "rrt_pin.compiled.rnea_vector",
    "rrt_pin.compiled.rnea",
    "rrt_pin.compiled.robot_code",
    "rrt_pin.compiled._robot_template",
    "rrt_pin.compiled._aot",
    "rrt_pin.simulate.codes",
)
#: Keys of the models seen in this process, by identity (a copy kept to notice changes).
_KEYS: IdentityCache[tuple[Any, str]] = IdentityCache(16)
_lock = threading.Lock()


@lru_cache(maxsize=1)
def _generators() -> bytes:
    """The generators' sources and the toolchain, hashed once a process."""
    import importlib.util

    from rrt_pin.compiled._cache import _cpu, _version

    h = hashlib.sha256()
    for name in _GENERATORS:
        spec = importlib.util.find_spec(name)
        origin = spec.origin if spec is not None else None
        try:
            h.update(Path(origin).read_bytes() if origin else b"<missing>")
        except OSError:
            h.update(b"<unreadable>")
    for part in (sys.version, _version("numba"), _version("llvmlite"), _cpu()):
        h.update(part.encode())
    return h.digest()


def model_key(model: Any) -> str:
    """A key of ``model`` and of the code generators (24 hex digits), kept per model object."""
    entry = _KEYS.get(model)
    if entry is not None and bool(entry[0] == model):
        return entry[1]
    import pinocchio as pin

    key = hashlib.sha256(_generators() + pickle.dumps(model)).hexdigest()[:24]
    _KEYS.put(model, value=(pin.Model(model), key))
    return key


def _index() -> Path | None:
    from rrt_pin.compiled._cache import generated_dir

    where = generated_dir()
    return None if where is None else where / "index"


def remember(kind: str, model: Any, record: dict[str, Any]) -> None:
    """Record what ``model`` generates for ``kind`` (JSON).

    ``record["digest"]``: its source's SHA-256; the rest: any sizes the code needs
    without generating the source.
    """
    index = _index()
    if index is None:
        return
    path = index / f"{kind}-{model_key(model)}"
    text = json.dumps(record, sort_keys=True)
    try:
        if path.read_text(encoding="utf-8") == text:
            return
    except (OSError, UnicodeDecodeError):
        pass
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{threading.get_ident()}.tmp")
    with _lock:
        try:
            index.mkdir(parents=True, exist_ok=True)
            tmp.write_text(text, encoding="utf-8")
            os.replace(tmp, path)
        except OSError:
            tmp.unlink(missing_ok=True)


def recall(kind: str, model: Any) -> dict[str, Any] | None:
    """What :func:`remember` recorded for ``model`` and ``kind`` (None: nothing, or unreadable)."""
    index = _index()
    if index is None:
        return None
    try:
        record = json.loads((index / f"{kind}-{model_key(model)}").read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    digest = record.get("digest") if isinstance(record, dict) else None
    if not isinstance(digest, str) or len(digest) != 64:
        return None
    if any(c not in "0123456789abcdef" for c in digest):
        return None
    return record
