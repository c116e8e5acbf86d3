"""Per-metric accumulators that the evaluation loop (:func:`cerberus_core.eval.runner.evaluate_dataset`) feeds.

The loop runs the model once per batch and hands every accumulator the same :class:`BatchResult`
(the reconstructions, the cameras, each image's identity and ground-truth mesh, and one record per
image to which each metric adds its own fields). An accumulator follows :class:`MetricAccumulator`:
``for_evaluation(context)`` makes it from what the evaluation has (:class:`EvalContext`), then
``update(batch)`` per batch and ``summary()``. Each diagnostic's row of
:data:`cerberus_core.eval.diagnostics.DIAGNOSTICS` names its class. One per metric:

* :class:`StandardIoU`: voxel IoU of each reconstruction against its ground truth;
* :class:`PartVisibility`: how often each part is wholly hidden in its input view (one render per batch);
* :class:`HardHumanIoU`: the subject's canonical part shapes posed by each other image;
* :class:`PartQuality`: the parts against the ground-truth semantic parts;
* :class:`BodySegments`: recall and off-body voxels per ground-truth body segment, the IoU each learned
  part is worth, and each segment's coverage in the input view;
* :class:`Allocation`: where the parts' keypoints sit against the silhouette and the segments, and the
  foreground each part alone covers (:mod:`cerberus_core.eval.allocation`).

What several metrics need of one batch is computed once, by the :class:`BatchResult`: the voxels of
each image (:meth:`BatchResult.voxels`) and the input-view render of the parts
(:meth:`BatchResult.part_id`), and the ground truth's own render (:meth:`BatchResult.gt_foreground`).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields
from typing import Any, Protocol

import numpy as np
import torch

from cerberus_core.bodies.body import PosedBody
from cerberus_core.errors import DatasetError
from cerberus_core.eval.allocation import AllocationAccumulator, ImageAllocation, measure_allocation
from cerberus_core.eval.hard import CanonicalParts, ItemMeta
from cerberus_core.eval.part_quality import PartQualityAccumulator, image_overlap
from cerberus_core.eval.segments import (
    SegmentAccumulator,
    covered_vertices,
    group_by_body,
    image_segments,
)
from cerberus_core.eval.standard import IoUSummary, Score, Voxels, VoxelScorer, summarize
from cerberus_core.eval.visibility import VisibilityAccumulator, input_view_part_id
from cerberus_core.parts import PartSet
from cerberus_core.render.api import part_pixel_counts, render
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
    _voxels: dict[int, Voxels] = field(init=False, default_factory=dict)
    _part_id: dict[int, torch.Tensor] = field(init=False, default_factory=dict)
    _foreground: dict[int, torch.Tensor] = field(init=False, default_factory=dict)

    def __post_init__(self) -> None:
        self.singles = [self.recon.index(b) for b in range(len(self.items))]

    def voxels(self, b: int, scorer: VoxelScorer) -> Voxels:
        """Image ``b``'s voxels, scored by ``scorer`` (:meth:`VoxelScorer.voxels`), once per batch."""
        if b not in self._voxels:
            body = self.bodies[b]
            self._voxels[b] = scorer.voxels(self.singles[b].part_meshes(0), (body.vertices, body.faces))
        return self._voxels[b]

    def part_id(self, renderer: Renderer) -> torch.Tensor:
        """``(B, H, W)`` the part in front at each pixel of the input views (-1: none), rendered once per
        batch and renderer (:func:`~cerberus_core.eval.visibility.input_view_part_id`), on the CPU."""
        if id(renderer) not in self._part_id:
            self._part_id[id(renderer)] = input_view_part_id(renderer, self.recon, self.camera).cpu()
        return self._part_id[id(renderer)]

    def gt_foreground(self, renderer: Renderer) -> torch.Tensor:
        """``(B, H, W)`` bool: where each image's ground-truth body covers its input view (the body's own
        render, one per body for all its views in the batch), rendered once per batch and renderer, on
        the CPU."""
        key = id(renderer)
        if key not in self._foreground:
            out = torch.zeros(len(self.items), self.camera.height, self.camera.width, dtype=torch.bool)
            for group in group_by_body(self.bodies):
                body = self.bodies[group[0]]
                verts = torch.as_tensor(body.vertices, dtype=torch.float32).expand(len(group), -1, -1)
                with torch.no_grad():
                    own = render(renderer, verts.to(self.camera.device).contiguous(), torch.as_tensor(body.faces),
                                 self.camera.index(group)).part_id.cpu() >= 0
                out[group] = own
            self._foreground[key] = out
        return self._foreground[key]

    def scored(self):
        """``(b, item, single reconstruction, ground-truth (vertices, faces), record)`` per image."""
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
    ``iou``, ``clipped``, ``error`` to each record. :meth:`summary`: per image, per subject, overall."""

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


class HardHumanIoU:
    """The Hard Human test: each subject's canonical part shapes, posed by every other image of it,
    scored like :class:`StandardIoU`; adds ``hard_iou``, ``hard_clipped``, ``hard_error`` to the
    records it applies to. :meth:`summary` is ``None`` when it applied to none."""

    def __init__(self, scorer: VoxelScorer, canonical: CanonicalParts) -> None:
        self.scorer = scorer
        self.canonical = canonical
        self.scores: list[Score] = []
        self.groups: list[str] = []

    @classmethod
    def for_evaluation(cls, context: EvalContext) -> HardHumanIoU:
        return cls(context.scorer, context.canonical())

    def update(self, batch: BatchResult) -> None:
        for _, item, one, gt, rec in batch.scored():
            if self.canonical.applies_to(item):
                score = self.scorer(self.canonical.pose(item.subject, one).part_meshes(0), gt)
                self.scores.append(score)
                self.groups.append(item.subject)
                rec.update(hard_iou=score.iou, hard_clipped=score.clipped, hard_error=score.error)

    def summary(self) -> IoUSummary | None:
        return summarize(self.scores, self.groups) if self.scores else None

    @staticmethod
    def outputs(hard: HardHumanIoU | None) -> dict[str, Any]:
        """Its entries of a result: ``hard`` (the summary, ``None``: not run or nothing scored) and
        ``canonical`` (``{subject: dataset index}`` of the images the shapes came from)."""
        return {"hard": None if hard is None else hard.summary(),
                "canonical": {} if hard is None else dict(hard.canonical.indices)}


class PartVisibility:
    """How often each learned part is wholly hidden in its input view (one render per batch, see
    :mod:`cerberus_core.eval.visibility`); adds ``visible_pixels`` (per part) to each record."""

    def __init__(self, renderer: Renderer) -> None:
        self.renderer = renderer
        self.counts: VisibilityAccumulator | None = None

    @classmethod
    def for_evaluation(cls, context: EvalContext) -> PartVisibility:
        return cls(context.renderer)

    def update(self, batch: BatchResult) -> None:
        shown = part_pixel_counts(batch.part_id(self.renderer), batch.recon.num_parts)
        if self.counts is None:
            self.counts = VisibilityAccumulator(batch.recon.num_parts, (batch.camera.height, batch.camera.width))
        self.counts.add(shown)
        for b, rec in enumerate(batch.records):
            rec["visible_pixels"] = shown[b].tolist()

    def summary(self) -> dict[str, Any] | None:
        return None if self.counts is None else self.counts.summary()


class PartQuality:
    """The learned parts against the ground-truth semantic parts (:mod:`cerberus_core.eval.part_quality`):
    one overlap matrix per image, in one part vocabulary."""

    def __init__(self, weighting: str = "area", density: int = 4) -> None:
        self.weighting = weighting
        self.density = density
        self.overlaps: PartQualityAccumulator | None = None

    @classmethod
    def for_evaluation(cls, context: EvalContext) -> PartQuality:
        return cls(context.config.weighting, context.config.density)

    def update(self, batch: BatchResult) -> None:
        faces = batch.recon.faces.numpy()
        for b, item, one, _, _ in batch.scored():
            body = batch.bodies[b]
            if self.overlaps is None:
                self.overlaps = PartQualityAccumulator(batch.recon.num_parts, list(body.part_names))
            elif list(body.part_names) != self.overlaps.gt_part_names:
                raise DatasetError(f"item {item.index}: ground-truth part names {body.part_names} differ from the "
                                   f"first item's {self.overlaps.gt_part_names}; part quality needs one part "
                                   "vocabulary: evaluate a dataset of one body source")
            self.overlaps.add(image_overlap(one.posed()[0].numpy(), faces, body.vertices, body.faces,
                                            body.vertex_parts, len(body.part_names), weighting=self.weighting,
                                            density=self.density), item.subject)

    def summary(self) -> dict[str, Any] | None:
        return None if self.overlaps is None else self.overlaps.summary()


class BodySegments:
    """Per ground-truth body segment, recall and off-body voxels; per learned part, the IoU lost when it
    is deleted; per segment, its coverage in the input view (:mod:`cerberus_core.eval.segments`, from
    the voxels :class:`StandardIoU` scores and the render :class:`PartVisibility` counts). Adds
    ``voxel_precision``, ``voxel_recall``, ``segment_recall`` and ``deletion_loss`` to each record.

    Args:
        scorer: the standard IoU's scorer (its voxels are reused).
        renderer: the backend of the input-view renders (``None``: no coverage).
    """

    def __init__(self, scorer: VoxelScorer, renderer: Renderer | None) -> None:
        self.scorer = scorer
        self.renderer = renderer
        self.counts: SegmentAccumulator | None = None

    @classmethod
    def for_evaluation(cls, context: EvalContext) -> BodySegments:
        return cls(context.scorer, context.renderer)

    def update(self, batch: BatchResult) -> None:
        coverage = self._coverage(batch) if self.renderer is not None else [None] * len(batch.items)
        for b, item, one, _, rec in batch.scored():
            body = batch.bodies[b]
            if self.counts is None:
                self.counts = SegmentAccumulator(list(body.part_names), one.num_parts)
            elif list(body.part_names) != self.counts.segments:
                raise DatasetError(f"item {item.index}: ground-truth segments {body.part_names} differ from the first "
                                   f"item's {self.counts.segments}; body segments need one vocabulary: evaluate a "
                                   "dataset of one body source")
            image = image_segments(batch.voxels(b, self.scorer), body.vertices, body.vertex_parts,
                                   len(body.part_names), coverage[b])
            self.counts.add(image)
            rec.update(image.record())

    def _coverage(self, batch: BatchResult) -> list[tuple[np.ndarray, np.ndarray]]:
        """Per image, which ground-truth vertices project onto a pixel covered by the predicted parts
        and by the ground truth's own render (:meth:`BatchResult.gt_foreground`)."""
        predicted = batch.part_id(self.renderer) >= 0
        own = batch.gt_foreground(self.renderer)
        camera = batch.camera.to("cpu")
        out: list[Any] = [None] * len(batch.items)
        for group in group_by_body(batch.bodies):
            body = batch.bodies[group[0]]
            cams = camera.index(group)
            verts = torch.as_tensor(body.vertices, dtype=torch.float32).expand(len(group), -1, -1)
            covered = covered_vertices(predicted[group], verts, cams).numpy()
            gt_covered = covered_vertices(own[group], verts, cams).numpy()
            for k, b in enumerate(group):
                out[b] = (covered[k], gt_covered[k])
        return out

    def summary(self) -> dict[str, Any] | None:
        return None if self.counts is None else self.counts.summary()


