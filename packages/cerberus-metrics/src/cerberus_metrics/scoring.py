"""A prepared voxel-IoU scorer for evaluation loops (entry point ``cerberus.metrics: voxel_iou_scorer``).

An evaluation scores thousands of predictions against a few hundred ground truths. The scorer
holds what such a loop needs and what only this package knows:

* the ground-truth grids, in a :class:`~cerberus_metrics.cache.GridCache` (memory by default), so
  the views of one pose voxelize their shared ground truth once;
* the protocol's grid: a prediction leaving a fixed-frame protocol's box (``kato``:
  ``[-0.5, 0.5]^3``) is clamped into it (its outside bits pressed onto the box's faces, which is
  what voxelizing only inside the grid amounts to) and reported as clipped, instead of raising;
* quiet predictions: mesh-quality notes on predicted parts (self-intersections, open parts) would
  flood a log, so the self-intersection check is off and quality warnings are silenced.
"""

from __future__ import annotations

import os
import warnings
from typing import Any

import numpy as np

from .api import voxel_iou
from .cache import GridCache
from .io import MeshQualityWarning
from .protocols import check_resolution, get_protocol

__all__ = ["VoxelIoUScorer", "UNIT_HALF_EXTENT"]

UNIT_HALF_EXTENT = 0.5
"""Half-side of the fixed box of ``unit``-frame protocols (``kato``), in mesh units."""


class VoxelIoUScorer:
    """``scorer(pred_parts, gt) -> (iou, clipped)``.

    Args:
        protocol: a protocol name (:data:`~cerberus_metrics.protocols.PROTOCOLS`).
        resolution: voxels per grid side (32 in the paper).
        cache: a :class:`GridCache` for ground-truth grids, or a directory for a disk-backed one
            (shared by processes); default: a memory cache.
    Attributes:
        cache: the grid cache (``hits`` / ``misses`` count ground-truth look-ups).
    """

    def __init__(self, protocol: str = "kato", resolution: int = 32,
                 cache: GridCache | str | os.PathLike | None = None) -> None:
        self.protocol = get_protocol(protocol).name  # unknown names fail here, before any work
        self.resolution = int(check_resolution(resolution))
        self.cache = cache if isinstance(cache, GridCache) else GridCache(cache)

    def clip(self, parts: list[tuple[np.ndarray, np.ndarray]]) -> tuple[list[tuple[np.ndarray, np.ndarray]], bool]:
        """Clamp ``(vertices, faces)`` parts into the protocol's fixed box (other frames: unchanged)."""
        if get_protocol(self.protocol).frame != "unit":
            return parts, False
        out, clipped = [], False
        for v, f in parts:
            v = np.asarray(v)
            if v.size and np.abs(v).max() > UNIT_HALF_EXTENT:
                v = np.clip(v, -UNIT_HALF_EXTENT, UNIT_HALF_EXTENT)
                clipped = True
            out.append((v, f))
        return out, clipped

    def __call__(self, pred_parts: list[tuple[np.ndarray, np.ndarray]], gt: Any) -> tuple[float, bool]:
        """Voxel IoU of the union of ``pred_parts`` (``(vertices (V, 3), faces (F, 3))`` pairs)
        against ``gt`` (any mesh input of :func:`~cerberus_metrics.api.voxel_iou`).

        Returns:
            ``(iou, clipped)``. Raises :class:`~cerberus_metrics.io.MeshInputError` where a mesh
            cannot be scored.
        """
        parts, clipped = self.clip(pred_parts)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MeshQualityWarning)
            iou = voxel_iou(parts, gt, self.protocol, self.resolution, cache=self.cache,
                            check_self_intersections=False)
        return float(iou), clipped
