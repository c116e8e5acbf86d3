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
  flood a log, so the self-intersection check is off and quality warnings are silenced;
* strict ground truths: a ground truth is the reference every prediction is scored against, so its
  quality warnings are raised (a flood fill that leaked into a closed mesh, a mesh under one voxel;
  Python's default warning filter shows each message once), and one that is not watertight is an
  :class:`~cerberus_metrics.io.OpenMeshError` (the flood fill would enter through its holes and score a
  hollow shell), unless ``gt_open_mesh`` says to close its holes. Its self-intersections are not tested:
  neither rule's solid depends on them (both take the union of overlapping regions), and the test costs
  more than the voxelization (17.5 s for a 26,692-face human body).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from typing import Any

import numpy as np

from .api import _check_gt_open_mesh, prediction_grids
from .cache import GridCache
from .io import MeshInputError
from .protocols import Frame, check_resolution, get_protocol
from .voxelize import PartGrids, VoxelGrid, _paste, grid_iou

__all__ = ["ScoredGrids", "VoxelIoUScorer"]


@dataclass(frozen=True, eq=False)
class ScoredGrids:
    """The grids one score comes from, on one lattice box (:meth:`VoxelIoUScorer.grids`).

    parts: (P, nx, ny, nz) bool, each prediction part's voxels; gt: (nx, ny, nz) bool, the ground
    truth's. origin: lattice index of voxel ``[0, 0, 0]``; frame: the mesh-to-lattice map;
    clamped: parts clamped into a fixed grid; iou: ``|union(parts) & gt| / |union(parts) | gt|``, the
    score :meth:`VoxelIoUScorer.__call__` returns.
    """

    parts: np.ndarray
    gt: np.ndarray
    origin: tuple[int, int, int]
    frame: Frame
    clamped: int
    iou: float

    def centers(self, index: np.ndarray) -> np.ndarray:
        """(N, 3) mesh coordinates of the centres of the voxels at (N, 3) indices of this box."""
        return self.frame.to_mesh(np.asarray(index, np.float64) + np.asarray(self.origin) + 0.5)


class VoxelIoUScorer:
    """``scorer(pred_parts, gt) -> (iou, clamped)``.

    Args:
        protocol: a protocol name (:data:`~cerberus_metrics.protocols.PROTOCOLS`).
        resolution: voxels per grid side (32 in the paper).
        cache: a :class:`GridCache` for ground-truth grids, or a directory for a disk-backed one
            (shared by processes); default: a memory cache.
        gt_open_mesh: a ground truth that is not watertight: ``"error"`` (default) raises
            :class:`~cerberus_metrics.io.OpenMeshError`; ``"close"`` closes its holes with pymeshlab
            (``meshing_close_holes``) and warns; ``"warn"`` scores it as it is (a hollow shell where the fill
            leaks) and warns.
    Attributes:
        cache: the grid cache (``hits`` / ``misses`` count ground-truth look-ups).
        rejects: the errors a prediction the scorer cannot score raises (its input error,
            :class:`~cerberus_metrics.io.MeshInputError`); a caller may score such a prediction 0. Any other
            exception (a bug, ``MemoryError``) is not a verdict on the prediction. A ground truth the scorer
            refuses raises a ``MeshInputError`` too: score the ground truth alone to tell the two apart.

    Example: a cube of side 0.5 (mesh units), the same cube moved by half its side, and a cube of side
    1.1 that reaches outside the ``kato`` grid (``[-16/31, 16/31]^3``) on every side:

    >>> import trimesh
    >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
    >>> big = (box.vertices * 2.2, box.faces)
    >>> scorer = VoxelIoUScorer()  # kato, 32^3
    >>> iou, clamped = scorer([moved], cube)  # a third of the union is shared
    >>> round(iou, 4), clamped
    (0.3431, 0)
    >>> scorer([big], cube)  # clamped to the whole grid: 32^3 voxels against the cube's 16^3
    (0.125, 1)
    >>> scorer.cache.misses, scorer.cache.hits  # the ground truth was voxelized once
    (1, 1)
    >>> lidless = (box.vertices, box.faces[2:])  # the cube without one of its sides (two triangles): open
    >>> scorer([cube], lidless)
    Traceback (most recent call last):
    ...
    cerberus_metrics.io.OpenMeshError: gt: the ground truth is not watertight (4 boundary (open) edges), ...
    >>> VoxelIoUScorer(gt_open_mesh="close")([cube], lidless)  # its holes closed with pymeshlab
    (1.0, 0)
    >>> VoxelIoUScorer(resolution=1)
    Traceback (most recent call last):
    ...
    cerberus_metrics.io.MeshInputError: resolution must be an integer in [2, 1024] (e.g. 32, 64, 128), got 1
    """

    rejects: tuple[type[Exception], ...] = (MeshInputError,)

    def __init__(self, protocol: str = "kato", resolution: int = 32,
                 cache: GridCache | str | os.PathLike | None = None, gt_open_mesh: str = "error") -> None:
        self.protocol = get_protocol(protocol).name  # unknown names fail here, before any work
        self.resolution = int(check_resolution(resolution))
        self.gt_open_mesh = _check_gt_open_mesh(gt_open_mesh)  # an unknown policy fails here too
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
        parts, truth = self._voxelize(pred_parts, gt)
        return float(grid_iou(parts.union(), truth)), int(parts.clamped)

    def grids(self, pred_parts: list[tuple[np.ndarray, np.ndarray]], gt: Any) -> ScoredGrids:
        """The voxels behind ``self(pred_parts, gt)``, each prediction part's apart, on one box that holds
        the prediction and the ground truth (for per-part and per-region figures scored exactly like
        the IoU). Raises as :meth:`__call__` does.

        Example: two parts, the cube and the cube moved by half its side, against the cube (``kato``, 32^3):

        >>> import trimesh
        >>> box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
        >>> cube, moved = (box.vertices, box.faces), (box.vertices + [0.25, 0, 0], box.faces)
        >>> g = VoxelIoUScorer().grids([cube, moved], cube)
        >>> g.parts.shape, g.gt.shape, g.origin  # (P, nx, ny, nz), (nx, ny, nz): here the whole grid
        ((2, 32, 32, 32), (32, 32, 32), (0, 0, 0))
        >>> int(g.gt.sum()), int(g.parts.any(axis=0).sum()), round(g.iou, 4)  # 4096 / 6144
        (4096, 6144, 0.6667)
        >>> g.centers([[0, 0, 0]])  # voxel [0, 0, 0]'s centre, mesh units
        array([[-0.5, -0.5, -0.5]])
        """
        parts, truth = self._voxelize(pred_parts, gt)
        lo = np.minimum(parts.origin, truth.origin)
        hi = np.maximum(np.add(parts.origin, parts.occupancy.shape[1:]), np.add(truth.origin, truth.occupancy.shape))
        occ = np.zeros((len(parts.occupancy), *(hi - lo)), bool)
        for p, sub in zip(occ, parts.occupancy, strict=True):
            _paste(p, lo, sub, parts.origin, np.logical_or)
        gt_occ = np.zeros(tuple(hi - lo), bool)
        _paste(gt_occ, lo, truth.occupancy, truth.origin, np.logical_or)
        return ScoredGrids(occ, gt_occ, tuple(int(x) for x in lo), truth.frame, int(parts.clamped),
                           float(grid_iou(parts.union(), truth)))

    def _voxelize(self, pred_parts: list[tuple[np.ndarray, np.ndarray]], gt: Any) -> tuple[PartGrids, VoxelGrid]:
        """``(the prediction's PartGrids, the ground truth's VoxelGrid)`` from
        :func:`~cerberus_metrics.api.prediction_grids` under this scorer's options: the ground truth strict, the
        prediction quiet and clamped (module docstring)."""
        return prediction_grids(pred_parts, gt, self.protocol, self.resolution, self.cache, "clamp",
                                check_self_intersections=False, open_mesh="warn", gt_open_mesh=self.gt_open_mesh,
                                gt_check_self_intersections=False, quiet_pred=True)
