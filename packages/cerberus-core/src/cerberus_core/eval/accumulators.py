"""Per-metric accumulators that the evaluation loop (:func:`cerberus_core.eval.runner.evaluate_dataset`) feeds.

The loop runs the model once per batch and hands every accumulator the same :class:`BatchResult`
(the reconstructions, the cameras, each image's identity and ground-truth mesh, and one record per
image to which each metric adds its own fields). An accumulator follows :class:`MetricAccumulator`:
``for_evaluation(context)`` makes it from what the evaluation has (:class:`EvalContext`), then
``update(batch)`` per batch and ``summary()``. One per metric: :class:`StandardIoU` here (voxel IoU of each
reconstruction against its ground truth, always scored), and one class per diagnostic in the diagnostic's own
module, named by its row of :data:`cerberus_core.eval.diagnostics.DIAGNOSTICS`
(:class:`~cerberus_core.eval.hard.HardHumanIoU`, :class:`~cerberus_core.eval.part_quality.PartQuality`,
:class:`~cerberus_core.eval.visibility.PartVisibility`, :class:`~cerberus_core.eval.depth.DepthAccumulator`,
:class:`~cerberus_core.eval.segments.BodySegments`, :class:`~cerberus_core.eval.allocation.Allocation`).

What several metrics need of one batch is computed once, by the :class:`BatchResult`: the voxels of
each image (:meth:`BatchResult.voxels`) and the input-view render of the parts
(:meth:`BatchResult.part_id`), and the ground truth's own render (:meth:`BatchResult.gt_foreground`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np
import torch

from cerberus_core.bodies.body import PosedBody
from cerberus_core.eval.hard import CanonicalParts, ItemMeta
from cerberus_core.eval.masks import coverage_masks
from cerberus_core.eval.segments import group_by_body
from cerberus_core.eval.standard import IoUSummary, Score, Voxels, VoxelScorer, summarize
from cerberus_core.eval.visibility import input_view_part_id
from cerberus_core.parts import PartSet
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer


@dataclass
class BatchResult:
    """One batch of model output and what every metric needs to score it.

    Attributes:
        recon: the reconstructions (``B`` images), on the CPU.
        camera: the batch's cameras, on the model's device.
        items: subject, pose, view and canonical flag of each image.
        bodies: each image's ground-truth :class:`~cerberus_core.bodies.body.PosedBody`.
        records: one dict per image (index, subject, pose, view), to which each metric adds its fields.
        singles: ``recon.index(b)`` for each image (filled in on creation).
    """

    recon: PartSet
    camera: Camera
    items: list[ItemMeta]
    bodies: list[PosedBody]
    records: list[dict[str, Any]]
    singles: list[PartSet] = field(init=False)
    _voxels: dict[tuple[int, int], Voxels] = field(init=False, default_factory=dict)
    _part_id: dict[int, torch.Tensor] = field(init=False, default_factory=dict)
    _foreground: dict[int, torch.Tensor] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.singles = [self.recon.index(b) for b in range(len(self.items))]

    def voxels(self, b: int, scorer: VoxelScorer) -> Voxels:
        """Image ``b``'s voxels, scored by ``scorer`` (:meth:`VoxelScorer.voxels`), once per batch and scorer; a
        ground truth the metric refuses is named by its image, subject and pose."""
        key = (id(scorer), b)
        if key not in self._voxels:
            body, item = self.bodies[b], self.items[b]
            name = f"the ground truth of image {item.index} (subject {item.subject}, pose {item.pose})"
            self._voxels[key] = scorer.voxels(self.singles[b].part_meshes(0), (body.vertices, body.faces), name)
        return self._voxels[key]

    def part_id(self, renderer: Renderer) -> torch.Tensor:
        """``(B, H, W)`` the part in front at each pixel of the input views (-1: none), rendered once per
        batch and renderer (:func:`~cerberus_core.eval.visibility.input_view_part_id`), on the CPU."""
        if id(renderer) not in self._part_id:
            self._part_id[id(renderer)] = input_view_part_id(renderer, self.recon, self.camera).cpu()
        return self._part_id[id(renderer)]

    def gt_foreground(self, renderer: Renderer) -> torch.Tensor:
        """``(B, H, W)`` bool: where each image's ground-truth body covers its input view
        (:func:`~cerberus_core.eval.masks.coverage_masks`, one render per body for all its views in the batch),
        once per batch and renderer, on the CPU."""
        key = id(renderer)
        if key not in self._foreground:
            out = torch.zeros(len(self.items), self.camera.height, self.camera.width, dtype=torch.bool)
            for group in group_by_body(self.bodies):
                body = self.bodies[group[0]]
                verts = torch.as_tensor(body.vertices, dtype=torch.float32).expand(len(group), 1, -1, -1)
                out[group] = coverage_masks(renderer, verts.to(self.camera.device), torch.as_tensor(body.faces),
                                            self.camera.index(group)).cpu()
            self._foreground[key] = out
        return self._foreground[key]

    def scored(self):
        """Each image of the batch, in order, as one tuple.

        Yields:
            ``(b, item, one, (vertices, faces), record)``: its position ``b`` in the batch (int), its
            :class:`~cerberus_core.eval.hard.ItemMeta` (dataset index, subject, pose, view, canonical flag), its
            reconstruction alone (a :class:`PartSet` of batch 1, ``P`` parts, on the CPU, world frame), its ground
            truth's ``vertices`` ``(V, 3)`` (world frame, mesh units) and ``faces`` ``(F, 3)`` (int), and its record
            (the dict the metrics add their fields to; ``results.json``'s ``records``).
        """
        for b, (item, one, body, rec) in enumerate(zip(self.items, self.singles, self.bodies, self.records,
                                                        strict=True)):
            yield b, item, one, (body.vertices, body.faces), rec


@dataclass(frozen=True)
class EvalContext:
    """What an evaluation gives its accumulators when it makes them (:meth:`MetricAccumulator.for_evaluation`).

    Attributes:
        config: the :class:`~cerberus_core.eval.runner.EvalConfig` (its fields: batch size, weighting...).
        scorer: the standard IoU's :class:`VoxelScorer` (its voxels are shared).
        renderer: the backend of every input-view render (``None`` when no diagnostic asked for one).
        canonical: ``() -> CanonicalParts``: each subject's canonical part shapes, reconstructed when called.
    """

    config: Any
    scorer: VoxelScorer
    renderer: Renderer | None
    canonical: Callable[[], CanonicalParts]


class MetricAccumulator(Protocol):
    """What the evaluation loop feeds: made from the evaluation's context, every batch in order, then one
    summary (the value its :class:`~cerberus_core.eval.diagnostics.Diagnostic` writes)."""

    @classmethod
    def for_evaluation(cls, context: EvalContext) -> MetricAccumulator: ...

    def update(self, batch: BatchResult) -> None: ...

    def summary(self) -> Any: ...


class StandardIoU:
    """Voxel IoU of each reconstruction (the union of its parts) against its ground-truth mesh; adds
    ``iou``, ``clipped``, ``error`` to each record. :meth:`summary`: per image, per subject, overall.

    Example (needs cerberus-metrics): a :class:`BatchResult` made by hand, no dataset: the ground truth is a cube
    of side 0.5 (mesh units), image 0's reconstruction is that cube (one part), image 1's the cube moved by half
    its side:

        >>> from cerberus_core.bodies.body import PosedBody
        >>> from cerberus_core.eval.hard import ItemMeta
        >>> corners = np.array([[x, y, z] for x in (-0.25, 0.25) for y in (-0.25, 0.25) for z in (-0.25, 0.25)])
        >>> faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
        ...                   [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
        >>> body = PosedBody(corners, faces, np.zeros(8), ["body"], "s1", 0)
        >>> posed = torch.tensor(np.stack([corners, corners + [0.25, 0.0, 0.0]]), dtype=torch.float32)
        >>> recon = PartSet.from_posed(posed.unsqueeze(1), torch.as_tensor(faces))  # (B = 2, P = 1, V = 8, 3)
        >>> items = [ItemMeta(index=i, subject="s1", pose=0, view=i, is_canonical=False) for i in range(2)]
        >>> batch = BatchResult(recon, Camera.look_at(torch.tensor([0.0, 90.0]), 0.0, 2.5), items, [body, body],
        ...                     [{"index": 0}, {"index": 1}])
        >>> metric = StandardIoU(VoxelScorer())  # the paper's protocol: kato, 32^3
        >>> metric.update(batch)
        >>> batch.records[1]  # a third of the union is shared
        {'index': 1, 'iou': 0.343..., 'clipped': 0, 'error': None}
        >>> round(metric.summary().mean, 4), metric.scorer.cache.misses  # one body: voxelized once
        (0.6715, 1)
    """

    def __init__(self, scorer: VoxelScorer) -> None:
        self.scorer = scorer
        self.scores: list[Score] = []
        self.groups: list[str] = []

    @classmethod
    def for_evaluation(cls, context: EvalContext) -> StandardIoU:
        return cls(context.scorer)

    def update(self, batch: BatchResult) -> None:
        for b, item, _, _, rec in batch.scored():
            score = batch.voxels(b, self.scorer).score
            self.scores.append(score)
            self.groups.append(item.subject)
            rec.update(iou=score.iou, clipped=score.clipped, error=score.error)

    def running_mean(self) -> float:
        """The mean IoU so far (the progress bar shows it)."""
        return float(np.mean([s.iou for s in self.scores]))

    def summary(self) -> IoUSummary:
        return summarize(self.scores, self.groups)
