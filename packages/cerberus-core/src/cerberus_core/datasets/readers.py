"""Torch datasets over the on-disk format (docs/data_format.md).

* :class:`QuadrupletDataset` — training quadruplets: one body in 2 poses (a, b) from 2 viewpoints
  (0, 1), images in the order ``(a0, a1, b0, b1)``.
* :class:`ViewDataset` — single images (evaluation), with the ground-truth mesh of each image.
The readers run the checks of the whole-folder check (:meth:`Dataset.verify
<cerberus_core.datasets.dataset.Dataset.verify>`) on the split they open; :class:`Dataset
<cerberus_core.datasets.dataset.Dataset>` opens them by split.

Both are cheap to construct (they read ``manifest.json`` and stat the shard files) and picklable:
shards are opened lazily in each process with ``np.load(mmap_mode="r")``.
"""
from __future__ import annotations

import operator
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.utils.data import Dataset

from cerberus_core.bodies.body import PosedBody
from cerberus_core.datasets.format import (
    VIEW_DTYPE,
    DatasetError,
    check_shard_arrays,
    check_shard_files,
    resolve_inside,
    unpack_mesh,
)
from cerberus_core.datasets.manifest import Manifest, ShardRecord
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import InputTypeError
from cerberus_core.render.camera import Camera

Tensor = torch.Tensor


class _SplitReader:
    """Lazy access to the shards of one split (shared by the datasets below)."""

    def __init__(self, root: str | Path, split: str, *, allow_partial: bool = False, verify: bool = False) -> None:
        self.root = Path(root)
        self.split = split
        self.manifest = Manifest.read(self.root)
        self.info = self.manifest.readable_split(split, allow_partial=allow_partial)
        self.shards: tuple[ShardRecord, ...] = self.info.shards
        for shard in self.shards:
            problems = (check_shard_files(self.root, shard, checksums=verify)
                        or check_shard_arrays(self.manifest, split, shard))
            if problems:
                more = f" (and {len(problems) - 1} more problems)" if len(problems) > 1 else ""
                raise DatasetError(problems[0] + more)
        self.image_offsets = np.concatenate([[0], np.cumsum([s.images for s in self.shards])]).astype(np.int64)
        self.quad_offsets = np.concatenate([[0], np.cumsum([s.quadruplets for s in self.shards])]).astype(np.int64)
        self.image_size = self.manifest.image_size
        self._cache: dict[tuple[int, str], Any] = {}

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_cache"] = {}  # memory maps are reopened in each worker
        return state

    def array(self, shard: int, role: str) -> np.ndarray:
        """The memory-mapped ``role`` array (images, views, quads, vertices) of shard ``shard``."""
        key = (shard, role)
        if key not in self._cache:
            rec = self.shards[shard].files.get(role)
            if rec is None:
                raise DatasetError(f"{self.root}: shard {self.shards[shard].name} of split {self.split!r} has no "
                                   f"{role} file (this split was generated without it)")
            path = resolve_inside(self.root, rec.path)
            try:
                arr = np.load(path, mmap_mode="r", allow_pickle=False)
            except (OSError, ValueError) as exc:
                raise DatasetError(f"{path}: unreadable ({exc}); run `cerberus data check {self.root}`") from exc
            if arr.shape != rec.shape or arr.dtype.str != rec.dtype:
                raise DatasetError(f"{path}: array {arr.dtype.str}{list(arr.shape)} does not match the manifest "
                                   f"({rec.dtype}{list(rec.shape or ())}); the shard is corrupt")
            if role == "views" and arr.dtype != VIEW_DTYPE:
                raise DatasetError(f"{path}: view records of an unknown layout {arr.dtype}")
            self._cache[key] = arr
        return self._cache[key]

    def meshes(self, shard: int) -> dict[str, np.ndarray]:
        key = (shard, "meshes")
        if key not in self._cache:
            rec = self.shards[shard].files.get("meshes")
            if rec is None:
                raise DatasetError(f"{self.root}: split {self.split!r} was generated without ground-truth meshes")
            path = resolve_inside(self.root, rec.path)
            try:
                with np.load(path, allow_pickle=False) as npz:
                    self._cache[key] = {k: npz[k] for k in npz.files}
            except (OSError, ValueError) as exc:
                raise DatasetError(f"{path}: unreadable ({exc}); run `cerberus data check {self.root}`") from exc
        return self._cache[key]

    @staticmethod
    def locate(offsets: np.ndarray, i: int) -> tuple[int, int]:
        n = int(offsets[-1])
        try:
            i = operator.index(i)
        except TypeError:
            raise InputTypeError(f"a dataset is indexed by an integer 0..{n - 1}, got {type(i).__name__} {i!r}") from None
        if i < 0:
            i += n
        if not 0 <= i < n:
            raise IndexError(f"index {i} out of range for {n} items")
        shard = int(np.searchsorted(offsets, i, side="right") - 1)
        return shard, int(i - offsets[shard])

    def images(self, shard: int, idx: np.ndarray | int) -> Tensor:
        """``(..., 3, H, W)`` float32 in [0, 1]."""
        # numpy, not torch: a tiny torch op can stall on the intra-op thread pool of a busy worker
        return torch.from_numpy(np.divide(self.array(shard, "images")[idx], np.float32(255), dtype=np.float32))


