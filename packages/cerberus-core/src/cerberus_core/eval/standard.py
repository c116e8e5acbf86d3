"""Standard evaluation: voxel IoU of the union of the predicted parts against the ground truth.

The paper (§5.2) voxelizes prediction and ground truth at 32^3 and takes the union of the part
voxels as the output. The metric lives in the ``cerberus-metrics`` package and is reached only
through its ``cerberus.metrics`` entry point ``voxel_iou_scorer`` (:func:`cerberus_core.plugins.get_metric`):
a factory ``(protocol=, resolution=, cache=, gt_open_mesh=) -> scorer`` whose ``scorer(pred_parts, gt)`` returns
``(iou, clipped)`` and whose ``scorer.grids(pred_parts, gt)`` keeps the voxels behind that score, each
predicted part's apart (:class:`Voxels`: per-part and per-region figures scored exactly like the IoU). The scorer owns what only the metric knows: the ground-truth grid cache (the views
of a pose voxelize their mesh once), the protocol's grid (a predicted part leaving the ``kato`` grid is
clamped to it, one rule for faces, edges and corners: its voxels outside are dropped; ``clipped`` is the
number of parts so clamped) and the mesh-quality policy for predictions. Core never imports the
package by name.

:class:`GroundTruthMemo` keeps the last few ground-truth meshes so the views of a pose do not rebuild
them. A prediction the metric still rejects (e.g. every triangle degenerate) scores 0 and is counted
as ``failed`` with the message: the scorer names the exception types it raises for such input in its
``rejects`` attribute (a tuple; cerberus-metrics' ``MeshInputError``), and anything else it raises (a bug)
stops the evaluation instead of scoring 0. A ground truth the metric refuses stops it too, as a
:class:`~cerberus_core.errors.DatasetError` naming the image (:func:`ground_truth_error`): by default
(``gt_open_mesh="error"``) one that is not watertight, which the flood fill would score as a hollow shell;
``gt_open_mesh`` (:data:`GT_OPEN_MESH`) passes the metric another policy for them.
"""
from __future__ import annotations

from collections import OrderedDict
from collections.abc import Callable, Hashable
from dataclasses import dataclass, field
from typing import Any, Literal, get_args

import numpy as np

from cerberus_core.errors import ConfigError, DatasetError, ShapeError
from cerberus_core.plugins import get_metric

MeshPair = tuple[np.ndarray, np.ndarray]

SCORER_ENTRY_POINT = "voxel_iou_scorer"
"""The ``cerberus.metrics`` entry point evaluation scores with."""

GtOpenMesh = Literal["error", "close", "warn"]
GT_OPEN_MESH: tuple[str, ...] = get_args(GtOpenMesh)
"""What the metric does with a ground truth that is not watertight (its ``gt_open_mesh``): ``error`` (the
default) refuses it, and the evaluation stops naming the image; ``close`` closes its holes with pymeshlab and
warns; ``warn`` scores it as it is (a hollow shell where the flood fill leaks in) and warns."""


def open_ground_truths(policy: str | None) -> str:
    """How reports say a ``gt_open_mesh`` policy that scored open ground truths (``""`` for ``"error"``, the default,
    and for ``None``, a result from before the policy was recorded: every ground truth scored was watertight).

    Example:
        >>> open_ground_truths("close"), open_ground_truths("warn"), open_ground_truths("error")
        ('open ground truths closed with pymeshlab', 'open ground truths scored as they are', '')
    """
    return {"close": "open ground truths closed with pymeshlab", "warn": "open ground truths scored as they are"}.get(
        policy or "error", "")


@dataclass
class Score:
    """One voxel IoU. ``clipped``: the number of the prediction's parts clamped into the grid (0: none;
    a scorer answering a bool counts as 0 or 1). ``error``: the metric rejected the prediction (then
    ``iou`` is 0)."""

    iou: float
    clipped: int = 0
    error: str | None = None


@dataclass
class Voxels:
    """The voxels one :class:`Score` comes from, each predicted part's apart (:meth:`VoxelScorer.voxels`).

    Attributes:
        parts: ``(P, X, Y, Z)`` bool, each predicted part's solid voxels (all empty for a prediction
            the metric rejected).
        gt: ``(X, Y, Z)`` bool, the ground truth's, on the same lattice box.
        score: the score of the union of ``parts`` against ``gt`` (what :meth:`VoxelScorer.__call__` gives).
        centers: ``(N, 3)`` voxel indices of this box → ``(N, 3)`` mesh coordinates of their centres.
    """

    parts: np.ndarray
    gt: np.ndarray
    score: Score
    centers: Callable[[np.ndarray], np.ndarray]

    @property
    def union(self) -> np.ndarray:
        """``(X, Y, Z)`` bool, the prediction (the union of its parts)."""
        return self.parts.any(axis=0)


