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

    Feed it :class:`~cerberus_core.eval.accumulators.BatchResult` s (``update``); ``summary()``: ``None`` when no
    image was fed, else a dict with ``poses`` (the poses measured: those with two views or more among the images
    fed), ``images`` (their images: the only ones every figure here is over; an image whose pose has no other view
    is left out), ``images_evaluated`` (every image fed: the evaluation's, of which ``images`` were measured),
    ``note`` (``None``, or when no pose has two views among them, why depth was not measured: then ``poses`` and
    ``images`` are 0, the figures ``None`` and ``translation_disagreement`` empty), ``translation_disagreement``
    (per part, world units, mean over poses), ``mean_translation_disagreement``, ``input_view_silhouette_iou`` and
    ``turned_view_silhouette_iou`` (means over those images and, for the second, over every other view of the
    image's pose; a pair where the body and the reconstruction are both out of the camera has no IoU and is left
    out: NaN-aware means).

    Example: one image of a pose, none of another view of it: nothing to compare, and the summary says why:

        >>> from types import SimpleNamespace
        >>> from cerberus_core.eval.hard import ItemMeta
        >>> from cerberus_core.render.templates import icosphere
        >>> ball = icosphere(1, radius=0.35)
        >>> one = PartSet.from_posed(ball.vertices.expand(1, 1, -1, 3).clone(), ball.faces)  # 1 image, 1 part
        >>> camera = Camera.look_at(torch.tensor([0.0]), 0.0, 2.5, image_size=16)
        >>> batch = SimpleNamespace(camera=camera, scored=lambda: [(0, ItemMeta(0, "s1", 0, 0, False), one,
        ...                                                         (ball.vertices, ball.faces), {})])
        >>> depth = DepthAccumulator(renderer=None)
        >>> depth.update(batch)
        >>> summary = depth.summary()
        >>> summary["poses"], summary["images"], summary["images_evaluated"], summary["turned_view_silhouette_iou"]
        (0, 0, 1, None)
        >>> print(summary["note"])
        no pose has two of its views among the 1 image scored (depth compares the views of each pose): score more
        images (a larger limit), or a split that shows each pose from several views

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
        fed = sum(len(views.parts) for views in self.poses.values())  # every image fed is one of a pose's views
        if not fed:
            return None
        if not disagreement:
            return {"poses": 0, "images": 0, "images_evaluated": fed, "note": not_measured(fed),
                    "translation_disagreement": [], "mean_translation_disagreement": None,
                    "input_view_silhouette_iou": None, "turned_view_silhouette_iou": None}
        per_part = torch.stack(disagreement).mean(0)
        return {"poses": len(disagreement), "images": sum(len(views.parts) for views in measured),
                "images_evaluated": fed, "note": None,
                "translation_disagreement": [round(float(v), 5) for v in per_part],
                "mean_translation_disagreement": float(per_part.mean()),
                "input_view_silhouette_iou": float(torch.cat(own).nanmean()),
                "turned_view_silhouette_iou": float(torch.cat(turned).nanmean())}


def not_measured(count: int) -> str:
    """Why depth was not measured over ``count`` images no two of which show one pose (the ``note`` of a
    :meth:`DepthAccumulator.summary`): the evaluation's images, and what would give it poses to compare."""
    return (f"no pose has two of its views among the {count} image{'' if count == 1 else 's'} scored (depth compares "
            "the views of each pose): score more images (a larger limit), or a split that shows each pose from several "
            "views")


def depth_images(depth: Mapping[str, Any]) -> str:
    """``"16 of the 20 images scored"`` (``"all 16 images scored"`` when depth measured every one; ``"16 images"`` for
    a summary from before ``images_evaluated`` was recorded): the images the depth figures are over.

    Example:
        >>> depth_images({"images": 16, "images_evaluated": 20}), depth_images({"images": 16, "images_evaluated": 16})
        ('16 of the 20 images scored', 'all 16 images scored')
        >>> depth_images({"images": 16})
        '16 images'
    """
    images, evaluated = depth["images"], depth.get("images_evaluated")
    if evaluated is None:
        return f"{images} images"
    return f"all {images} images scored" if images == evaluated else f"{images} of the {evaluated} images scored"


def depth_line(depth: dict[str, Any]) -> str:
    """One sentence of a :meth:`DepthAccumulator.summary` (or its JSON form) for reports: what the figures are over
    (how many of the images scored) and the figures, or why depth was not measured (its ``note``).

    Example:
        >>> depth_line({"poses": 0, "images": 0, "images_evaluated": 1, "note": "no pose has two of its views ..."})
        'not measured: no pose has two of its views ...'
    """
    if depth.get("note"):
        return f"not measured: {depth['note']}"
    images = f" ({depth_images(depth)})" if depth.get("images") is not None else ""
    poses = f"{depth['poses']} test pose{'' if depth['poses'] == 1 else 's'}"
    return (f"over {poses} seen from several views{images}, each part's world translation "
            f"differs between two views of one pose by {depth['mean_translation_disagreement']:.3f} on average (world "
            f"units); the reconstruction of each of those images covers the body's silhouette with IoU "
            f"{depth['input_view_silhouette_iou']:.3f} in its input view and "
            f"{depth['turned_view_silhouette_iou']:.3f} turned to the pose's other views")


def depth_section(result: Mapping[str, Any]) -> list[str]:
    """The report's depth section from a result's JSON form: the sentence, then each part's translation
    disagreement beside its majority ground-truth part; one line saying why when depth was not measured."""
    depth, labels = result["depth"], part_labels(result)
    if depth.get("note"):
        return ["## Depth across views", "", sentence(depth_line(depth)) + ".", ""]
    drow = [[p, labels.get(p) or "-", d] for p, d in enumerate(depth["translation_disagreement"])]
    return ["## Depth across views", "", sentence(depth_line(depth)) + ".", "",
            markdown_table(["Learned part", "Majority GT part", "Translation disagreement"], drow, 3), ""]
