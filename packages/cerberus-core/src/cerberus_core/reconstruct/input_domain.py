"""Input the model was not trained for: named, not silently reconstructed.

A model learns from renders of one whole body on a plain background (the dataset's
``SceneSetup.background``), framed by the scene's fixed camera. A photo (a cluttered background, a
half-body portrait) is not such an image, and the model answers it with a full body regardless.
``cerberus reconstruct`` therefore prepares each input in one of two ways:

* **with a silhouette** (an RGBA cut-out's alpha channel, or a ``--mask`` image: white on the body):
  the body is composited onto the training background (:func:`composite`) and, unless it already sits
  in the frame as the training bodies do, cropped or padded around the silhouette so that it fills
  the frame as they do (:func:`frame_to_training`). A silhouette that runs along an image edge means a
  body cut off by the frame (a portrait): out of the training domain (:func:`cut_off_sides`).
* **without one**: the image is used as before (centre-cropped and resized), and
  :func:`background_check` says whether its border looks like the training background. The body is
  then estimated from the image alone (:func:`estimated_foreground`: what differs from the training
  background, or from a photo's own plain background), so that a half-body or a face close-up running
  along the image's edge is named cut off as with a silhouette.

Either way, :func:`appearance_check` then looks inside the body: the training bodies are untextured grey
renders (no colour, smooth shading), so a coloured or textured body (a clothed person in a photo) is out
of the training domain however well it is masked. A model trained in another input look
(``data.input_look``, :mod:`cerberus_core.datasets.looks`) gets its input in that look: for ``flat`` the body
is filled with a training body's mean grey (:func:`~cerberus_core.datasets.looks.flat_grey`), as in its training, so
its appearance is not checked (nor for ``random``,
which learned coloured and textured bodies).

The thresholds below were measured on generated images (``docs/evaluation.md``, "Input outside the
training domain"): every test and training image of the human ``small`` set passes, as do the same
images saved as JPEG (quality 75) or at 4x the size; noise, gradient and photo-like textured
backgrounds, a white background for a black-background model, and a body cut off at the bottom fail.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from PIL import Image

from cerberus_core.bodies.body import FILL, BodySource, source_class
from cerberus_core.datasets.looks import check_look, flat_grey, flat_look
from cerberus_core.errors import CerberusError, ImageInputError
from cerberus_core.photo_mask import AUTO, person_mask
from cerberus_core.plumbing.names import printable
from cerberus_core.reconstruct.images import (
    LoadedImage,
    RawImage,
    composite,
    finish,
    open_oriented,
    read_image,
    square_resize,
)

#: Width in pixels of the model-size image's outer ring that :func:`background_check` looks at.
BORDER_WIDTH = 2
#: A ring pixel is background when each of its channels is within this of the training background.
BACKGROUND_TOLERANCE = 0.1
#: Least fraction of the ring that must be background (generated images: 0.986 and above).
MIN_BACKGROUND_FRACTION = 0.9
#: Largest colour spread (standard deviation of the ring, largest over channels; generated: 0.063 at most).
MAX_BORDER_SPREAD = 0.15
#: Largest fraction of one side of the image that may be body (a silhouette's, or the foreground estimated without
#: one): more is a body cut off by the frame's edge (generated: 0.055 at most).
MAX_SIDE_FOREGROUND = 0.1
#: Least share of the ring that must be one plain colour (the training background, or the ring's median colour:
#: a photo's plain wall) for :func:`estimated_foreground` to tell body from background without a silhouette.
MIN_PLAIN_BORDER = 0.5
#: Where a training body's silhouette sits: its longest bounding-box side over the projected size of the
#: normalised body size (:func:`projected_extent`), median (human ``small``) and range (human ``small``,
#: the paper's look, animal ``tiny``), and how far (fraction of the frame) its bounding-box centre may
#: stray from the frame's centre.
FRAMING_MEDIAN = 0.89
FRAMING_RANGE = (0.55, 1.1)
CENTRE_TOLERANCE = 0.1
#: Largest fraction of a mask's non-black pixels (above 0.1) that may be grey (below 0.9): a mask is
#: black and white, its grey pixels the anti-aliased edge (a box-filtered 32 px mask of a thin body: 0.46;
#: a rendered picture given as a mask: 1.0).
MAX_MASK_GREY = 0.75
#: Largest mean colourfulness (max - min over RGB) of the body's pixels: training bodies are grey under
#: white light (0.000 in all 208 human test images and the animal tiny set; a body tinted (1, 0.7, 0.5): 0.28).
MAX_BODY_COLOUR = 0.08
#: Largest mean absolute luminance step between neighbouring pixels inside the body (its texture;
#: human test images: median 0.044, largest 0.071; the same body with 30 % multiplicative noise: 0.15).
MAX_BODY_TEXTURE = 0.11
#: An alpha or mask value at or above this is the body.
SILHOUETTE_THRESHOLD = 0.5

SIDES = ("top", "bottom", "left", "right")
OUT_OF_DOMAIN = "out of the training domain"


def projected_extent(scene) -> float:
    """Fraction of the frame that a body of the normalised size ``FILL`` at the origin spans (whatever
    volume the scene's camera distance was fitted to)."""
    return float(FILL / (2 * scene.distance * math.tan(math.radians(scene.fov_y) / 2)))


def _colour(rgb: Sequence[float]) -> str:
    return "(" + ", ".join(f"{float(c):.2g}" for c in rgb) + ")"


# ------------------------------------------------------------------ silhouettes
def silhouette_from(image_rgba: np.ndarray | None = None, mask: np.ndarray | None = None, *,
                    name: str = "mask") -> np.ndarray | None:
    """The ``(H, W)`` silhouette in [0, 1] (1: body) of an RGBA image's alpha or of a mask.

    Args:
        image_rgba: ``(H, W, 4)`` in [0, 1]: its alpha; ``None`` (no silhouette) when the alpha is opaque
            everywhere or marks nothing out (every value at least :data:`SILHOUETTE_THRESHOLD`).
        mask: ``(H, W)``, ``(H, W, 1)`` or grey ``(H, W, 3)`` in [0, 1]; used when given.
        name: what the messages call it.
    Raises:
        ImageInputError: a mask in colour, mostly grey, or one that marks no pixel or every pixel as the body;
            an alpha channel transparent everywhere.
    """
    if mask is not None:
        m = np.asarray(mask, dtype=np.float64)
        if m.ndim == 3 and m.shape[-1] == 3:
            spread = m.max(-1) - m.min(-1)
            if (spread > 0.1).mean() > 0.01:
                raise ImageInputError(f"{name}: is a colour image, not a mask; give a black-and-white image, "
                                      "white on the body and black elsewhere")
            m = m.mean(-1)
        m = m.reshape(m.shape[:2])
        lit = m > 0.1
        if lit.any() and (m[lit] < 0.9).mean() > MAX_MASK_GREY:
            raise ImageInputError(f"{name}: is not a mask (most of its non-black pixels are grey: a picture?); give a "
                                  "black-and-white image, white on the body and black elsewhere")
        body = m >= SILHOUETTE_THRESHOLD
        if not body.any():
            raise ImageInputError(f"{name}: marks no pixel as the body (no value is 50% white or more); the mask "
                                  "must be white on the body and black elsewhere")
        if body.all():
            raise ImageInputError(f"{name}: marks every pixel as the body; the mask must be white on the body and "
                                  "black elsewhere")
        return m
    if image_rgba is None or np.asarray(image_rgba).shape[-1] != 4:
        return None
    alpha = np.asarray(image_rgba, dtype=np.float64)[..., 3]
    if (alpha >= SILHOUETTE_THRESHOLD).all():
        return None
    if not (alpha >= SILHOUETTE_THRESHOLD).any():
        raise ImageInputError(f"{name}: the alpha channel is transparent everywhere: there is no body to "
                              "reconstruct; give the cut-out with the body opaque")
    return alpha


def _bbox(silhouette: np.ndarray) -> tuple[int, int, int, int]:
    """``(top, left, bottom, right)`` of the body pixels, bottom and right exclusive."""
    body = silhouette >= SILHOUETTE_THRESHOLD
    rows, cols = np.nonzero(body.any(1))[0], np.nonzero(body.any(0))[0]
    return int(rows[0]), int(cols[0]), int(rows[-1]) + 1, int(cols[-1]) + 1


def cut_off_sides(silhouette: np.ndarray) -> list[str]:
    """The image sides along which the body runs (more than :data:`MAX_SIDE_FOREGROUND` of the side):
    a body cut off by the frame, which the model never saw.

    Args:
        silhouette: ``(H, W)`` in [0, 1] or bool: a silhouette, or :func:`estimated_foreground`.
    """
    body = silhouette >= SILHOUETTE_THRESHOLD
    edges = (body[0], body[-1], body[:, 0], body[:, -1])
    return [side for side, edge in zip(SIDES, edges, strict=True) if edge.mean() > MAX_SIDE_FOREGROUND]


def cut_off_reason(sides: Sequence[str], estimated: bool = False) -> str:
    """The out-of-domain reason of a body running along ``sides`` (:func:`cut_off_sides`) of a silhouette, or of
    the foreground ``estimated`` without one (:func:`estimated_foreground`: said less surely, since an object
    touching the body can cross the edge too)."""
    edges = (f"{', '.join(sides[:-1])} and {sides[-1]} edges" if len(sides) > 1 else f"{sides[0]} edge")
    said = (f"the body seems to run along the image's {edges}: it may be cut off" if estimated else
            f"the body runs along the image's {edges}: it looks cut off")
    return f"{said} (a half-body or a close-up?), and the model was trained on whole bodies"


# ------------------------------------------------------------------ framing
def training_window(silhouette: np.ndarray, scene) -> tuple[int, int, int] | None:
    """The square ``(top, left, side)`` (pixels, may reach outside the image) that frames the silhouette as
    the training images frame their bodies: its bounding box centred, its longest side
    :data:`FRAMING_MEDIAN` of the scene's :func:`projected_extent`. ``None`` when the image's own
    centre square already does (the body's size within :data:`FRAMING_RANGE`, its centre within
    :data:`CENTRE_TOLERANCE`): the image is then used exactly as without a silhouette."""
    h, w = silhouette.shape
    top, left, bottom, right = _bbox(silhouette)
    longest = max(bottom - top, right - left)
    proj = projected_extent(scene)
    s = min(h, w)
    t0, l0 = (h - s) // 2, (w - s) // 2
    inside = top >= t0 and left >= l0 and bottom <= t0 + s and right <= l0 + s
    off = max(abs((top + bottom) / 2 - t0 - s / 2), abs((left + right) / 2 - l0 - s / 2)) / s
    if inside and FRAMING_RANGE[0] <= longest / s / proj <= FRAMING_RANGE[1] and off <= CENTRE_TOLERANCE:
        return None
    side = max(1, round(longest / (FRAMING_MEDIAN * proj)))
    return round((top + bottom - side) / 2), round((left + right - side) / 2), side


def _crop_padded(arr: np.ndarray, top: int, left: int, side: int, fill: Sequence[float]) -> np.ndarray:
    """The ``side`` square of ``(H, W, C)`` at ``(top, left)``, ``fill`` where it reaches outside."""
    h, w, c = arr.shape
    out = np.empty((side, side, c), dtype=np.float64)
    out[:] = np.asarray(fill, dtype=np.float64).reshape(1, 1, c)
    t, lf = max(top, 0), max(left, 0)
    b, r = min(top + side, h), min(left + side, w)
    if b > t and r > lf:
        out[t - top:b - top, lf - left:r - left] = arr[t:b, lf:r]
    return out


def frame_to_training(image: np.ndarray, silhouette: np.ndarray, scene, size: int,
                      notes: list[str] | None = None, *, raw: RawImage | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Crop or pad ``(H, W, 3)`` ``image`` (already over the training background) and its silhouette to the
    :func:`training_window`, then resize both to ``size``.

    Args:
        raw: the file ``image`` was read from, if it may have been reduced on reading: the notes then give
            the file's pixels (:attr:`RawImage.shown_size`).
    Returns:
        ``(size, size, 3)`` image and ``(size, size)`` silhouette; each change is appended to ``notes``.
    """
    notes = [] if notes is None else notes
    scale = 1.0 if raw is None else raw.scale
    shown = None if raw is None else raw.shown_size
    window = training_window(silhouette, scene)
    if window is not None:
        top, left, side = window
        image = _crop_padded(image, top, left, side, scene.background)
        silhouette = _crop_padded(silhouette[..., None], top, left, side, (0.0,))[..., 0]
        seen = round(side * scale)
        shown = None if shown is None else (seen, seen)
        notes.append(f"framed to its silhouette like the training images (a {seen}x{seen} square around the body, "
                     "padded with the training background where it leaves the image)")
    return (square_resize(image, size, notes, shown_size=shown),
            square_resize(silhouette[..., None], size, [])[..., 0])


# ------------------------------------------------------------------ no silhouette
def _ring(image: np.ndarray, width: int) -> dict[str, np.ndarray]:
    return {"top": image[:width].reshape(-1, 3), "bottom": image[-width:].reshape(-1, 3),
            "left": image[:, :width].reshape(-1, 3), "right": image[:, -width:].reshape(-1, 3)}


def _array(image: np.ndarray | torch.Tensor) -> np.ndarray:
    """``(S, S, 3)`` float64 of a ``(3, S, S)`` tensor or an ``(S, S, 3)`` array."""
    arr = image.detach().cpu().numpy().transpose(1, 2, 0) if isinstance(image, torch.Tensor) else np.asarray(image)
    return arr.astype(np.float64)


def estimated_foreground(image: np.ndarray | torch.Tensor, scene) -> np.ndarray | None:
    """The body as far as the image alone tells, for an image without a silhouette: the pixels farther than
    :data:`BACKGROUND_TOLERANCE` (any channel) from its background, which is the training background or,
    where more of the border is one other colour, that colour (the ring's median: a plain wall behind a
    person in a photo).

    Args:
        image: ``(3, S, S)`` tensor or ``(S, S, 3)`` array in [0, 1], as the model sees it.
        scene: the training :class:`~cerberus_core.datasets.scene.SceneSetup` (its ``background``).
    Returns:
        ``(S, S)`` bool, or ``None`` when less than :data:`MIN_PLAIN_BORDER` of the ring is either colour (a
        cluttered border: nothing tells the body from the background).
    """
    arr = _array(image)
    ring = np.concatenate(list(_ring(arr, BORDER_WIDTH).values()))
    colours = [np.asarray(scene.background, dtype=np.float64), np.median(ring, axis=0)]
    shares = [float((np.abs(ring - c).max(-1) <= BACKGROUND_TOLERANCE).mean()) for c in colours]
    best = int(np.argmax(shares))
    if shares[best] < MIN_PLAIN_BORDER:
        return None
    return _centre_connected(np.abs(arr - colours[best]).max(-1) > BACKGROUND_TOLERANCE)


def _centre_connected(mask: np.ndarray) -> np.ndarray:
    """The pixels of ``(H, W)`` bool ``mask`` connected (4-neighbourhood) to its pixels in the central third of the
    image, where the training bodies are: a body crossing an edge, not clutter along it."""
    h, w = mask.shape
    grown = np.zeros_like(mask)
    grown[h // 3:h - h // 3, w // 3:w - w // 3] = mask[h // 3:h - h // 3, w // 3:w - w // 3]
    while True:
        pad = np.pad(grown, 1)
        more = mask & (grown | pad[:-2, 1:-1] | pad[2:, 1:-1] | pad[1:-1, :-2] | pad[1:-1, 2:])
        if np.array_equal(more, grown):
            return grown
        grown = more


def background_check(image: np.ndarray | torch.Tensor, scene, cut_off: Sequence[str] = ()) -> tuple[bool, str]:
    """Whether an image's border looks like the training background, and if not, why.

    Args:
        image: ``(3, S, S)`` tensor or ``(S, S, 3)`` array in [0, 1], as the model sees it.
        scene: the training :class:`~cerberus_core.datasets.scene.SceneSetup` (its ``background``).
        cut_off: the sides along which the body runs (:func:`cut_off_sides`), left out of the border's
            measures (a half-body crossing the bottom edge of a training-background image is cut off, not on
            another background); all four: the whole ring is measured.
    Returns:
        ``(in_domain, reason)``; the reason is empty when in domain.
    """
    arr = _array(image)
    bg = np.asarray(scene.background, dtype=np.float64)
    sides = _ring(arr, BORDER_WIDTH)
    kept = [px for side, px in sides.items() if side not in cut_off] or list(sides.values())
    ring = np.concatenate(kept)
    fraction = float((np.abs(ring - bg).max(-1) <= BACKGROUND_TOLERANCE).mean())
    spread = float(ring.std(0).max())
    reasons = []
    if fraction < MIN_BACKGROUND_FRACTION:
        reasons.append(f"its border is not the training background {_colour(bg)} (only {fraction:.0%} of it is, "
                       f"training images {MIN_BACKGROUND_FRACTION:.0%} or more)")
    if spread > MAX_BORDER_SPREAD:
        reasons.append(f"its border varies in colour (spread {spread:.2f}, training images at most "
                       f"{MAX_BORDER_SPREAD:.2f})")
    return not reasons, "; ".join(reasons)


# ------------------------------------------------------------------ one input
def photo_subject(kind: str | None) -> str:
    """What a photograph of a body of ``kind`` (a body source's name, e.g. ``"animal"``) shows that the training
    renders do not: the source's :attr:`~cerberus_core.bodies.body.BodySource.photo_subject`; for an unknown
    kind (``None``: a folder of meshes, or a source not installed here) the generic one."""
    if kind:
        try:
            return source_class(kind).photo_subject
        except CerberusError:  # not installed here: the generic phrase still says what is wrong
            pass
    return BodySource.photo_subject


def appearance_check(image: np.ndarray, scene, kind: str | None = None) -> tuple[bool, str]:
    """Whether the body in ``image`` (``(S, S, 3)`` in [0, 1], over the training background) looks like the
    training bodies: grey and smoothly shaded. ``kind``: the kind of bodies the model learned (a body
    source's name; :func:`photo_subject` says what a photo of one looks like). Returns ``(ok, reason)``."""
    arr = np.asarray(image, dtype=np.float64)
    body = np.abs(arr - np.asarray(scene.background, dtype=np.float64)).max(-1) > BACKGROUND_TOLERANCE
    if body.sum() < 16:
        return True, ""
    colour = float((arr.max(-1) - arr.min(-1))[body].mean())
    pad = np.pad(body, 1, constant_values=False)  # one-pixel erosion (4-neighbourhood): the body without its edge
    inner = body & pad[:-2, 1:-1] & pad[2:, 1:-1] & pad[1:-1, :-2] & pad[1:-1, 2:]
    lum = arr.mean(-1)
    steps = np.concatenate([np.abs(np.diff(lum, axis=1))[inner[:, :-1] & inner[:, 1:]],
                            np.abs(np.diff(lum, axis=0))[inner[:-1] & inner[1:]]])
    texture = float(steps.mean()) if steps.size else 0.0
    found = [f"coloured (colour {colour:.2f}, training bodies 0.00)" if colour > MAX_BODY_COLOUR else "",
             f"textured (texture {texture:.2f}, training bodies {MAX_BODY_TEXTURE - 0.04:.2f} at most)"
             if texture > MAX_BODY_TEXTURE else ""]
    found = [f for f in found if f]
    if not found:
        return True, ""
    return False, (f"the body is {' and '.join(found)}: the model learned untextured grey renders only, so "
                   f"{photo_subject(kind)} is outside what it learned however well it is masked")


def read_mask(path: str | Path, raw: RawImage, image_path: str | Path) -> np.ndarray:
    """The mask image ``path`` for the image ``image_path`` (read as ``raw``), as an array the size of
    ``raw.rgb``: an alpha channel that varies, else its grey level.

    Raises:
        ImageInputError: not a readable image, not the image's size.
    """
    shown = printable(path)
    try:
        img = open_oriented(path, [])
    except ImageInputError as exc:
        raise ImageInputError(f"mask {exc}") from None
    if img.size != raw.original_size:
        raise ImageInputError(f"mask {shown}: is {img.size[0]}x{img.size[1]} but its image {printable(image_path)} is "
                              f"{raw.original_size[0]}x{raw.original_size[1]}; give a mask of the image's size")
    if img.mode in ("P", "PA", "LA", "RGBa"):
        img = img.convert("RGBA")
    if img.mode not in ("1", "L", "RGB", "RGBA"):
        img = img.convert("RGB")
    arr = np.asarray(img, dtype=np.float64) / (1.0 if img.mode == "1" else 255.0)
    if arr.ndim == 3 and arr.shape[-1] == 4:
        alpha = arr[..., 3]
        arr = alpha if alpha.min() < alpha.max() else arr[..., :3]
    h, w = raw.rgb.shape[:2]
    if arr.shape[:2] != (h, w):  # the image was reduced on reading: the mask follows
        chans = arr if arr.ndim == 3 else arr[..., None]
        arr = np.stack([np.asarray(Image.fromarray(chans[..., c].astype(np.float32), mode="F").resize((w, h), Image.BOX))
                        for c in range(chans.shape[-1])], -1).astype(np.float64)
    return silhouette_from(mask=arr, name=f"mask {shown}")


def prepare_input(path: str | Path, size: int, scene, mask: str | Path | None = None, *,
                  kind: str | None = None, look: str = "shaded", warn: bool = True) -> LoadedImage:
    """Read one image for a model of ``size`` pixels trained on ``scene``, on bodies of ``kind`` (a body
    source's name; ``None``: unknown) shown in the input ``look`` (``data.input_look``) (see the module
    docstring). ``mask``: a mask file, or ``"auto"`` (:data:`cerberus_core.photo_mask.AUTO`): the person found
    by the photo extra's segmenter.

    Returns:
        The :class:`LoadedImage`; its ``out_of_domain`` holds the reason when the image does not look like
        the training images (empty otherwise).
    Raises:
        ImageInputError: an unreadable image or a bad mask (one line naming the file and the fix).
    """
    path = Path(path)
    raw = read_image(path, size)
    notes = raw.notes
    auto = isinstance(mask, str) and mask == AUTO
    if auto:  # the person segmenter of the photo extra
        silhouette = auto_silhouette(raw, path)
        notes.append("the person cut out by the automatic person mask")
    elif mask is not None:
        silhouette = read_mask(mask, raw, path)
        if raw.alpha is not None:
            notes.append("the mask is used instead of the image's alpha channel")
    else:
        silhouette = silhouette_from(np.concatenate([raw.rgb, raw.alpha[..., None]], -1)
                                     if raw.alpha is not None else None, name=printable(path))
    reasons, advice = [], []
    if silhouette is None:
        arr = raw.rgb if raw.alpha is None else composite(raw.rgb, raw.alpha, scene.background)
        arr = square_resize(arr, size, notes, shown_size=raw.shown_size)
        foreground = estimated_foreground(arr, scene)
        cut = [] if foreground is None else cut_off_sides(foreground)
        ok, reason = background_check(arr, scene, cut)
        if not ok:
            reasons.append(reason)
            advice.append("give an RGBA cut-out (transparent background) or `mask=MASK.png` (white on the body)")
    else:
        notes.append(f"{'mask' if mask is not None else 'alpha'} composited over the training background "
                     f"{_colour(scene.background)}")
        cut = cut_off_sides(silhouette)
        arr, framed = frame_to_training(composite(raw.rgb, silhouette, scene.background), silhouette, scene, size,
                                        notes, raw=raw)
    if cut:
        reasons.append(cut_off_reason(cut, estimated=silhouette is None))
        advice.append("give images of the whole body")
    check_look(look)
    if look == "flat":
        notes.append("shown as a flat silhouette, the model's input look")
    looks, reason = appearance_check(arr, scene, kind) if look == "shaded" else (True, "")
    if not looks:
        reasons.append(reason)
        advice.append("expect a coarse grey body: no mask or framing brings a photo's appearance into the "
                      "training domain")
    loaded = finish(path, arr, raw.original_size, notes, warn=warn)
    if look == "flat":  # the body one grey level, a training body's (not the photo's colours)
        loaded.image = flat_input(loaded.image, None if silhouette is None else framed, scene)
    loaded.out_of_domain = "; ".join(reasons)
    loaded.advice = "; ".join(advice)
    if silhouette is not None:
        loaded.silhouette, loaded.photo, loaded.mask, loaded.auto_mask = framed, raw.rgb, silhouette, auto
    return loaded


FLAT_MIN_COVERAGE = 1 / 32
"""With a silhouette, a pixel of a flat input is body when the silhouette covers at least this much of it: the
training renders are 4x4-supersampled, so their flat look fills every pixel one of its 16 samples hits (coverage
1/16 and up); half that step rounds a continuous coverage to it. A lower bound takes in the faint ring the resize
(Lanczos) leaves around the silhouette: at any coverage above 0 a photo's flat body came out a pixel wider all
round than a render's (570 pixels against 420 for the same body, test image 0 of the human set)."""


def flat_input(image: torch.Tensor, silhouette: np.ndarray | None, scene) -> torch.Tensor:
    """``(3, S, S)`` ``image`` as a model trained in the flat look sees a body: :func:`~cerberus_core.datasets.looks.flat_grey`
    where the framed ``(S, S)`` ``silhouette`` covers at least :data:`FLAT_MIN_COVERAGE` of a pixel, the training
    background elsewhere; without a silhouette, every pixel off the background colour
    (:func:`~cerberus_core.datasets.looks.flat_look`)."""
    if silhouette is None:
        return flat_look(image[None], scene.background, grey=flat_grey(scene))[0]
    body = torch.from_numpy(np.asarray(silhouette) >= FLAT_MIN_COVERAGE)
    background = torch.as_tensor(scene.background, dtype=image.dtype).view(3, 1, 1).expand_as(image)
    return torch.where(body, image.new_tensor(flat_grey(scene)), background)


def auto_silhouette(raw: RawImage, path: str | Path) -> np.ndarray:
    """The person in ``raw`` found by the photo extra's segmenter (:func:`cerberus_core.photo_mask.person_mask`),
    checked like a mask file (:func:`silhouette_from`).

    Raises:
        MissingPackageError: the extra is not installed. ImageInputError: no person found.
    """
    found = person_mask(raw.rgb)
    if not (found >= SILHOUETTE_THRESHOLD).any():
        raise ImageInputError(f"{printable(path)}: the automatic person mask found no person; give a mask file "
                              "(white on the body, black elsewhere) or an RGBA cut-out")
    return silhouette_from(mask=found, name=f"the automatic person mask of {printable(path)}")


def domain_note(loaded: LoadedImage) -> str:
    """``"out of the training domain: <reason>"`` for an image that is, else ``""``."""
    return f"{OUT_OF_DOMAIN}: {loaded.out_of_domain}" if loaded.out_of_domain else ""