class VoxelScorer:
    """Voxel IoU of predicted parts (their union) against a ground-truth mesh.

    Args:
        protocol: the metric's protocol name (``"kato"``: the paper's, shapes in ``[-0.5, 0.5]^3``).
        resolution: voxels per side (32 in the paper).
        factory: the scorer factory (default: the ``voxel_iou_scorer`` entry point).
        grid_cache: passed to the factory as ``cache`` (e.g. a directory for a disk-backed cache of
            ground-truth grids); default the scorer's memory cache.
        gt_open_mesh: passed to the factory: what to do with a ground truth that is not watertight
            (:data:`GT_OPEN_MESH`; default ``"error"``: :meth:`voxels` raises a
            :class:`~cerberus_core.errors.DatasetError` naming it).
    Attributes:
        cache: the scorer's ground-truth grid cache (``hits`` / ``misses``).
        gt_open_mesh: the policy passed (an evaluation records it).

    Example (needs cerberus-metrics): a cube of side 0.5 (mesh units, ``(V, 3)`` vertices and ``(F, 3)``
    faces), the same cube moved by half its side, and a cube of side 1.1 that leaves the ``kato`` grid:

        >>> import numpy as np
        >>> corners = np.array([[x, y, z] for x in (-0.25, 0.25) for y in (-0.25, 0.25) for z in (-0.25, 0.25)])
        >>> faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
        ...                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
        >>> cube, moved, big = (corners, faces), (corners + [0.25, 0, 0], faces), (corners * 2.2, faces)
        >>> scorer = VoxelScorer()  # the paper's protocol: kato, 32^3
        >>> scorer([moved], cube)  # a third of the union is shared
        Score(iou=0.343..., clipped=0, error=None)
        >>> scorer([big], cube)  # clamped to the whole grid: 32^3 voxels against the cube's 16^3
        Score(iou=0.125, clipped=1, error=None)
        >>> v = scorer.voxels([cube, moved], cube)
        >>> v.parts.shape, int(v.gt.sum()), int(v.union.sum()), round(v.score.iou, 4)  # (P, X, Y, Z)
        ((2, 32, 32, 32), 4096, 6144, 0.6667)
        >>> scorer.cache.misses, scorer.cache.hits  # the ground truth was voxelized once
        (1, 2)
    """

    def __init__(self, protocol: str = "kato", resolution: int = 32, factory: Callable[..., Any] | None = None,
                 grid_cache: Any = None, gt_open_mesh: GtOpenMesh = "error") -> None:
        factory = factory if factory is not None else get_metric(SCORER_ENTRY_POINT)
        self.protocol = protocol
        self.resolution = resolution
        self.gt_open_mesh = gt_open_mesh
        self.scorer = factory(protocol=protocol, resolution=resolution, cache=grid_cache, gt_open_mesh=gt_open_mesh)
        self.cache = self.scorer.cache

    def __call__(self, parts: list[MeshPair], gt: MeshPair, name: str = "the ground truth") -> Score:
        """Score one prediction (list of part meshes) against one ground truth: :meth:`voxels`'s score."""
        return self.voxels(parts, gt, name).score

    def voxels(self, parts: list[MeshPair], gt: MeshPair, name: str = "the ground truth") -> Voxels:
        """Score one prediction and keep its voxels, part by part (the metric's ``scorer.grids``). A prediction the
        metric rejects scores 0 with the reason (module docstring); a ground truth it rejects raises a
        :class:`~cerberus_core.errors.DatasetError` that calls it ``name`` (:func:`ground_truth_error`)."""
        rejects = getattr(self.scorer, "rejects", ())
        try:
            grids = self.scorer.grids(parts, gt)
        except rejects as exc:  # the metric's input error: a rejected prediction scores 0
            try:
                truth = self.scorer.grids([gt], gt)  # unless the metric refuses the ground truth itself
            except rejects as refused:
                raise ground_truth_error(refused, name, self.gt_open_mesh) from None
            return Voxels(np.zeros_like(truth.parts[:1]).repeat(len(parts), 0), truth.gt,
                          Score(0.0, 0, f"{type(exc).__name__}: {exc}"), truth.centers)
        return Voxels(grids.parts, grids.gt, Score(grids.iou, int(grids.clamped)), grids.centers)


def ground_truth_error(exc: Exception, name: str, policy: str = "error") -> DatasetError:
    """The error of a ground truth the metric refuses (``exc``, its input error), calling it ``name``.

    One that is not watertight (the metric's error carries a ``report`` whose ``watertight`` is false: its
    ``OpenMeshError``) is said with its defects and the fix in this package's terms, the ``gt_open_mesh`` setting
    (:data:`GT_OPEN_MESH`), never the metric's own keyword; any other, with the metric's message.

    Example: a report of a mesh with 4 open edges, as the metric's error carries one:

        >>> from types import SimpleNamespace
        >>> report = SimpleNamespace(watertight=False, problems=lambda: ["4 boundary (open) edges"])
        >>> open_mesh = ValueError("gt: the ground truth is not watertight ...")
        >>> open_mesh.report = report
        >>> print(ground_truth_error(open_mesh, "the ground truth of image 3"))
        the ground truth of image 3 is not watertight (4 boundary (open) edges): the voxel IoU fills a ground
        truth's inside, and through its holes the fill would leave a hollow shell to score every prediction against;
        repair the mesh, or pass `gt_open_mesh=close` (its holes closed with pymeshlab) or `gt_open_mesh=warn`
        (scored as it is, a warning each)
        >>> print(ground_truth_error(ValueError("gt: degenerate mesh"), "the ground truth of image 3"))
        the ground truth of image 3: the metric refuses it (ValueError: gt: degenerate mesh); repair the mesh
    """
    report = getattr(exc, "report", None)
    if report is not None and getattr(report, "watertight", True) is False and policy == "error":
        problems = ", ".join(report.problems()) if callable(getattr(report, "problems", None)) else "open edges"
        return DatasetError(f"{name} is not watertight ({problems}): the voxel IoU fills a ground truth's inside, "
                            "and through its holes the fill would leave a hollow shell to score every prediction "
                            "against; repair the mesh, or pass `gt_open_mesh=close` (its holes closed with pymeshlab) "
                            "or `gt_open_mesh=warn` (scored as it is, a warning each)")
    return DatasetError(f"{name}: the metric refuses it ({type(exc).__name__}: {exc}); repair the mesh")


