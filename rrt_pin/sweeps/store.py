"""A sweep's folder: one Parquet file per chunk, the kept trajectories, and a manifest.

Layout of ``OUT/``::

    manifest.json                 spec, its hash, variants, chunks, which are done
    chunks/chunk-000042.parquet   variant index, varied values, metrics (units in metadata)
    trajectories/variant-17.parquet  t, q…, qd…, tau… of a kept variant

Every file is written atomically (:mod:`rrt_pin.io`): a crash leaves the old
file or the new one. The manifest is rewritten after each chunk file, so a
chunk listed as done is on disk; ``--resume`` recomputes only the others and
refuses a spec whose hash differs.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from rrt_pin._version import __version__
from rrt_pin.errors import InputError
from rrt_pin.io import atomic_write_bytes

__all__ = ["Store"]

MANIFEST = "manifest.json"


def _table(columns: dict[str, np.ndarray], metadata: dict[str, str]) -> Any:
    import pyarrow as pa

    arrays = {}
    for name, col in columns.items():
        col = np.asarray(col)
        arrays[name] = pa.array(col.tolist() if col.dtype == object else col)
    table = pa.table(arrays)
    return table.replace_schema_metadata({k: str(v) for k, v in metadata.items()})


def _parquet_bytes(table: Any) -> bytes:
    import pyarrow as pa
    import pyarrow.parquet as pq

    sink = pa.BufferOutputStream()
    pq.write_table(table, sink)  # snappy: cheap for the process that writes every chunk
    return sink.getvalue().to_pybytes()


class Store:
    """The output folder of one sweep."""

    def __init__(self, folder: str | Path) -> None:
        self.folder = Path(folder)

    @property
    def manifest_path(self) -> Path:
        """The manifest's path."""
        return self.folder / MANIFEST

    def chunk_path(self, k: int) -> Path:
        """Where chunk ``k`` is stored."""
        return self.folder / "chunks" / f"chunk-{k:06d}.parquet"

    def read_manifest(self) -> dict[str, Any] | None:
        """The manifest, or None when the folder holds no sweep."""
        try:
            return json.loads(self.manifest_path.read_text(encoding="utf-8"))
        except FileNotFoundError:
            return None
        except (OSError, ValueError) as e:
            raise InputError(f"cannot read {str(self.manifest_path)!r}: {e}") from e

    def check(self, manifest: dict[str, Any], resume: bool) -> None:
        """Refuse, writing nothing, a folder this sweep cannot use.

        Raises:
            InputError: the folder is a file or its parent is missing; it holds another
                sweep and ``resume`` is false; or ``resume`` is true and the spec differs.
        """
        if self.folder.exists() and not self.folder.is_dir():
            raise InputError(f"--out {str(self.folder)!r} is not a folder")
        old = self.read_manifest() if self.folder.is_dir() else None
        if old is not None and not resume:
            raise InputError(
                f"--out {str(self.folder)!r} already holds a sweep: add --resume to finish it, "
                "or choose another folder"
            )
        if resume and old is not None and old.get("spec_hash") != manifest["spec_hash"]:
            raise InputError(
                f"--resume: the spec changed since {str(self.folder)!r} was started "
                f"(hash {manifest['spec_hash']} vs {old.get('spec_hash')}); use another folder"
            )
        if resume and old is not None and old.get("chunk") != manifest["chunk"]:
            raise InputError(
                f"--resume: chunk={manifest['chunk']} but the sweep in {str(self.folder)!r} "
                f"was started with chunk={old.get('chunk')}"
            )
        if not self.folder.is_dir() and not self.folder.absolute().parent.is_dir():
            raise InputError(f"--out {str(self.folder)!r}: its folder does not exist")

    def start(self, manifest: dict[str, Any], resume: bool) -> set[int]:
        """Open the folder for a sweep (after :meth:`check`); the chunks already done."""
        self.check(manifest, resume)
        old = self.read_manifest() if self.folder.is_dir() else None
        (self.folder / "chunks").mkdir(parents=True, exist_ok=True)
        done = set()
        if old is not None:
            done = {k for k in old.get("done", []) if self.chunk_path(k).is_file()}
        self.manifest = dict(manifest, done=sorted(done))
        self._write_manifest()
        return done

    def _write_manifest(self) -> None:
        text = json.dumps(self.manifest, indent=1) + "\n"
        atomic_write_bytes(self.manifest_path, text.encode("utf-8"), flag="--out")

    def write_chunk(self, k: int, result: dict[str, Any], units: dict[str, str]) -> None:
        """Store chunk ``k`` (index, varied values, metrics) and its kept trajectories."""
        columns = {"variant": result["index"]}
        columns.update({name: col for name, col in result["values"].items()})
        columns.update(result["columns"])
        meta = {
            "rrt_pin.version": __version__,
            "rrt_pin.spec_hash": self.manifest["spec_hash"],
            "rrt_pin.units": json.dumps({n: units.get(n, "") for n in columns}),
        }
        data = _parquet_bytes(_table(columns, meta))
        atomic_write_bytes(self.chunk_path(k), data, flag="--out")
        for i, (t, q, qd, tau) in result["trajectories"].items():
            self.write_trajectory(i, t, q, qd, tau)
        self.manifest["done"] = sorted({*self.manifest["done"], k})
        self._write_manifest()

    def write_trajectory(self, i: int, t: np.ndarray, q: np.ndarray, qd: np.ndarray,
                         tau: np.ndarray) -> None:  # fmt: skip
        """Store the dense run of variant ``i``."""
        names = self.manifest["columns"]
        cols = {"t": t}
        for k, name in enumerate(names["q"]):
            cols[name] = q[:, k]
        for k, name in enumerate(names["qd"]):
            cols[name] = qd[:, k]
        for k, name in enumerate(names["tau"]):
            cols[name] = tau[:, k]
        (self.folder / "trajectories").mkdir(exist_ok=True)
        data = _parquet_bytes(_table(cols, {"rrt_pin.variant": str(i)}))
        atomic_write_bytes(self.folder / "trajectories" / f"variant-{i}.parquet", data)

    def read(self) -> Any:
        """All chunks as one pyarrow Table, sorted by variant."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        files = sorted((self.folder / "chunks").glob("chunk-*.parquet"))
        if not files:
            raise InputError(f"{str(self.folder)!r} holds no chunk yet")
        table = pa.concat_tables([pq.read_table(f) for f in files])
        return table.sort_by("variant")
