"""Allocation: do the learned parts go where the body's limbs are? (Beyond the paper.)

A part set can score a fair IoU while every part's keypoint sits at the body's centre and the parts
reach the limbs by stretching. Three numbers per test set tell the two apart, all in the input view
(``H x W`` pixels of the input image, pixel centres at ``j + 0.5``):

* **Keypoint** of part ``k``: the model's expected pixel coordinate ``Predictions.maps.uv`` (equation 1
  before unprojection). It is read back from the part's world translation projected with the input
  camera (:func:`keypoints`), which is exactly where the model unprojected it from, so any model that
  returns a :class:`~cerberus_core.parts.PartSet` is measured the same way.
* **Keypoint spread** per learned part (:func:`keypoint_spread`): the standard deviation over images of
  (keypoint − silhouette centroid), the RMS of its two axes, in pixels. The silhouette is the ground
  truth's own render in the input view (its centroid: the mean pixel centre). A keypoint that moves
  with the body's centre has a spread near 0; one that follows a forearm spreads like the forearm.
  The same spread of each ground-truth segment's projected centroid is reported beside it, for scale.
* **Segment → keypoint** per ground-truth segment (:func:`nearest_keypoint_distances`): the median over
  images of the distance from the segment's vertex centroid (the mean of its vertices, projected with
  the input camera) to the nearest keypoint, in pixels. Without segment labels (a mesh folder without
  ``parts.npy``) the one segment ``body`` is the whole body: allocation needs no labels.
* **Unique coverage** per learned part (:func:`unique_coverage`): the share of the ground truth's
  foreground pixels that this part alone covers in the input view (each part rendered on its own: a
  pixel counts when its silhouette holds it and no other part's does, hidden or not), mean over images.
  A part that adds almost nothing alone is spare even when it is visible.

One rule for every figure over the test set (:meth:`Allocation.summary`): an image whose ground-truth foreground is
empty (the body wholly out of its input view) has no silhouette centroid and no foreground to share, so it is left
out of all of them (``empty_foreground_images`` counts it; its record's ``unique_coverage`` is ``null``), and
``images`` counts the images they are over.

These are the columns of the limb screen (``docs/results.md``; the lead's table in issue 38), and
``cerberus train`` logs the same numbers on a fixed batch of test views (``train.allocation_every``).
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import Any

import numpy as np
import torch

from cerberus_core.errors import ShapeError
from cerberus_core.eval.markdown import markdown_table, part_labels, sentence
from cerberus_core.eval.masks import coverage_masks
from cerberus_core.eval.segments import one_vocabulary, vocabulary_set
from cerberus_core.parts import PartSet
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

SPARE_COVERAGE = 0.02
"""A learned part that alone covers at most this share of the foreground (mean over images) is counted
in the one-line summary as adding little alone."""


def keypoints(recon: PartSet, camera: Camera) -> Tensor:
    """Each part's keypoint: its world translation projected with the input camera.

    For a :class:`~cerberus_core.model.Cerberus` model this is ``Predictions.maps.uv`` (the translation
    is that pixel unprojected at the predicted depth with the same camera), to float precision.

    Args:
        recon: ``B`` reconstructions of ``P`` parts (world frame).
        camera: their ``B`` input cameras.
    Returns:
        ``(B, P, 2)`` pixel coordinates ``(u, v)``, on the camera's device.

    Example:
        >>> cam = Camera.look_at(0.0, 0.0, 3.0, image_size=64)
        >>> parts = PartSet(torch.zeros(1, 1, 4, 3), torch.tensor([[0, 1, 2]]), torch.eye(3).expand(1, 1, 3, 3),
        ...                 torch.zeros(1, 1, 3))
        >>> keypoints(parts, cam)  # the origin, at the image's centre
        tensor([[[32., 32.]]])
    """
    if recon.batch_size != camera.batch_size:
        raise ShapeError(f"keypoints: {recon.batch_size} reconstructions but {camera.batch_size} cameras; pass one "
                         "camera per reconstruction")
    return camera.project(recon.translations.to(camera.device))[0]


def silhouette_centroids(mask: Tensor) -> Tensor:
    """The mean pixel centre of each mask.

    Args:
        mask: ``(B, H, W)`` bool foreground.
    Returns:
        ``(B, 2)`` float ``(u, v)`` in pixels (centres at ``j + 0.5``); NaN for an empty mask.

    Example:
        >>> m = torch.zeros(1, 4, 4, dtype=torch.bool)
        >>> m[0, 1:3, 0:2] = True
        >>> silhouette_centroids(m)
        tensor([[1., 2.]])
    """
    check_shapes("silhouette_centroids", mask=(mask, "B H W"))
    h, w = mask.shape[-2:]
    weight = mask.float()
    total = weight.sum(dim=(-2, -1))
    u = (weight.sum(-2) * (torch.arange(w, device=mask.device) + 0.5)).sum(-1) / total
    v = (weight.sum(-1) * (torch.arange(h, device=mask.device) + 0.5)).sum(-1) / total
    return torch.stack([u, v], dim=-1)


def segment_centroids(vertices: Tensor, vertex_parts: Tensor, num_segments: int, camera: Camera) -> Tensor:
    """Each ground-truth segment's vertex centroid, projected with each camera.

    Args:
        vertices: ``(B, V, 3)`` world coordinates of each image's ground-truth body.
        vertex_parts: ``(V,)`` int, each vertex's segment in ``[0, num_segments)``.
        camera: ``B`` input cameras.
    Returns:
        ``(B, K, 2)`` pixel coordinates (NaN for a segment with no vertex).
    """
    check_shapes("segment_centroids", vertices=(vertices, "B V 3"), vertex_parts=(vertex_parts, "V"))
    onehot = torch.nn.functional.one_hot(vertex_parts.long(), num_segments).to(vertices.dtype)  # (V, K)
    count = onehot.sum(0)
    centres = torch.einsum("vk,bvd->bkd", onehot, vertices) / count[:, None]  # (B, K, 3); NaN where empty
    return camera.project(centres)[0]


def keypoint_spread(points: np.ndarray, centroids: np.ndarray) -> np.ndarray:
    """The spread of points around each image's silhouette centroid.

    Args:
        points: ``(N, P, 2)`` pixel coordinates of ``P`` points (keypoints, or segment centroids) in ``N``
            images; centroids: ``(N, 2)`` each image's silhouette centroid.
    Returns:
        ``(P,)`` pixels: per point, ``sqrt((std_u² + std_v²) / 2)`` of ``points - centroids`` over the
        images (population standard deviation; images where either is NaN are left out).

    Example:
        >>> pts = np.array([[[1.0, 0.0]], [[-1.0, 0.0]]])  # one point, +-1 px in u around the centroid
        >>> keypoint_spread(pts, np.zeros((2, 2))).round(4)
        array([0.7071])
    """
    check_shapes("keypoint_spread", points=(points, "N P 2"), centroids=(centroids, "N 2"))
    offset = np.asarray(points, np.float64) - np.asarray(centroids, np.float64)[:, None, :]
    std = np.nanstd(offset, axis=0)  # (P, 2)
    return np.sqrt((std ** 2).mean(-1))


def nearest_keypoint_distances(centroids: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Per image and segment, the distance from the segment's projected centroid to the nearest keypoint.

    Args:
        centroids: ``(N, K, 2)`` segment centroids (:func:`segment_centroids`); points: ``(N, P, 2)``
            keypoints (:func:`keypoints`); both in pixels.
    Returns:
        ``(N, K)`` pixels.

    Example:
        >>> nearest_keypoint_distances(np.array([[[0.0, 0.0]]]), np.array([[[3.0, 4.0], [10.0, 0.0]]]))
        array([[5.]])
    """
    check_shapes("nearest_keypoint_distances", centroids=(centroids, "N K 2"), points=(points, "N P 2"))
    gap = np.asarray(centroids, np.float64)[:, :, None, :] - np.asarray(points, np.float64)[:, None, :, :]
    return np.linalg.norm(gap, axis=-1).min(-1)


