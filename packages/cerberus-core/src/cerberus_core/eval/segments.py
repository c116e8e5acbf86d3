"""Body segments: which parts of the body a reconstruction misses, where its extra voxels lie, which
learned parts matter, and what the input view already shows of each segment. (Beyond the paper.)

Everything voxel-based here comes from the voxels the standard IoU is scored on
(:meth:`cerberus_core.eval.standard.VoxelScorer.voxels`: the same voxelization, each predicted part
kept apart), so it adds no voxelization. Per test image (:func:`image_segments`):

* **Segment of a voxel.** A voxel belongs to the ground-truth segment (``PosedBody.vertex_parts``:
  head, torso, lower_arm.L, ...) of the ground-truth vertex nearest to its centre (a k-d tree).
* **Recall per segment**: the fraction of a segment's ground-truth voxels that the prediction (the
  union of its parts) covers. **Missed** voxels are ground truth only.
* **Off-body voxels**: predicted voxels outside the ground truth, each attributed to the nearest
  segment (same rule); a segment's *off-body share* is its share of all of them.
* **Deletion loss** per learned part (:func:`deletion_losses`): the voxel IoU minus the IoU of the
  prediction without that part (the voxels only it covers removed). A part whose mean loss over the
  test set is at most :data:`SPARE_LOSS` is *spare*: the reconstruction barely needs it.
* **Input-view coverage** per segment (:func:`covered_vertices`): the fraction of a segment's
  ground-truth vertices that project onto a pixel the predicted parts cover in the input view
  (the reconstruction rendered from the image's camera, at the image's size), beside the same
  fraction for the ground truth's own render (the ceiling at that resolution: vertices of thin limbs
  project between pixel centres). A segment missed in the voxels but covered in the image is a depth
  problem; one missed in the image already is a silhouette problem.

Over the test set (:class:`BodySegments`) voxel and vertex counts are summed before dividing
(pooled over all voxels: a large body weighs more than a small one), and deletion losses are averaged over
images; the voxel precision and recall are given per image too (their means over the images, the statistic
``cerberus compare`` pairs).

**No segment labels.** A mesh folder without ``parts.npy`` has one ground-truth part, ``body``; then
no per-segment figure is scored (``segment_labels`` is ``False`` and ``note`` says so in one line),
while the overall voxel precision and recall, the deletion losses and the spare parts still are.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from cerberus_core.errors import ConfigError, DatasetError, MissingPackageError
from cerberus_core.eval.markdown import fmt, markdown_table, part_labels, sentence
from cerberus_core.eval.standard import Voxels, VoxelScorer
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

SPARE_LOSS = 0.003
"""A learned part whose deletion costs at most this much voxel IoU (mean over the test set) is spare."""


def nearest_labels(points: np.ndarray, vertices: np.ndarray, labels: np.ndarray) -> np.ndarray:
    """``(N,)`` the label of the vertex nearest to each of ``points`` ``(N, 3)`` (``vertices`` ``(V, 3)``,
    ``labels`` ``(V,)``; same frame)."""
    try:
        from scipy.spatial import cKDTree
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise MissingPackageError("body-segment evaluation needs scipy: pip install 'cerberus-core[eval]', "
                                  "or pass `skip=('segments',)`") from exc
    if len(points) == 0:
        return np.zeros(0, np.int64)
    _, idx = cKDTree(np.asarray(vertices, np.float64)).query(np.asarray(points, np.float64), k=1)
    return np.asarray(labels, np.int64)[idx]


def deletion_losses(parts: np.ndarray, gt: np.ndarray) -> np.ndarray:
    """Voxel IoU lost when each part is deleted.

    Args:
        parts: ``(P, X, Y, Z)`` bool, each part's voxels; gt: ``(X, Y, Z)`` bool (not empty).
    Returns:
        ``(P,)`` float64: ``IoU(union of parts, gt) - IoU(union of the other parts, gt)`` (>= 0 only
        where the part helps; a part wholly off the body has a negative loss).
    """
    check_shapes("deletion_losses", parts=(parts, "P X Y Z"), gt=(gt, "X Y Z"))
    count = parts.sum(axis=0, dtype=np.int32)
    union = count > 0
    inter = int(np.count_nonzero(union & gt))
    total = int(np.count_nonzero(union | gt))
    sole = parts & (count == 1)  # voxels only this part covers: deleting it removes exactly these
    sole_in = np.count_nonzero(sole & gt, axis=(1, 2, 3))
    sole_out = np.count_nonzero(sole & ~gt, axis=(1, 2, 3))
    return inter / total - (inter - sole_in) / (total - sole_out)


def covered_vertices(mask: Tensor, vertices: Tensor, camera: Camera) -> Tensor:
    """Which vertices project onto a pixel of a mask.

    Args:
        mask: ``(B, H, W)`` bool, e.g. where a render shows anything.
        vertices: ``(B, V, 3)`` world coordinates.
        camera: ``B`` cameras of size ``H x W``.
    Returns:
        ``(B, V)`` bool: the vertex's projection lies in a pixel (``[j, j + 1)``) where ``mask`` is set
        (occluded vertices count: coverage, not visibility; vertices off the image are uncovered).
    """
    check_shapes("covered_vertices", mask=(mask, "B H W"), vertices=(vertices, "B V 3"))
    uv, _ = camera.project(vertices)
    col, row = uv[..., 0].floor().long(), uv[..., 1].floor().long()
    h, w = mask.shape[-2:]
    inside = (col >= 0) & (col < w) & (row >= 0) & (row < h)
    flat = (row.clamp(0, h - 1) * w + col.clamp(0, w - 1))
    return inside & torch.gather(mask.reshape(mask.shape[0], -1), 1, flat)


@dataclass
class ImageSegments:
    """One image's counts per ground-truth segment (``K``) and per learned part (``P``).

    Attributes:
        gt_voxels, hit_voxels, off_voxels: ``(K,)`` the segment's ground-truth voxels, those the
            prediction covers, and the off-body predicted voxels attributed to it.
        deletion_loss: ``(P,)`` :func:`deletion_losses`.
        vertices, covered, gt_covered: ``(K,)`` the segment's ground-truth vertices, those projecting
            onto a pixel the predicted parts cover in the input view, and onto one the ground truth's
            own render covers (all zero when coverage was not measured).
    """

    gt_voxels: np.ndarray
    hit_voxels: np.ndarray
    off_voxels: np.ndarray
    deletion_loss: np.ndarray
    vertices: np.ndarray
    covered: np.ndarray
    gt_covered: np.ndarray

    def record(self) -> dict[str, Any]:
        """What an image's record keeps: voxel precision and recall, recall per segment (``None``
        where the segment has no voxel) and the deletion loss per learned part."""
        pred = int(self.hit_voxels.sum() + self.off_voxels.sum())
        gt = int(self.gt_voxels.sum())
        return {"voxel_precision": float(self.hit_voxels.sum() / pred) if pred else None,
                "voxel_recall": float(self.hit_voxels.sum() / gt) if gt else None,
                "segment_recall": [round(float(h / g), 5) if g else None
                                   for h, g in zip(self.hit_voxels, self.gt_voxels, strict=True)],
                "deletion_loss": [round(float(v), 5) for v in self.deletion_loss]}


def image_segments(voxels: Voxels, gt_vertices: np.ndarray, vertex_parts: np.ndarray, num_segments: int,
                   coverage: tuple[np.ndarray, np.ndarray] | None = None) -> ImageSegments:
    """The counts of one image (see the module docstring).

    Args:
        voxels: the image's :class:`~cerberus_core.eval.standard.Voxels`.
        gt_vertices: ``(V, 3)`` the ground-truth mesh's vertices (mesh units, the frame voxelized);
            vertex_parts: ``(V,)`` their segments, ``num_segments`` of them.
        coverage: ``(covered, gt_covered)``, ``(V,)`` bool each (:func:`covered_vertices` for the
            prediction's and the ground truth's renders), or ``None``.
    """
    labels = np.asarray(vertex_parts, np.int64)
    union = voxels.union
    occupied = voxels.gt | union
    seg = nearest_labels(voxels.centers(np.argwhere(occupied)), gt_vertices, labels)  # one k-d tree per image
    in_gt = voxels.gt[occupied]  # np.argwhere and boolean indexing share C order
    gt_seg, off_seg = seg[in_gt], seg[~in_gt]
    hit = union[voxels.gt]
    k = num_segments
    zeros = np.zeros(k, np.int64)
    counts = np.bincount(labels, minlength=k)
    return ImageSegments(
        gt_voxels=np.bincount(gt_seg, minlength=k), hit_voxels=np.bincount(gt_seg[hit], minlength=k),
        off_voxels=np.bincount(off_seg, minlength=k), deletion_loss=deletion_losses(voxels.parts, voxels.gt),
        vertices=counts if coverage is not None else zeros,
        covered=zeros if coverage is None else np.bincount(labels[coverage[0]], minlength=k),
        gt_covered=zeros if coverage is None else np.bincount(labels[coverage[1]], minlength=k))


def _mean_of(records: Sequence[Mapping[str, Any]], key: str) -> float | None:
    """The mean of ``key`` over the records that have it (``None``: none has)."""
    values = [r[key] for r in records if r.get(key) is not None]
    return float(np.mean(values)) if values else None


def _ratio(num: np.ndarray, den: np.ndarray) -> list[float | None]:
    return [float(n / d) if d else None for n, d in zip(num, den, strict=True)]


@dataclass
class BodySegments:
    """Per ground-truth body segment, recall and off-body voxels; per learned part, the IoU lost when it is
    deleted; per segment, its coverage in the input view, over a test set: the accumulator of the ``segments``
    row of :data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS`.

    The evaluation feeds it :class:`~cerberus_core.eval.accumulators.BatchResult` s (:meth:`update`: the voxels
    the standard IoU scores, :meth:`BatchResult.voxels`, and the input-view renders,
    :meth:`BatchResult.part_id` and :meth:`BatchResult.gt_foreground`); it adds ``voxel_precision``,
    ``voxel_recall``, ``segment_recall`` and ``deletion_loss`` to each record. :meth:`add` takes one image's
    :class:`ImageSegments` directly.

    Args:
        scorer: the standard IoU's :class:`~cerberus_core.eval.standard.VoxelScorer` (its voxels are reused;
            what :meth:`update` needs).
        renderer: the backend of the input-view renders (``None``: no coverage).
        segments: the ``K`` ground-truth segment names (``None``: the first image's).
        num_parts: learned parts ``P`` (``None``: the first image's).
    """

    scorer: VoxelScorer | None = None
    renderer: Renderer | None = None
    segments: list[str] | None = None
    num_parts: int | None = None
    images: list[ImageSegments] = field(default_factory=list)

    @classmethod
    def for_evaluation(cls, context: Any) -> BodySegments:
        """From an :class:`~cerberus_core.eval.accumulators.EvalContext`: its scorer and renderer."""
        return cls(context.scorer, context.renderer)

    def update(self, batch: Any) -> None:
        """Count each image's voxels and covered vertices per segment; every image must share the first one's
        segment names, else a :class:`DatasetError`."""
        coverage = self._coverage(batch) if self.renderer is not None else [None] * len(batch.items)
        for b, item, one, _, rec in batch.scored():
            body = batch.bodies[b]
            self.segments = one_vocabulary(self.segments, item.index, body.part_names, "body segments")
            self.num_parts = one.num_parts if self.num_parts is None else self.num_parts
            image = image_segments(batch.voxels(b, self.scorer), body.vertices, body.vertex_parts,
                                   len(body.part_names), coverage[b])
            self.add(image)
            rec.update(image.record())

    def _coverage(self, batch: Any) -> list[tuple[np.ndarray, np.ndarray]]:
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

    def add(self, image: ImageSegments) -> None:
        """Record one image's counts (:func:`image_segments`)."""
        vocabulary_set("BodySegments", self.segments, self.num_parts)
        check_shapes("BodySegments.add", gt_voxels=(image.gt_voxels, f"{len(self.segments)}"),
                     deletion_loss=(image.deletion_loss, f"{self.num_parts}"))
        self.images.append(image)

    def summary(self) -> dict[str, Any] | None:
        """``None`` when no image was added, else a dict: ``images``, ``segments`` (K names), ``segment_labels`` (bool: at least two
        segments hold voxels), ``note`` (one line without segment labels, else ``None``),
        ``voxel_precision`` and ``voxel_recall`` (pooled over every voxel of every image),
        ``image_mean_voxel_precision`` and ``image_mean_voxel_recall`` (the mean over images of each image's own,
        leaving out an image without a predicted, or ground-truth, voxel), ``spare_threshold``,
        ``deletion_loss`` (per learned part, mean over images), ``spare_parts`` (their indices) and
        ``spare_count``; and per segment, ``{name: value}`` (``None`` where undefined; empty without
        segment labels): ``body_share`` (its share of the ground-truth voxels), ``recall``,
        ``missed_share`` (its share of the missed voxels), ``off_body_share``, ``input_view_coverage``
        and ``gt_render_coverage`` (the last two empty when coverage was not measured).
        """
        if not self.images:
            return None

        def total(name: str) -> np.ndarray:
            return np.sum([getattr(im, name) for im in self.images], axis=0)

        gt, hit, off = total("gt_voxels"), total("hit_voxels"), total("off_voxels")
        per_image = [im.record() for im in self.images]
        verts, covered, gt_covered = total("vertices"), total("covered"), total("gt_covered")
        loss = np.mean([im.deletion_loss for im in self.images], axis=0)
        spare = [p for p in range(self.num_parts) if loss[p] <= SPARE_LOSS]
        present = [self.segments[k] for k in np.flatnonzero(gt > 0)]
        labelled = len(present) >= 2
        out: dict[str, Any] = {
            "images": len(self.images), "segments": list(self.segments), "segment_labels": labelled,
            "note": None if labelled else (
                f"no segment labels: the ground truth has {len(present)} labelled segment"
                f"{'' if len(present) == 1 else 's'} ({', '.join(present) or 'none'}), so nothing is scored per "
                "segment; give the meshes per-vertex part labels (parts.npy) to score it"),
            "voxel_precision": float(hit.sum() / (hit.sum() + off.sum())) if hit.sum() + off.sum() else None,
            "voxel_recall": float(hit.sum() / gt.sum()) if gt.sum() else None,
            "image_mean_voxel_precision": _mean_of(per_image, "voxel_precision"),
            "image_mean_voxel_recall": _mean_of(per_image, "voxel_recall"),
            "spare_threshold": SPARE_LOSS,
            "deletion_loss": [float(v) for v in loss],
            "spare_parts": spare, "spare_count": len(spare),
            "body_share": {}, "recall": {}, "missed_share": {}, "off_body_share": {},
            "input_view_coverage": {}, "gt_render_coverage": {},
        }
        if not labelled:
            return out
        missed = gt - hit
        per_segment = {"body_share": _ratio(gt, np.full_like(gt, gt.sum())), "recall": _ratio(hit, gt),
                       "missed_share": _ratio(missed, np.full_like(missed, missed.sum())),
                       "off_body_share": _ratio(off, np.full_like(off, off.sum()))}
        if verts.sum():
            per_segment |= {"input_view_coverage": _ratio(covered, verts),
                            "gt_render_coverage": _ratio(gt_covered, verts)}
        for key, values in per_segment.items():
            out[key] = dict(zip(self.segments, values, strict=True))
        return out


def segments_line(summary: dict[str, Any], lowest: int = 4) -> str:
    """One line for a console: the ``lowest`` segment recalls and the spare parts, e.g. ``voxel recall
    by body segment: lowest lower_arm.R 0.13, lower_arm.L 0.15 (highest torso 0.91); spare learned parts
    (deleting one costs <= 0.003 IoU): 6 of 9``; works on :meth:`BodySegments.summary` or its JSON form."""
    spare = (f"spare learned parts (deleting one costs <= {summary['spare_threshold']:g} IoU): "
             f"{summary['spare_count']} of {len(summary['deletion_loss'])}")
    recall = {k: v for k, v in summary["recall"].items() if v is not None}
    if not summary["segment_labels"] or not recall:
        return f"{summary['note'] or 'no segment recall'}; {spare}"
    order = sorted(recall, key=recall.get)
    best = order[-1]
    return ("voxel recall by body segment: lowest " + ", ".join(f"{k} {recall[k]:.2f}" for k in order[:lowest])
            + f" (highest {best} {recall[best]:.2f}); {spare}")


def one_vocabulary(known: list[str] | None, index: int, names: Sequence[str], who: str) -> list[str]:
    """The ground-truth segment names an accumulator keeps: image ``index``'s ``names`` when it has none yet
    (``known`` is ``None``), else ``known`` when ``names`` equal them, else a :class:`DatasetError` naming the
    item (``who``: the diagnostic, e.g. ``"part quality"``). Part quality, body segments and allocation count per
    segment, so every image they score must share one vocabulary (one body source).

    >>> one_vocabulary(None, 0, ("head", "torso"), "allocation")
    ['head', 'torso']
    >>> one_vocabulary(["head", "torso"], 5, ("body",), "allocation")
    Traceback (most recent call last):
    ...
    cerberus_core.errors.DatasetError: item 5: ground-truth segments ['body'] differ from the first item's ['head', 'torso']; allocation needs one vocabulary of segments: evaluate a dataset of one body source
    """
    if known is None:
        return list(names)
    if list(names) != known:
        raise DatasetError(f"item {index}: ground-truth segments {list(names)} differ from the first item's {known}; "
                           f"{who} needs one vocabulary of segments: evaluate a dataset of one body source")
    return known


def vocabulary_set(who: str, segments: list[str] | None, num_parts: int | None, key: str = "segments") -> None:
    """Before :meth:`add` of an accumulator that counts per segment and part: both set (:meth:`update` sets them
    from the first image), else a :class:`ConfigError` naming the fix."""
    if segments is None or num_parts is None:
        raise ConfigError.about(key if segments is None else "num_parts", None,
                                f"{who}.add needs the ground-truth segment names and the learned part count; "
                                f"update() takes them from the first batch; to add by hand, make it with "
                                f"`{who}({key}=[...], num_parts=P)`")


def group_by_body(bodies: Sequence[Any]) -> list[list[int]]:
    """Indices of a batch's images grouped by their ground-truth body object (the views of a pose share
    one), in first-seen order: one render per group."""
    groups: dict[int, list[int]] = {}
    for b, body in enumerate(bodies):
        groups.setdefault(id(body), []).append(b)
    return list(groups.values())


def _image_means(seg: Mapping[str, Any]) -> str:
    """``"; per image, mean precision 0.7722 and recall 0.8774"``, or ``""`` for a result written before they were."""
    if "image_mean_voxel_precision" not in seg:
        return ""
    return (f"; per image, mean precision {fmt(seg['image_mean_voxel_precision'])} and recall "
            f"{fmt(seg['image_mean_voxel_recall'])} (as the voxel IoU is averaged)")


def segments_section(result: Mapping[str, Any]) -> list[str]:
    """The report's body-segment section from a result's JSON form: per segment, then per learned part."""
    seg = result["segments"]
    out = ["## Body segments", "",
           f"Voxels as the standard IoU scores them, {seg['images']} images: precision {fmt(seg['voxel_precision'])}, "
           f"recall {fmt(seg['voxel_recall'])}, pooled over all voxels (every image's voxels counted together, as "
           f"every figure of this section but the deletion losses){_image_means(seg)}. "
           f"{sentence(segments_line(seg))}.", ""]
    if seg["segment_labels"]:
        out += ["Each voxel belongs to the segment of the nearest ground-truth vertex. *Recall*: the share of the "
                "segment's voxels the prediction covers; *missed* and *off-body*: its share of the voxels only "
                "the ground truth has, and of those only the prediction has; *input view*: the share of its "
                "ground-truth vertices that project onto a pixel the predicted parts cover, beside the same for "
                "the ground truth's own render.", ""]
        cov = seg["input_view_coverage"]
        rows = [[k, seg["body_share"][k], seg["recall"][k], seg["missed_share"][k], seg["off_body_share"][k],
                 *([cov[k], seg["gt_render_coverage"][k]] if cov else [])] for k in seg["segments"]]
        out += [markdown_table(["GT segment", "Share of body", "Recall", "Share of missed", "Share of off-body",
                                *(["Input view: predicted", "Input view: ground truth"] if cov else [])], rows, 3), ""]
    labels = part_labels(result)
    rows = [[p, labels.get(p) or "-", loss, "spare" if p in seg["spare_parts"] else ""]
            for p, loss in enumerate(seg["deletion_loss"])]
    out += [f"IoU lost when a learned part is deleted (mean over images; spare: at most {seg['spare_threshold']:g}):",
            "", markdown_table(["Learned part", "Majority GT part", "IoU lost when deleted", "Spare"], rows, 4), ""]
    return out
