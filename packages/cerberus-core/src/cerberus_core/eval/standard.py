"""Standard evaluation: voxel IoU of the union of the predicted parts against the ground truth.

The paper (§5.2) voxelizes prediction and ground truth at 32^3 and takes the union of the part
voxels as the output. The metric itself lives in the ``cerberus-metrics`` package and is found
through the ``cerberus.metrics`` entry point (:func:`cerberus_core.plugins.get_metric`); core never
imports it by name.

Ground truths are voxelized once per (subject, pose), since every view of a pose shares one mesh:
:class:`VoxelScorer` hands the metric a memory cache (when the metric accepts ``cache=``), and
:class:`GroundTruthMemo` keeps the last few ground-truth meshes so the views of a pose do not rebuild
them.

Predictions outside the protocol's grid. The ``kato`` protocol voxelizes inside the fixed cube
``[-0.5, 0.5]^3`` and refuses meshes that leave it. A prediction that does is clamped into the cube
(its outside bits are pressed onto the cube's faces, which is what voxelizing only inside the
grid amounts to) and counted as ``clipped`` in the results. A prediction the metric still rejects
(e.g. every triangle degenerate) scores 0 and is counted as ``failed`` with the message.
"""
from __future__ import annotations

import inspect
import warnings
from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cerberus_core.plugins import get_metric

MeshPair = tuple[np.ndarray, np.ndarray]

#: Half-side of the fixed cube of the ``kato`` protocol (normalised units).
KATO_HALF_EXTENT = 0.5


class _MemoryGridCache:
    """The ``get`` / ``put`` cache protocol of ``cerberus-metrics`` (its ``GridCache``), in memory,
    without importing that package. Keys are the metric's own content hashes."""

    def __init__(self) -> None:
        self._items: dict[str, Any] = {}
        self.hits = 0
        self.misses = 0

    def get(self, key: str) -> Any:
        item = self._items.get(key)
        if item is None:
            self.misses += 1
        else:
            self.hits += 1
        return item

    def put(self, key: str, item: Any) -> None:
        self._items[key] = item

    def __len__(self) -> int:
        return len(self._items)


@dataclass
class Score:
    """One voxel IoU. ``clipped``: the prediction was clamped into the grid. ``error``: the metric
    rejected the prediction (then ``iou`` is 0)."""

    iou: float
    clipped: bool = False
    error: str | None = None


class VoxelScorer:
    """Voxel IoU of predicted parts (their union) against a ground-truth mesh.

    Args:
        protocol: the metric's protocol name (``"kato"``: the paper's, shapes in ``[-0.5, 0.5]^3``).
        resolution: voxels per side (32 in the paper).
        metric: the callable (default: the ``voxel_iou`` entry point). It is called as
            ``metric(pred_parts, gt, protocol=..., resolution=..., **options)`` with ``pred_parts`` a
            list of ``(vertices, faces)`` pairs and ``gt`` one pair.
        grid_cache: an object with ``get(key)`` / ``put(key, item)`` for ground-truth grids (e.g. a
            disk-backed ``cerberus_metrics.GridCache`` the caller built); default a memory cache.
    """

    def __init__(self, protocol: str = "kato", resolution: int = 32, metric: Callable[..., float] | None = None,
                 grid_cache: Any = None) -> None:
        self.metric = metric if metric is not None else get_metric("voxel_iou")
        self.protocol = protocol
        self.resolution = resolution
        params = _parameters(self.metric)
        self.options: dict[str, Any] = {}
        if "cache" in params:
            self.cache = grid_cache if grid_cache is not None else _MemoryGridCache()
            self.options["cache"] = self.cache
        else:
            self.cache = None
        if "check_self_intersections" in params:
            # Only a warning in the metric, and predicted parts often self-intersect: skip the check.
            self.options["check_self_intersections"] = False

    def clip(self, parts: list[MeshPair]) -> tuple[list[MeshPair], bool]:
        """Clamp the parts into the ``kato`` cube (other protocols are returned unchanged)."""
        if self.protocol != "kato":
            return parts, False
        out, clipped = [], False
        for v, f in parts:
            if np.abs(v).max() > KATO_HALF_EXTENT:
                v = np.clip(v, -KATO_HALF_EXTENT, KATO_HALF_EXTENT)
                clipped = True
            out.append((v, f))
        return out, clipped

    def __call__(self, parts: list[MeshPair], gt: MeshPair) -> Score:
        """Score one prediction (list of part meshes) against one ground truth."""
        parts, clipped = self.clip(parts)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # mesh-quality notes on predictions would flood the log
            try:
                iou = float(self.metric(parts, gt, protocol=self.protocol, resolution=self.resolution, **self.options))
            except Exception as exc:  # noqa: BLE001 - a rejected prediction scores 0, see module docstring
                # If the ground truth alone fails too, that is a data error, not a score: let it raise.
                self.metric([gt], gt, protocol=self.protocol, resolution=self.resolution, **self.options)
                return Score(0.0, clipped, f"{type(exc).__name__}: {exc}")
        return Score(iou, clipped)


def _parameters(fn: Callable[..., Any]) -> set[str]:
    try:
        return set(inspect.signature(fn).parameters)
    except (TypeError, ValueError):
        return set()


class GroundTruthMemo:
    """The last ``size`` ground-truth meshes, keyed by (subject, pose).

    Args:
        loader: ``index -> PosedBody`` (e.g. ``dataset.gt_mesh``).
        size: meshes kept (the views of a pose are usually consecutive; a few suffice).
    """

    def __init__(self, loader: Callable[[int], Any], size: int = 8) -> None:
        self.loader = loader
        self.size = size
        self._items: OrderedDict[Hashable, Any] = OrderedDict()

    def get(self, key: Hashable, index: int) -> Any:
        item = self._items.get(key)
        if item is None:
            item = self.loader(index)
            self._items[key] = item
            while len(self._items) > self.size:
                self._items.popitem(last=False)
        else:
            self._items.move_to_end(key)
        return item


@dataclass
class IoUSummary:
    """Mean voxel IoU overall and per group (subject or species)."""

    mean: float
    count: int
    per_group: dict[str, float] = field(default_factory=dict)
    clipped: int = 0
    failed: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {"mean": self.mean, "count": self.count, "per_group": self.per_group, "clipped": self.clipped,
                "failed": self.failed}


def summarize(scores: list[Score], groups: list[str]) -> IoUSummary:
    """Average scores overall and per group (the order of ``groups`` matches ``scores``)."""
    if len(scores) != len(groups):
        raise ValueError("summarize: one group per score is needed")
    if not scores:
        return IoUSummary(float("nan"), 0)
    ious = np.array([s.iou for s in scores])
    g = np.asarray(groups)
    per_group = {name: float(ious[g == name].mean()) for name in sorted(set(groups))}
    return IoUSummary(float(ious.mean()), len(scores), per_group, sum(s.clipped for s in scores),
                      sum(s.error is not None for s in scores))