def part_masks(renderer: Renderer, recon: PartSet, camera: Camera) -> Tensor:
    """Each part's own silhouette in its input view, every part rendered alone (hidden pixels count).

    Args:
        renderer: a backend; recon: ``B`` reconstructions of ``P`` parts (world frame); camera: ``B`` cameras.
    Returns:
        ``(B, P, H, W)`` bool on the camera's device.
    """
    if recon.batch_size != camera.batch_size:
        raise ShapeError(f"part_masks: {recon.batch_size} reconstructions but {camera.batch_size} cameras; pass one "
                         "camera per reconstruction")
    bsz, nparts = recon.batch_size, recon.num_parts
    posed = recon.to(camera.device).posed()  # (B, P, V, 3)
    masks = coverage_masks(renderer, posed.reshape(bsz * nparts, 1, *posed.shape[-2:]), recon.faces.to(camera.device),
                           camera.index(torch.arange(bsz).repeat_interleave(nparts)))
    return masks.reshape(bsz, nparts, *masks.shape[-2:])


def unique_coverage(masks: Tensor, foreground: Tensor) -> Tensor:
    """The share of each image's foreground that one part alone covers.

    Args:
        masks: ``(B, P, H, W)`` bool, each part's silhouette (:func:`part_masks`).
        foreground: ``(B, H, W)`` bool, the ground truth's silhouette.
    Returns:
        ``(B, P)`` float in [0, 1]: ``|foreground ∧ part k ∧ no other part| / |foreground|`` (NaN for an
        empty foreground: there is no share to measure).

    Example:
        >>> fg = torch.ones(1, 1, 4, dtype=torch.bool)
        >>> masks = torch.tensor([[[[1, 1, 1, 0]], [[0, 0, 1, 1]]]], dtype=torch.bool)  # 2 parts, 4 pixels
        >>> unique_coverage(masks, fg)  # part 0 alone on 2 of 4 pixels, part 1 alone on 1
        tensor([[0.5000, 0.2500]])
    """
    check_shapes("unique_coverage", masks=(masks, "B P H W"), foreground=(foreground, "B H W"))
    alone = masks & (masks.sum(1, keepdim=True) == 1) & foreground[:, None]
    area = foreground.flatten(1).sum(-1).unsqueeze(1).float()
    share = alone.flatten(2).sum(-1).float() / area.clamp(min=1)
    return share.masked_fill(area == 0, float("nan"))


