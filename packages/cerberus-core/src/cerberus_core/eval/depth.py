"""Depth seen from the other views: do a model's parts sit at the same 3D place whichever view it sees?

A part can sit well in its input view and still lie at the wrong depth along its camera ray: the input
view cannot tell, the voxel IoU can. The test split shows every pose from several views, so the
evaluation can check depth without any 3D label of the parts. Over the test poses with two or more
views (:class:`DepthAccumulator`):

* **translation disagreement**, per part: the mean distance, in world units, between the part's world
  translations predicted from two views of the same pose, over every pair of views (0: the part is
  placed at the same 3D point from every view; a depth error shows up here as the views disagree);
* **turned-view silhouette IoU**: each image's reconstruction rendered from the cameras of the *other*
  views of its pose, against the ground-truth body's silhouette there, beside the same IoU in the
  input view. A model right in its input view and wrong in depth scores high in the input view and low
  in the turned views.

``experiments/depth/depth_oracle.py`` goes one step further and moves each part along its own ray to
the depth its keypoints triangulate to, which bounds what better depth alone would add to the IoU.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from itertools import combinations
from typing import Any

import torch
from tqdm import tqdm

from cerberus_core.errors import ShapeError
from cerberus_core.eval.markdown import markdown_table, part_labels, sentence
from cerberus_core.eval.masks import coverage_masks, mask_iou
from cerberus_core.parts import PartSet
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor


def translation_disagreement(translations: Tensor) -> Tensor:
    """Mean distance between the translations one part gets from different views of one pose.

    Args:
        translations: ``(K, N, 3)`` world translations of ``N`` parts predicted from ``K >= 2`` views.
    Returns:
        ``(N,)`` per part, the mean over the ``K (K - 1) / 2`` pairs of views of ``||T^x - T^y||``
        (world units).
    Raises:
        ShapeError: ``translations`` not ``(K, N, 3)``, or fewer than 2 views.

    Example: three views of a pose, two parts; view 1 places part 0 0.3 further along x:

        >>> t = torch.zeros(3, 2, 3)  # (K views, N parts, xyz), world units
        >>> t[1, 0, 0] = 0.3  # pairs (0, 1) and (1, 2) differ by 0.3, pair (0, 2) agrees
        >>> translation_disagreement(t)
        tensor([0.2000, 0.0000])
        >>> translation_disagreement(t[:1])
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ShapeError: translation_disagreement: needs the translations of at least 2 views ...
    """
    check_shapes("translation_disagreement", translations=(translations, "K N 3"))
    k = translations.shape[0]
    if k < 2:
        raise ShapeError("translation_disagreement: needs the translations of at least 2 views of the pose; "
                         "pass (K, N, 3) with K >= 2")
    pairs = torch.tensor(list(combinations(range(k), 2)))
    return (translations[pairs[:, 0]] - translations[pairs[:, 1]]).norm(dim=-1).mean(0)


@dataclass
class _PoseViews:
    """What one test pose's images gave: per view, the parts, the camera and the ground-truth body."""

    parts: list[PartSet] = field(default_factory=list)
    cameras: list[Camera] = field(default_factory=list)
    body: tuple[Tensor, Tensor] | None = None


def turned_view_ious(renderer: Renderer, parts: PartSet, cameras: Camera, body: tuple[Tensor, Tensor]) -> Tensor:
    """Silhouette IoU of every view's reconstruction seen from every view of one pose.

    Args:
        renderer: a backend.
        parts: ``K`` reconstructions (world frame), one per view of the pose.
        cameras: the ``K`` views' cameras.
        body: the pose's ground-truth mesh ``(vertices (Vg, 3), faces (Fg, 3))``, world frame.
    Returns:
        ``(K, K)`` float64: entry ``[x, y]`` is reconstruction ``x`` rendered by camera ``y`` against the body's
        silhouette in camera ``y`` (the diagonal: the input views), :func:`~cerberus_core.eval.masks.mask_iou`
        (NaN where both silhouettes are empty: the body out of camera ``y`` and the reconstruction too).

    Example: the body is a ball of radius 0.35 at the origin, seen from the front (camera 0, on +z) and the side
    (camera 1, on +x). View 0's reconstruction is the ball slid 0.4 toward its camera and shrunk to look the same
    there (right in its input view, wrong in depth); view 1's is the ball itself:

        >>> from cerberus_core import make_renderer, icosphere
        >>> ball = icosphere(1, radius=0.35)
        >>> cams = Camera.look_at(torch.tensor([0.0, 90.0]), 0.0, 2.5, image_size=32)  # K = 2 views, 32 x 32 pixels
        >>> parts = PartSet.from_posed(ball.vertices.expand(2, 1, -1, 3).clone(), ball.faces)  # (K, N = 1, V, 3)
        >>> parts.local_vertices[0] *= (2.5 - 0.4) / 2.5
        >>> parts.translations[0, 0] = torch.tensor([0.0, 0.0, 0.4])  # along camera 0's ray
        >>> translation_disagreement(parts.translations)  # world units
        tensor([0.4000])
        >>> ious = turned_view_ious(make_renderer("torch"), parts, cams, (ball.vertices, ball.faces))
        >>> ious.round(decimals=2).tolist()  # [x, y]: reconstruction x seen by camera y; [0, 1] sees the error
        [[1.0, 0.13], [1.0, 1.0]]
    """
    k = parts.batch_size
    if cameras.batch_size != k:
        raise ShapeError(f"turned_view_ious: {k} reconstructions but {cameras.batch_size} cameras; pass one camera "
                         "per reconstruction")
    seen_by = torch.arange(k).repeat(k)  # (x, y) pairs, x major
    from_view = torch.arange(k).repeat_interleave(k)
    posed = parts.posed()[from_view]  # (K K, N, V, 3)
    pred = coverage_masks(renderer, posed, parts.faces, cameras.index(seen_by))
    verts = torch.as_tensor(body[0], dtype=posed.dtype).unsqueeze(0).unsqueeze(0).expand(k, 1, -1, 3)
    truth = coverage_masks(renderer, verts, torch.as_tensor(body[1], dtype=torch.long), cameras)  # (K, H, W)
    return mask_iou(pred, truth[seen_by]).view(k, k)