class Allocation:
    """Where the learned parts go (:mod:`cerberus_core.eval.allocation`): per part its keypoint's spread
    around the silhouette centroid and the foreground it alone covers, per ground-truth segment the
    distance to the nearest keypoint; adds ``keypoints`` (per part, ``[u, v]`` px) and ``unique_coverage``
    (per part) to each record. Renders each part alone once per batch, and reuses the ground truth's
    render (:meth:`BatchResult.gt_foreground`)."""

    def __init__(self, renderer: Renderer) -> None:
        self.renderer = renderer
        self.counts: AllocationAccumulator | None = None

    @classmethod
    def for_evaluation(cls, context: EvalContext) -> Allocation:
        return cls(context.renderer)

    def update(self, batch: BatchResult) -> None:
        if self.counts is None:
            self.counts = AllocationAccumulator(list(batch.bodies[0].part_names), batch.recon.num_parts)
        for item, body in zip(batch.items, batch.bodies, strict=True):
            if list(body.part_names) != self.counts.segments:
                raise DatasetError(f"item {item.index}: ground-truth segments {body.part_names} differ from the first "
                                   f"item's {self.counts.segments}; allocation needs one vocabulary of segments: "
                                   "evaluate a dataset of one body source")
        foreground = batch.gt_foreground(self.renderer)
        layouts: dict[tuple[int, bytes], list[int]] = {}  # one vertex layout per group (animals: one per species)
        for b, body in enumerate(batch.bodies):
            layouts.setdefault((len(body.vertices), np.asarray(body.vertex_parts).tobytes()), []).append(b)
        parts = []
        for group in layouts.values():
            first = batch.bodies[group[0]]
            vertices = torch.stack([torch.as_tensor(batch.bodies[b].vertices, dtype=torch.float32) for b in group])
            parts.append((group, measure_allocation(self.renderer, batch.recon.index(group), batch.camera.index(group),
                                                    foreground[group], (vertices, torch.as_tensor(first.vertex_parts),
                                                                        len(first.part_names)))))
        order = np.argsort(np.concatenate([g for g, _ in parts]), kind="stable")  # back to the batch's order
        measured = ImageAllocation(*(np.concatenate([getattr(m, f.name) for _, m in parts])[order]
                                     for f in fields(ImageAllocation)))
        self.counts.add(measured)
        for b, rec in enumerate(batch.records):
            rec["keypoints"] = [[round(float(u), 3), round(float(v), 3)] for u, v in measured.keypoints[b]]
            rec["unique_coverage"] = [round(float(c), 5) for c in measured.unique[b]]

    def summary(self) -> dict[str, Any] | None:
        return None if self.counts is None else self.counts.summary()