@dataclass
class ImageAllocation:
    """One batch's allocation measurements (``B`` images, ``P`` parts, ``K`` segments), pixels of the input.

    Attributes:
        keypoints: ``(B, P, 2)``; centroid: ``(B, 2)`` the ground-truth silhouette's;
        segments: ``(B, K, 2)`` the segments' projected centroids; unique: ``(B, P)`` unique coverage.
    """

    keypoints: np.ndarray
    centroid: np.ndarray
    segments: np.ndarray
    unique: np.ndarray


def measure_allocation(renderer: Renderer, recon: PartSet, camera: Camera, foreground: Tensor,
                       bodies: tuple[Tensor, Tensor, int]) -> ImageAllocation:
    """The measurements of one batch (everything in the module docstring).

    Args:
        renderer: a backend; recon: ``B`` reconstructions; camera: their ``B`` input cameras.
        foreground: ``(B, H, W)`` bool, the ground truth's own render in each input view.
        bodies: ``(vertices (B, V, 3), vertex_parts (V,), K)`` the ground-truth bodies (one vertex
            layout: one body source) and their number of segments.
    """
    vertices, vertex_parts, num_segments = bodies
    cam = camera.to("cpu")
    masks = part_masks(renderer, recon, camera).cpu()
    return ImageAllocation(
        keypoints=keypoints(recon.to("cpu"), cam).double().numpy(),
        centroid=silhouette_centroids(foreground.cpu()).double().numpy(),
        segments=segment_centroids(torch.as_tensor(vertices, dtype=torch.float32), torch.as_tensor(vertex_parts),
                                   num_segments, cam).double().numpy(),
        unique=unique_coverage(masks, foreground.cpu()).double().numpy())


