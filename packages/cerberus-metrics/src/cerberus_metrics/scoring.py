"""A prepared voxel-IoU scorer for evaluation loops (entry point ``cerberus.metrics: voxel_iou_scorer``).

An evaluation scores thousands of predictions against a few hundred ground truths. The scorer
holds what such a loop needs and what only this package knows:

* the ground-truth grids, in a :class:`~cerberus_metrics.cache.GridCache` (memory by default), so
  the views of one pose voxelize their shared ground truth once;
* the protocol's grid: a prediction part leaving a fixed-frame protocol's grid (``kato``: ``[0, R)^3``
  in lattice units, ``[-16/31, 16/31]^3`` mesh units at R = 32) is clamped to it by one rule in every
  direction (faces, edges and corners alike): the part is voxelized whole and its voxels outside the
  grid are dropped (a part wholly outside adds none). The scorer returns how many parts were clamped
  instead of raising;
* quiet predictions: mesh-quality notes on predicted parts (self-intersections, open parts) would
  flood a log, so the self-intersection check is off and quality warnings are silenced.
"""

from __future__ import annotations

import os
import warnings
from typing import Any

import numpy as np

from .api import voxel_iou_clamped
from .cache import GridCache
from .io import MeshQualityWarning
from .protocols import check_resolution, get_protocol

__all__ = ["VoxelIoUScorer"]


class VoxelIoUScorer:
    """``scorer(pred_parts, gt) -> (iou, clamped)``.

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

    def __call__(self, pred_parts: list[tuple[np.ndarray, np.ndarray]], gt: Any) -> tuple[float, int]:
        """Voxel IoU of the union of ``pred_parts`` (``(vertices (V, 3), faces (F, 3))`` pairs, mesh
        units) against ``gt`` (any mesh input of :func:`~cerberus_metrics.api.voxel_iou`).

        Returns:
            ``(iou, clamped)``: iou in [0, 1]; clamped, the number of parts that reached outside a
            fixed-frame protocol's grid and were clamped to it (0 for none; see the module
            docstring). Raises :class:`~cerberus_metrics.io.MeshInputError` where a mesh cannot be
            scored.
        """
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", MeshQualityWarning)
            iou, clamped = voxel_iou_clamped(pred_parts, gt, self.protocol, self.resolution, cache=self.cache,
                                             check_self_intersections=False, outside="clamp")
        return float(iou), int(clamped)