class DepthAccumulator:
    """Collects each test image's reconstruction by pose and measures depth across its views.

    Feed it :class:`~cerberus_core.eval.accumulators.BatchResult` s (``update``); ``summary()``:
    ``None`` when no pose has two views, else a dict with ``poses`` (the poses measured: those with two views or
    more among the images fed), ``images`` (their images: the only ones every figure here is over; an image whose
    pose has no other view is left out), ``translation_disagreement`` (per part, world units, mean over poses),
    ``mean_translation_disagreement``, ``input_view_silhouette_iou`` and ``turned_view_silhouette_iou`` (means over
    those images and, for the second, over every other view of the image's pose; a pair where the body and the
    reconstruction are both out of the camera has no IoU and is left out: NaN-aware means).

    Args:
        renderer: the backend of the silhouette renders.
        progress: show a progress bar over the poses while :meth:`summary` renders them (``K x K`` renders of a
            pose of ``K`` views, after the evaluation's own bar).
    """

    def __init__(self, renderer: Renderer, progress: bool = False) -> None:
        self.renderer = renderer
        self.progress = progress
        self.poses: dict[tuple[str, int], _PoseViews] = {}

    @classmethod
    def for_evaluation(cls, context: Any) -> DepthAccumulator:
        """From an :class:`~cerberus_core.eval.accumulators.EvalContext`: its renderer and its config's ``progress``."""
        return cls(context.renderer, progress=context.config.progress)

    def update(self, batch: Any) -> None:
        cameras = batch.camera.to("cpu")
        for b, item, one, gt, _ in batch.scored():
            views = self.poses.setdefault((item.subject, item.pose), _PoseViews())
            views.parts.append(one)
            views.cameras.append(cameras.index([b]))
            if views.body is None:  # one body per pose: its views share it
                views.body = (torch.as_tensor(gt[0]), torch.as_tensor(gt[1]))

    def summary(self) -> dict[str, Any] | None:
        disagreement, own, turned = [], [], []
        measured = [views for views in self.poses.values() if len(views.parts) >= 2]
        for views in tqdm(measured, desc="depth", unit="pose", disable=not self.progress):
            parts = PartSet.cat(views.parts)
            disagreement.append(translation_disagreement(parts.translations))
            ious = turned_view_ious(self.renderer, parts, Camera.cat(views.cameras), views.body)
            off = ~torch.eye(len(views.parts), dtype=torch.bool)
            own.append(ious.diagonal())
            turned.append(ious[off])
        if not disagreement:
            return None
        per_part = torch.stack(disagreement).mean(0)
        return {"poses": len(disagreement), "images": sum(len(views.parts) for views in measured),
                "translation_disagreement": [round(float(v), 5) for v in per_part],
                "mean_translation_disagreement": float(per_part.mean()),
                "input_view_silhouette_iou": float(torch.cat(own).nanmean()),
                "turned_view_silhouette_iou": float(torch.cat(turned).nanmean())}


def depth_line(depth: dict[str, Any]) -> str:
    """One sentence of a :meth:`DepthAccumulator.summary` for reports."""
    images = f" ({depth['images']} images)" if depth.get("images") is not None else ""
    poses = f"{depth['poses']} test pose{'' if depth['poses'] == 1 else 's'}"
    return (f"over {poses} seen from several views{images}, each part's world translation "
            f"differs between two views of one pose by {depth['mean_translation_disagreement']:.3f} on average (world "
            f"units); the reconstruction of each of those images covers the body's silhouette with IoU "
            f"{depth['input_view_silhouette_iou']:.3f} in its input view and "
            f"{depth['turned_view_silhouette_iou']:.3f} turned to the pose's other views")


def depth_section(result: Mapping[str, Any]) -> list[str]:
    """The report's depth section from a result's JSON form: the sentence, then each part's translation
    disagreement beside its majority ground-truth part."""
    depth, labels = result["depth"], part_labels(result)
    drow = [[p, labels.get(p) or "-", d] for p, d in enumerate(depth["translation_disagreement"])]
    return ["## Depth across views", "", sentence(depth_line(depth)) + ".", "",
            markdown_table(["Learned part", "Majority GT part", "Translation disagreement"], drow, 3), ""]