def check_scorer(protocol: str, resolution: int) -> None:
    """The voxel-IoU protocol and resolution must be ones the metric takes (checked through its entry point, before
    anything runs: the metric's bounds are the only ones; a missing cerberus-metrics is named as such).

    Raises:
        ConfigError: the metric refuses ``protocol`` or ``resolution`` (its message says why).

    Example (needs cerberus-metrics):
        >>> check_scorer("kato", 64)
        >>> check_scorer("kato", 1)
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ConfigError: resolution = 1: resolution must be an integer in [2, 1024] ...
    """
    factory = get_metric(SCORER_ENTRY_POINT)
    for key, value, tried in (("protocol", protocol, {"resolution": 32}), ("resolution", resolution, {})):
        try:
            factory(**({"protocol": protocol, "resolution": resolution} | tried))
        except (ValueError, KeyError, TypeError) as exc:
            raise ConfigError.about(key, value, str(exc)) from None


class GroundTruthMemo:
    """The last ``size`` ground-truth meshes, keyed by (subject, pose).

    Args:
        loader: ``index -> PosedBody`` (e.g. ``dataset.gt_mesh``).
        size: meshes kept (the views of a pose are usually consecutive; a few suffice).

    Example:
        >>> loaded = []
        >>> memo = GroundTruthMemo(lambda i: loaded.append(i) or f"mesh of image {i}", size=1)
        >>> memo.get(("s1", 0), 0), memo.get(("s1", 0), 1)  # two views of pose 0: one load
        ('mesh of image 0', 'mesh of image 0')
        >>> memo.get(("s1", 1), 2), memo.get(("s1", 0), 3)  # size 1: pose 0 was dropped, loaded again
        ('mesh of image 2', 'mesh of image 3')
        >>> loaded
        [0, 2, 3]
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
    """Mean voxel IoU overall and per group (subject or species).

    clipped: predictions (images) with at least one part clamped into the grid; clipped_parts: the
    parts clamped, over all predictions. failed: predictions the metric rejected (scored 0).
    """

    mean: float
    count: int
    per_group: dict[str, float] = field(default_factory=dict)
    clipped: int = 0
    failed: int = 0
    clipped_parts: int = 0

    def to_dict(self) -> dict[str, Any]:
        return {"mean": self.mean, "count": self.count, "per_group": self.per_group, "clipped": self.clipped,
                "clipped_parts": self.clipped_parts, "failed": self.failed}


def summarize(scores: list[Score], groups: list[str]) -> IoUSummary:
    """Average scores overall and per group (the order of ``groups`` matches ``scores``).

    Args:
        scores: one :class:`Score` per prediction (image).
        groups: each score's group (subject or species), as long as ``scores``.
    Returns:
        An :class:`IoUSummary` (``mean`` NaN and ``count`` 0 for no score).
    Raises:
        ShapeError: ``scores`` and ``groups`` differ in length.

    Example:
        >>> s = summarize([Score(0.5), Score(0.7, clipped=2), Score(0.0, error="MeshInputError: ...")], ["a", "a", "b"])
        >>> round(s.mean, 4), s.count, s.per_group
        (0.4, 3, {'a': 0.6, 'b': 0.0})
        >>> s.clipped, s.clipped_parts, s.failed  # images with a part clamped, parts clamped, images rejected
        (1, 2, 1)
        >>> summarize([Score(0.5)], [])
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ShapeError: summarize: one group per score is needed; ...
    """
    if len(scores) != len(groups):
        raise ShapeError("summarize: one group per score is needed; pass `groups` as long as `scores`")
    if not scores:
        return IoUSummary(float("nan"), 0)
    ious = np.array([s.iou for s in scores])
    g = np.asarray(groups)
    per_group = {name: float(ious[g == name].mean()) for name in sorted(set(groups))}
    return IoUSummary(float(ious.mean()), len(scores), per_group, sum(bool(s.clipped) for s in scores),
                      sum(s.error is not None for s in scores), sum(int(s.clipped) for s in scores))