@dataclass
class Allocation:
    """Where the learned parts go over a test set: the accumulator of the ``allocation`` row of
    :data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS` (and of ``cerberus train``'s allocation log).

    The evaluation feeds it :class:`~cerberus_core.eval.accumulators.BatchResult` s (:meth:`update`: each part
    rendered alone once per batch, :func:`measure_allocation`, beside the ground truth's own render,
    :meth:`BatchResult.gt_foreground`); it adds ``keypoints`` (per part, ``[u, v]`` px) and ``unique_coverage``
    (per part) to each record. :meth:`add` takes a batch's :class:`ImageAllocation` directly.

    Args:
        renderer: the backend of the part renders (what :meth:`update` needs).
        segments: the ``K`` ground-truth segment names (``None``: the first batch's).
        num_parts: learned parts ``P`` (``None``: the first batch's).
    """

    renderer: Renderer | None = None
    segments: list[str] | None = None
    num_parts: int | None = None
    batches: list[ImageAllocation] = field(default_factory=list)

    @classmethod
    def for_evaluation(cls, context: Any) -> Allocation:
        """From an :class:`~cerberus_core.eval.accumulators.EvalContext`: its renderer."""
        return cls(context.renderer)

    def update(self, batch: Any) -> None:
        """Measure the batch; every body must share the first one's segments (one body source), else a
        :class:`DatasetError`. Bodies of different vertex layouts (animals of several species) are measured a
        layout at a time and put back in the batch's order."""
        for item, body in zip(batch.items, batch.bodies, strict=True):
            self.segments = one_vocabulary(self.segments, item.index, body.part_names, "allocation")
        self.num_parts = batch.recon.num_parts if self.num_parts is None else self.num_parts
        foreground = batch.gt_foreground(self.renderer)
        layouts: dict[tuple[int, bytes], list[int]] = {}
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
        self.add(measured)
        for b, rec in enumerate(batch.records):
            rec["keypoints"] = [[round(float(u), 3), round(float(v), 3)] for u, v in measured.keypoints[b]]
            rec["unique_coverage"] = [round(float(c), 5) for c in measured.unique[b]]

    def add(self, batch: ImageAllocation) -> None:
        """Record a batch's measurements (:func:`measure_allocation`)."""
        vocabulary_set("Allocation", self.segments, self.num_parts)
        check_shapes("Allocation.add", keypoints=(batch.keypoints, f"B {self.num_parts} 2"),
                     segments=(batch.segments, f"B {len(self.segments)} 2"), unique=(batch.unique, f"B {self.num_parts}"))
        self.batches.append(batch)

    def summary(self) -> dict[str, Any] | None:
        """``None`` when no batch was added, else a dict: ``images`` (the images every figure is over: those whose
        ground-truth foreground is not empty) and ``empty_foreground_images`` (those left out: the module
        docstring's rule); per learned part (lists of ``P``) ``keypoint_spread`` (px) and
        ``unique_coverage`` (mean share of the foreground), ``spare_coverage`` (the threshold of
        :data:`SPARE_COVERAGE`) and ``low_coverage_parts`` (the parts at or below it); per ground-truth
        segment (``{name: value}``) ``segment_to_keypoint`` (median px to the nearest keypoint) and
        ``segment_spread`` (its projected centroid's spread, px, for scale). Every figure is NaN when no image has
        a foreground."""
        if not self.batches:
            return None

        def stack(name: str) -> np.ndarray:
            return np.concatenate([getattr(b, name) for b in self.batches])

        seen = np.isfinite(stack("centroid")).all(-1)  # the images whose ground-truth foreground is not empty
        points, centroid, segments, unique = (stack(name)[seen] for name in ("keypoints", "centroid", "segments",
                                                                             "unique"))
        nothing = np.full(len(self.segments), np.nan)  # no image with a foreground: no figure
        coverage = unique.mean(0) if seen.any() else np.full(self.num_parts, np.nan)
        spread = keypoint_spread(points, centroid) if seen.any() else np.full(self.num_parts, np.nan)
        to_keypoint = np.nanmedian(nearest_keypoint_distances(segments, points), 0) if seen.any() else nothing
        segment_spread = keypoint_spread(segments, centroid) if seen.any() else nothing
        return {
            "images": int(seen.sum()),
            "empty_foreground_images": int((~seen).sum()),
            "keypoint_spread": [round(float(v), 4) for v in spread],
            "unique_coverage": [round(float(v), 5) for v in coverage],
            "spare_coverage": SPARE_COVERAGE,
            "low_coverage_parts": [p for p in range(self.num_parts) if coverage[p] <= SPARE_COVERAGE],
            "segment_to_keypoint": {k: round(float(v), 4) for k, v in zip(self.segments, to_keypoint, strict=True)},
            "segment_spread": {k: round(float(v), 4) for k, v in zip(self.segments, segment_spread, strict=True)},
        }