class _Base(Dataset):
    """Manifest-level accessors shared by both datasets.

    Attributes:
        root: the dataset folder; split: the split read; manifest: the dataset's :class:`Manifest`;
        image_size: square image size in pixels.
    """

    def __init__(self, root: str | Path, split: str, *, allow_partial: bool, verify: bool) -> None:
        self._reader = _SplitReader(root, split, allow_partial=allow_partial, verify=verify)
        self.root, self.split = self._reader.root, self._reader.split
        self.manifest: Manifest = self._reader.manifest
        self.image_size: int = self._reader.image_size

    @property
    def scene(self) -> SceneSetup:
        """The scene set-up (cameras of view records, light, background, albedo): :attr:`Manifest.scene`."""
        return self.manifest.scene

    @property
    def part_names(self) -> list[str]:
        """Names of the ground-truth parts (evaluation only)."""
        return list(self.manifest.part_names)

    @property
    def subject_names(self) -> list[str]:
        """Subject index → name (indices are global over the dataset's splits)."""
        return self.manifest.subject_names

    def cameras(self, batch: dict[str, Tensor], slot: int | None = None) -> Camera:
        """Cameras of a (collated) batch at this dataset's image size: :meth:`SceneSetup.view_cameras`.

        Args:
            batch: a dict with ``azimuth``, ``elevation``, ``distance``, ``fov_y``, each ``(B, 4)``
                (QuadrupletDataset), ``(B,)`` (ViewDataset) or unbatched.
            slot: quadruplets only: image slot 0..3 (``a0, a1, b0, b1``) → ``B`` cameras; ``None``
                → every image, ``B * 4`` cameras in row-major ``(b, slot)`` order, matching
                ``batch["images"].flatten(0, 1)``.
        Returns:
            :class:`Camera` on the batch's device with this dataset's image size.
        """
        return self.scene.view_cameras(batch, self.image_size, slot=slot)


class QuadrupletDataset(_Base):
    """Training quadruplets of one split.

    ``dataset[i]`` is a dict of tensors:

    * ``images`` ``(4, 3, H, W)`` float32 in [0, 1], order ``(a0, a1, b0, b1)``: poses a, b; views 0, 1;
    * ``azimuth``, ``elevation``, ``fov_y`` ``(4,)`` float32 degrees; ``distance`` ``(4,)`` float32
      normalised units;
    * ``subject`` int64 scalar (index into :attr:`subject_names`);
    * ``pose`` ``(4,)`` int64 pose ids (``pose[0] == pose[1]``, ``pose[2] == pose[3]``);
    * ``view`` ``(4,)`` int64 view ids within each pose.

    Args:
        root: dataset folder.
        split: split name (default ``"train"``).
        allow_partial: read a split whose generation has not finished.
        verify: check every shard's sha256 now (slow; ``cerberus data check`` does the same).
    """

    def __init__(self, root: str | Path, split: str = "train", *, allow_partial: bool = False,
                 verify: bool = False) -> None:
        super().__init__(root, split, allow_partial=allow_partial, verify=verify)
        if self._reader.quad_offsets[-1] == 0:
            raise DatasetError(f"{self._reader.root}: split {split!r} has no quadruplets (a "
                               f"{self._reader.info.layout} test split?); read its single images with `Dataset.views(split)`")

    def __len__(self) -> int:
        return int(self._reader.quad_offsets[-1])

    def item(self, shard: int, local: int) -> dict[str, Tensor]:
        r = self._reader
        quad = np.asarray(r.array(shard, "quads")[local], dtype=np.int64)
        v = np.asarray(r.array(shard, "views")[quad])
        return {
            "images": r.images(shard, quad),
            "azimuth": torch.from_numpy(v["azimuth"].astype(np.float32)),
            "elevation": torch.from_numpy(v["elevation"].astype(np.float32)),
            "distance": torch.from_numpy(v["distance"].astype(np.float32)),
            "fov_y": torch.from_numpy(v["fov_y"].astype(np.float32)),
            "subject": torch.tensor(int(v["subject"][0]), dtype=torch.int64),
            "pose": torch.from_numpy(v["pose"].astype(np.int64)),
            "view": torch.from_numpy(v["view"].astype(np.int64)),
        }

    def __getitem__(self, i: int) -> dict[str, Tensor]:
        return self.item(*self._reader.locate(self._reader.quad_offsets, i))

    def view_indices(self, i: int) -> np.ndarray:
        """``(4,)`` int64: the indices of quadruplet ``i``'s images ``a0 a1 b0 b1`` among the split's views (the
        :class:`ViewDataset` of the same split)."""
        shard, local = self._reader.locate(self._reader.quad_offsets, i)
        return np.asarray(self._reader.array(shard, "quads")[local], dtype=np.int64) + int(self._reader.image_offsets[shard])


