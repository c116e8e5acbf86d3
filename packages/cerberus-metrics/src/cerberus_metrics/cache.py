"""Content-addressed cache of voxel grids (memory, plus an optional directory of .npz files).

Keys hash the mesh content (file bytes or vertex/face arrays, see
:func:`cerberus_metrics.io.content_digest`) together with everything that changes the
grid: protocol, resolution, frame, fill flag and the mesh options. A test set's ground
truths are therefore voxelized once, and a hit skips reading the file. A grid keeps the quality
warnings its mesh raised, and a hit replays them; they name the mesh (its file's path), so a hit
for an input named otherwise (another file of the same bytes, a moved file) voxelizes it again
rather than replay warnings that name another file.
"""

from __future__ import annotations

import hashlib
import json
import os
import zipfile
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._atomic import write_atomically
from .protocols import Frame
from .voxelize import VoxelGrid

__all__ = ["GridCache", "CachedGrid"]


@dataclass(frozen=True)
class CachedGrid:
    """A grid plus the quality warnings its mesh raised when it was voxelized, and ``labels``: how those warnings
    name its parts (:func:`~cerberus_metrics.io.mesh_labels`; None: not recorded, e.g. a file written before)."""

    grid: VoxelGrid
    messages: tuple[str, ...]
    labels: tuple[str, ...] | None = None


class GridCache:
    """LRU memory cache of voxel grids, optionally backed by ``directory`` (shared by processes).

    max_items: grids kept in memory. directory: where ``<key>.npz`` files are written;
    ``None`` keeps the cache in memory only. ``hits`` / ``misses`` count lookups.
    """

    def __init__(self, directory: str | os.PathLike | None = None, max_items: int = 512) -> None:
        self.directory = Path(directory) if directory is not None else None
        if self.directory is not None:
            self.directory.mkdir(parents=True, exist_ok=True)
        self.max_items = int(max_items)
        self._mem: OrderedDict[str, CachedGrid] = OrderedDict()
        self.hits = 0
        self.misses = 0

    @staticmethod
    def make_key(digest: str, **params: object) -> str:
        """Key of a mesh digest under the given parameters (JSON-serialisable values)."""
        blob = json.dumps(params, sort_keys=True, default=str).encode()
        return hashlib.sha256(digest.encode() + b"|" + blob).hexdigest()

    def get(self, key: str, labels: tuple[str, ...] | None = None) -> CachedGrid | None:
        """The grid under ``key``, or None (a miss). labels: how the input looked up names its parts
        (:func:`~cerberus_metrics.io.mesh_labels`); a grid whose warnings name other parts is a miss."""
        item = self._mem.get(key)
        if item is None and self.directory is not None:
            try:
                item = self._read(self.directory / f"{key}.npz")
            except (OSError, ValueError, KeyError, IndexError, TypeError, EOFError, zipfile.BadZipFile):
                item = None  # a damaged entry (a killed writer, a disk error) is a miss: recomputed and rewritten
            if item is not None:
                self._remember(key, item)
        if item is None or (item.messages and None not in (labels, item.labels) and item.labels != labels):
            self.misses += 1
            return None
        self._mem.move_to_end(key)
        self.hits += 1
        return item

    def put(self, key: str, item: CachedGrid) -> None:
        self._remember(key, item)
        if self.directory is not None:
            self._write(self.directory / f"{key}.npz", item)

    def __len__(self) -> int:
        return len(self._mem)

    def _remember(self, key: str, item: CachedGrid) -> None:
        self._mem[key] = item
        self._mem.move_to_end(key)
        while len(self._mem) > self.max_items:
            self._mem.popitem(last=False)

    @staticmethod
    def _write(path: Path, item: CachedGrid) -> None:
        """Write ``item`` to ``path`` atomically (:func:`~cerberus_metrics._atomic.write_atomically`): concurrent
        workers never read half a file, and an error leaves no temporary file behind."""
        g = item.grid
        arrays = {
            "bits": np.packbits(g.occupancy.ravel()),
            "shape": np.asarray(g.occupancy.shape),
            "origin": np.asarray(g.origin),
            "frame": np.asarray([g.frame.scale, *g.frame.shift, g.frame.resolution, g.frame.fixed], np.float64),
            "protocol": np.asarray(g.protocol),
            "messages": np.asarray(json.dumps(list(item.messages))),
            "labels": np.asarray(json.dumps(None if item.labels is None else list(item.labels))),
            "clamped": np.asarray(g.clamped),
        }
        write_atomically([(path, lambda fh: np.savez_compressed(fh, **arrays))])

    @staticmethod
    def _read(path: Path) -> CachedGrid | None:
        if not path.is_file():
            return None
        with np.load(path) as z:
            shape = tuple(int(s) for s in z["shape"])
            occ = np.unpackbits(z["bits"], count=int(np.prod(shape))).astype(bool).reshape(shape)
            f = z["frame"]
            frame = Frame(float(f[0]), (float(f[1]), float(f[2]), float(f[3])), int(f[4]), bool(f[5]))
            clamped = int(z["clamped"]) if "clamped" in z.files else 0  # files written before the field: 0
            grid = VoxelGrid(occ, tuple(int(o) for o in z["origin"]), frame, str(z["protocol"]), clamped)
            labels = json.loads(str(z["labels"])) if "labels" in z.files else None  # files written before: None
            return CachedGrid(grid, tuple(json.loads(str(z["messages"]))), None if labels is None else tuple(labels))
