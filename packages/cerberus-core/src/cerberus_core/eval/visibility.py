"""Part visibility: how often a learned part is wholly hidden in its own input view.

The paper's renderer (no anti-aliasing) sends a part gradient only through the pixels where it is
the front surface. A part that no pixel of the reconstruction rendered from the input camera shows
(behind other parts, or off-screen) gets no gradient from that image's reconstruction term: it
drifts instead of learning. This module measures, per learned part and over a test set:

* ``hidden_fraction``: the fraction of images in which the part covers no pixel;
* ``mean_visible_pixels``: its mean number of front-surface pixels per image;
* ``mean_silhouette_share``: its mean share of the rendered silhouette (over the images whose
  silhouette is not empty);
* ``parts_hidden_in_most_images``: how many parts are hidden in more than half of the images.

The per-pixel visible part is the ``part_id`` map of :func:`cerberus_core.render.api.render_parts`,
rendered once per image at the camera's (the dataset's) image size. A one-part model (the NMRr
baseline) is hidden only where it leaves the picture.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch

from cerberus_core.errors import ShapeError
from cerberus_core.eval.markdown import markdown_table, scored_part_quality
from cerberus_core.parts import PartSet
from cerberus_core.render.api import part_pixel_counts, render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor


def input_view_part_id(renderer: Renderer, recon: PartSet, camera: Camera) -> Tensor:
    """The part in front at each pixel, seen from the given cameras.

    Args:
        renderer: a backend from :func:`cerberus_core.make_renderer`.
        recon: ``B`` reconstructions of ``P`` parts (world frame).
        camera: ``B`` cameras (the input views); the render is ``camera.height x camera.width``.
    Returns:
        ``(B, H, W)`` int64 on the camera's device: the part index, -1 on background.
    """
    if recon.batch_size != camera.batch_size:
        raise ShapeError(f"input_view_part_id: {recon.batch_size} reconstructions but {camera.batch_size} cameras; "
                         "pass one camera per reconstruction")
    recon = recon.to(camera.device)
    with torch.no_grad():
        return render_parts(renderer, recon.posed(), recon.faces, camera).part_id


def visible_pixels(renderer: Renderer, recon: PartSet, camera: Camera) -> Tensor:
    """Pixels where each part is the front surface, seen from the given cameras (arguments as
    :func:`input_view_part_id`).

    Returns:
        ``(B, P)`` int64 on the CPU: pixel counts (0: the part is wholly hidden in that image).
    """
    return part_pixel_counts(input_view_part_id(renderer, recon, camera), recon.num_parts).cpu()


@dataclass
class PartVisibility:
    """How often each learned part is wholly hidden in its input view, over a test set: the accumulator of the
    ``visibility`` row of :data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS`.

    The evaluation feeds it :class:`~cerberus_core.eval.accumulators.BatchResult` s (:meth:`update`: the batch's
    one input-view render, :meth:`BatchResult.part_id`; adds ``visible_pixels``, per part, to each record);
    :meth:`add` takes per-image counts directly (:func:`visible_pixels`).

    Args:
        renderer: the backend of the input-view render (what :meth:`update` needs).
        num_parts: learned parts ``P`` (``None``: those of the first counts added).
        image_size: ``(H, W)`` of the renders, for the record (``None``: the first batch's cameras' in
            :meth:`update`; with :meth:`add` alone it stays ``None`` and :meth:`summary` records ``None``).

    Example:
        >>> vis = PartVisibility()
        >>> vis.add(np.array([[120, 0], [80, 40]]))  # 2 images, 2 parts: part 1 hidden in the first
        >>> s = vis.summary()
        >>> s["hidden_fraction"], s["image_size"]
        ([0.0, 0.5], None)
    """

    renderer: Renderer | None = None
    num_parts: int | None = None
    image_size: tuple[int, int] | None = None
    counts: list[np.ndarray] = field(default_factory=list)

    @classmethod
    def for_evaluation(cls, context: Any) -> PartVisibility:
        """From an :class:`~cerberus_core.eval.accumulators.EvalContext`: its renderer."""
        return cls(context.renderer)

    def update(self, batch: Any) -> None:
        """Count each part's front-surface pixels in the batch's input views and record them per image."""
        shown = part_pixel_counts(batch.part_id(self.renderer), batch.recon.num_parts)
        if self.image_size is None:
            self.image_size = (batch.camera.height, batch.camera.width)
        self.add(shown)
        for b, rec in enumerate(batch.records):
            rec["visible_pixels"] = shown[b].tolist()

    def add(self, counts: Tensor | np.ndarray) -> None:
        """Record a batch's ``(B, P)`` visible-pixel counts (:func:`visible_pixels`)."""
        c = np.asarray(counts.cpu() if isinstance(counts, Tensor) else counts, dtype=np.int64)
        check_shapes("PartVisibility.add", counts=(c, "B P" if self.num_parts is None else f"B {self.num_parts}"))
        self.num_parts = c.shape[1]
        self.counts.extend(c)

    def summary(self) -> dict[str, Any] | None:
        """Per-part visibility over every image added (see the module docstring); ``None`` when none was.
        ``image_size`` is ``[H, W]``, or ``None`` when it was neither given nor seen (counts given to :meth:`add`
        alone)."""
        if not self.counts:
            return None
        stack = np.stack(self.counts).astype(np.float64)  # (N, P)
        hidden = (stack == 0).mean(0)
        silhouette = stack.sum(1)
        drawn = silhouette > 0
        share = (stack[drawn] / silhouette[drawn, None]).mean(0) if drawn.any() else np.full(self.num_parts, np.nan)
        most = [p for p in range(self.num_parts) if hidden[p] > 0.5]
        return {
            "images": len(self.counts),
            "image_size": None if self.image_size is None else list(self.image_size),
            "hidden_fraction": hidden.tolist(),
            "mean_visible_pixels": stack.mean(0).tolist(),
            "mean_silhouette_share": share.tolist(),
            "parts_hidden_in_most_images": len(most),
            "hidden_in_most_images": most,
        }


def visibility_line(summary: dict[str, Any]) -> str:
    """One line for a console or report, e.g. ``parts hidden in most images: 2 of 9 (part 0: 61%,
    part 2: 58%)`` (with none, the most often hidden part is named, if any is ever hidden); works on
    :meth:`PartVisibility.summary` or its JSON form."""
    hidden = summary["hidden_fraction"]
    most = summary["hidden_in_most_images"]
    line = f"parts hidden in most images: {len(most)} of {len(hidden)}"
    if most:
        line += " (" + ", ".join(f"part {p}: {100 * hidden[p]:.0f}%" for p in most) + ")"
    elif hidden and max(hidden) > 0:
        worst = int(np.argmax(hidden))
        line += f" (most often hidden: part {worst}, in {100 * hidden[worst]:.0f}% of images)"
    return line


def visibility_sentence(vis: Mapping[str, Any]) -> str:
    """The report's sentence on part visibility (its JSON form; the render size left out where it is ``None``)."""
    size = "" if vis.get("image_size") is None else "{}x{} ".format(*vis["image_size"])
    return (f"Part visibility in the input view ({size}renders of the reconstruction, {vis['images']} images): "
            f"{visibility_line(vis)}. *Hidden*: the fraction of images where no pixel shows the part (it gets no "
            "gradient from the paper's renderer there); *silhouette share*: its mean share of the rendered "
            "silhouette.")


def visibility_header(vis: Mapping[str, Any] | None) -> list[str]:
    """The report's visibility columns (none when visibility did not run)."""
    return ["Hidden in input view", "Silhouette share"] if vis else []


def visibility_cells(vis: Mapping[str, Any] | None, part: int) -> list[Any]:
    """A learned part's cells under :func:`visibility_header`."""
    return [vis["hidden_fraction"][part], vis["mean_silhouette_share"][part]] if vis else []


def visibility_section(result: Mapping[str, Any]) -> list[str]:
    """The report's part-visibility section from a result's JSON form; empty when part quality was scored
    (its table has the visibility columns)."""
    vis = result["part_visibility"]
    if scored_part_quality(result):
        return []
    vrow = [[p, *visibility_cells(vis, p), px] for p, px in enumerate(vis["mean_visible_pixels"])]
    return ["## Part visibility", "", visibility_sentence(vis), "",
            markdown_table(["Learned part", *visibility_header(vis), "Visible pixels"], vrow, 3), ""]