class ViewDataset(_Base):
    """Single images of one split (evaluation).

    ``dataset[i]`` is a dict of tensors: ``images`` ``(3, H, W)`` float32 in [0, 1]; ``azimuth``,
    ``elevation``, ``fov_y`` (degrees) and ``distance`` float32 scalars; ``subject``, ``pose``,
    ``view``, ``index`` (= ``i``) int64 scalars; ``is_canonical`` bool scalar.

    :meth:`gt_mesh` gives the ground-truth body of an image, :meth:`canonical_indices` the images of
    each subject's canonical pose (the Hard Human test's part source).
    """

    def __init__(self, root: str | Path, split: str = "test", *, allow_partial: bool = False,
                 verify: bool = False) -> None:
        super().__init__(root, split, allow_partial=allow_partial, verify=verify)
        self._records: np.ndarray | None = None
        self._source = None

    def __getstate__(self) -> dict:
        state = self.__dict__.copy()
        state["_source"] = None
        return state

    def __len__(self) -> int:
        return int(self._reader.image_offsets[-1])

    def item(self, shard: int, local: int) -> dict[str, Tensor]:
        r = self._reader
        v = r.array(shard, "views")[local]
        return {
            "images": r.images(shard, local),
            "azimuth": torch.tensor(float(v["azimuth"]), dtype=torch.float32),
            "elevation": torch.tensor(float(v["elevation"]), dtype=torch.float32),
            "distance": torch.tensor(float(v["distance"]), dtype=torch.float32),
            "fov_y": torch.tensor(float(v["fov_y"]), dtype=torch.float32),
            "subject": torch.tensor(int(v["subject"]), dtype=torch.int64),
            "pose": torch.tensor(int(v["pose"]), dtype=torch.int64),
            "view": torch.tensor(int(v["view"]), dtype=torch.int64),
            "is_canonical": torch.tensor(bool(v["canonical"])),
            "index": torch.tensor(int(r.image_offsets[shard] + local), dtype=torch.int64),
        }

    def __getitem__(self, i: int) -> dict[str, Tensor]:
        return self.item(*self._reader.locate(self._reader.image_offsets, i))

    @property
    def records(self) -> np.ndarray:
        """``(N,)`` :data:`~cerberus_core.datasets.format.VIEW_DTYPE` records of every image, in index order."""
        if self._records is None:
            r = self._reader
            parts = [np.asarray(r.array(k, "views")) for k in range(len(r.shards))]
            self._records = np.concatenate(parts) if parts else np.zeros(0, VIEW_DTYPE)
        return self._records

    def subjects(self) -> list[int]:
        """Sorted subject indices present in this split."""
        return sorted(int(s) for s in np.unique(self.records["subject"]))

    def canonical_indices(self) -> dict[int, list[int]]:
        """Subject index → indices of its canonical-pose images (view order), for subjects that have them."""
        rec = self.records
        out: dict[int, list[int]] = {}
        for i in np.flatnonzero(rec["canonical"]):
            out.setdefault(int(rec["subject"][i]), []).append(int(i))
        return out

    def gt_mesh(self, i: int) -> PosedBody:
        """The ground-truth body seen in image ``i`` (vertices in normalised units, faces, per-vertex
        part labels, :attr:`part_names`). If the split was generated without meshes, the body is
        regenerated from its (subject, pose) reference with the dataset's body source."""
        shard, local = self._reader.locate(self._reader.image_offsets, i)
        v = self._reader.array(shard, "views")[local]
        subject, pose, mesh = int(v["subject"]), int(v["pose"]), int(v["mesh"])
        if mesh < 0:
            return self._regenerate(subject, pose)
        meshes = self._reader.meshes(shard)
        verts, faces, parts = unpack_mesh(self._reader.array(shard, "vertices"), meshes, mesh)
        meta = {"pose_params": meshes["pose_params"][mesh]} if "pose_params" in meshes else {}
        return PosedBody(verts, faces, parts, self.part_names, self.subject_names[subject], pose, meta=meta)

    def _regenerate(self, subject: int, pose: int) -> PosedBody:
        """Rebuild a body from the manifest alone: its source (name and options) and the subject's record."""
        if self._source is None:
            try:
                self._source = self.manifest.source.build()
            except DatasetError as exc:
                raise DatasetError(f"{self.root}: split {self.split!r} stores no meshes and {exc}") from exc
        try:
            return self._source.bodies(self.manifest.subjects[subject].subject, [pose])[0]
        except DatasetError as exc:  # a subject record of an older manifest
            raise DatasetError(f"{self.manifest.path}: {exc}") from exc


__all__ = ["QuadrupletDataset", "ViewDataset"]