def allocation_line(summary: dict[str, Any], top: int = 4) -> str:
    """One line for a console: the ``top`` largest keypoint spreads, the ``top`` segments farthest from a
    keypoint and the parts that add little alone, e.g. ``keypoints: spread 1.9 1.8 1.8 1.8 px (largest 4);
    farthest from a keypoint shin.L 19.7 px, shin.R 19.5 px, ...; parts covering <= 2% of the foreground
    alone: 5 of 9``; works on :meth:`Allocation.summary` or its JSON form."""
    spread = sorted((v for v in summary["keypoint_spread"] if v is not None), reverse=True)[:top]
    far = sorted(((v, k) for k, v in summary["segment_to_keypoint"].items() if v is not None), reverse=True)[:top]
    line = "keypoints: spread " + " ".join(f"{v:.1f}" for v in spread) + f" px (largest {len(spread)})"
    if far:
        line += "; farthest from a keypoint " + ", ".join(f"{k} {v:.1f} px" for v, k in far)
    return (line + f"; parts covering <= {100 * summary['spare_coverage']:g}% of the foreground alone: "
            f"{len(summary['low_coverage_parts'])} of {len(summary['unique_coverage'])}")


def _left_out(alloc: Mapping[str, Any]) -> str:
    """The images left out of the allocation figures, said when there are any."""
    empty = alloc.get("empty_foreground_images") or 0
    return (f" ({empty} more left out: the ground-truth body is wholly out of {'its' if empty == 1 else 'their'} "
            "input view, so there is no foreground to measure)") if empty else ""


def allocation_section(result: Mapping[str, Any]) -> list[str]:
    """The report's allocation section from a result's JSON form: per learned part, then per ground-truth
    segment."""
    alloc = result["allocation"]
    line = allocation_line(alloc)
    labels = part_labels(result)
    prow = [[p, labels.get(p) or "-", spread, alloc["unique_coverage"][p]]
            for p, spread in enumerate(alloc["keypoint_spread"])]
    srow = [[k, alloc["segment_to_keypoint"][k], alloc["segment_spread"][k]] for k in alloc["segment_to_keypoint"]]
    return ["## Allocation", "",
            f"Where the parts go, in pixels of the input image, {alloc['images']} images{_left_out(alloc)}. "
            f"{sentence(line)}. "
            "*Keypoint spread*: the standard deviation over images of (keypoint − the ground-truth silhouette's "
            "centroid), RMS of the two axes; *alone covers*: the mean share of the ground-truth foreground that "
            "only this part covers (each part rendered on its own); *to nearest keypoint*: the median distance "
            "from the segment's projected vertex centroid to the nearest keypoint; *segment spread*: the same "
            "spread as the keypoints' for the segment's centroid, for scale.", "",
            markdown_table(["Learned part", "Majority GT part", "Keypoint spread (px)", "Alone covers"], prow, 3), "",
            markdown_table(["GT segment", "To nearest keypoint (px)", "Segment spread (px)"], srow, 2), ""]
