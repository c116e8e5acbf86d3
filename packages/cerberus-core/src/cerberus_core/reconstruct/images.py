"""Reading user images for ``cerberus reconstruct``.

A model is trained on square RGB renders of one size over a uniform background. Images from
elsewhere are brought into that form, each change reported (as an :class:`ImageInputWarning` and
in :attr:`LoadedImage.notes`), or refused with an :class:`ImageInputError` that names the file:

=================================  ==================================================================
input                              handling
=================================  ==================================================================
unreadable / not an image / empty  refused
RGBA, LA, palette with alpha       composited over the dataset's background colour
grayscale (L, 1-bit)               repeated into RGB
16-bit grayscale (I;16, I)         scaled by 1/65535 (values beyond 16 bits are refused)
32-bit float (F)                   refused: no defined range (save it as 8-bit PNG)
CMYK, YCbCr, LAB, HSV              converted to RGB
EXIF orientation                   applied
more than MAX_INPUT_PIXELS pixels  refused before decoding (downscale it first)
much larger than the model's size  reduced (box filter) while still 8-bit, before the float conversion
animated / multi-frame             first frame used
not square                         centre-cropped to a square
other size                         resized (Lanczos) to the model's image size
=================================  ==================================================================
"""
from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageOps, UnidentifiedImageError

from cerberus_core.errors import ConfigError, ImageInputError
from cerberus_core.plumbing.names import printable

Tensor = torch.Tensor


#: Largest input accepted, in pixels (8000 x 5000): the header is checked before anything is decoded.
MAX_INPUT_PIXELS = 40_000_000


class ImageInputWarning(UserWarning):
    """An input image was changed to fit the model (alpha composited, resized, ...)."""


@dataclass
class LoadedImage:
    """One prepared image.

    Attributes:
        path: where it came from.
        image: ``(3, S, S)`` float32 RGB in [0, 1].
        original_size: ``(width, height)`` in the file.
        notes: what was done to it (empty when it already matched).
        out_of_domain: why it does not look like the training images (empty: it does, or it was not
            checked); see :mod:`cerberus_core.reconstruct.input_domain`.
        advice: what would bring it closer to them, for that reason (empty with it).
        silhouette: ``(S, S)`` in [0, 1]: the body's silhouette (a mask, an alpha channel or the automatic
            person mask) framed as :attr:`image` is; ``None`` without one.
        photo, mask: ``(H, W, 3)`` and ``(H, W)`` in [0, 1]: the image as read and its silhouette before the
            framing; ``None`` without a silhouette.
        auto_mask: the silhouette is the automatic person mask (:func:`cerberus_core.photo_mask.person_mask`).
    """

    path: Path
    image: Tensor
    original_size: tuple[int, int]
    notes: list[str] = field(default_factory=list)
    out_of_domain: str = ""
    advice: str = ""
    silhouette: np.ndarray | None = None
    photo: np.ndarray | None = None
    mask: np.ndarray | None = None
    auto_mask: bool = False


def _open(path: Path) -> Image.Image:
    """Open ``path`` as an image; its type is checked first, so a FIFO or a device never blocks the read."""
    import stat

    shown = printable(path)
    if len(shown) > 160:  # a path of thousands of characters: its start and its file name say enough
        shown = f"{shown[:80]}...{shown[-60:]}"
    try:
        mode = path.stat().st_mode  # follows a symlink to what it names
    except FileNotFoundError:
        raise ImageInputError(f"{shown}: no such file; check the path") from None
    except OSError as exc:
        raise ImageInputError(f"{shown}: cannot be read ({exc.strerror or exc}); check the path and its "
                              "permissions") from None
    if stat.S_ISDIR(mode):
        raise ImageInputError(f"{shown}: is a folder, not an image file")
    if not stat.S_ISREG(mode):
        kind = ("a FIFO (named pipe)" if stat.S_ISFIFO(mode) else "a device" if stat.S_ISCHR(mode) or stat.S_ISBLK(mode)
                else "a socket" if stat.S_ISSOCK(mode) else "not a regular file")
        raise ImageInputError(f"{shown}: is {kind}, not an image file; pass a PNG or JPEG file")
    path = Path(path)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", Image.DecompressionBombWarning)  # our own bound applies below
            img = Image.open(path)
        if img.width * img.height > MAX_INPUT_PIXELS:
            raise ImageInputError(f"{shown}: {img.width}x{img.height} pixels is too large (the limit is "
                                  f"{MAX_INPUT_PIXELS:,} pixels); downscale it first, e.g. to 1024x1024")
        img.load()
    except ImageInputError:  # our own bound: said once, not wrapped in "cannot be read" (a ValueError too)
        raise
    except Image.DecompressionBombError as exc:
        raise ImageInputError(f"{shown}: too large to decode safely ({exc}); downscale it first, e.g. to "
                              "1024x1024") from None
    except (UnidentifiedImageError, OSError, SyntaxError, ValueError) as exc:
        raise ImageInputError(f"{shown}: cannot be read as an image ({type(exc).__name__}: {printable(exc)}); "
                              "pass a PNG or JPEG file") from exc
    if img.width == 0 or img.height == 0:
        raise ImageInputError(f"{shown}: the image is empty ({img.width}x{img.height})")
    return img


def _to_rgba_float(img: Image.Image, path: Path, notes: list[str]) -> tuple[np.ndarray, np.ndarray | None]:
    """``(H, W, 3)`` float64 RGB in [0, 1] and the ``(H, W)`` alpha in [0, 1] (``None`` without one)."""
    mode = img.mode
    if mode == "P":
        img = img.convert("RGBA" if "transparency" in img.info else "RGB")
        notes.append("palette image converted to RGB")
        mode = img.mode
    if mode in ("I;16", "I;16B", "I;16L", "I;16N", "I"):
        arr = np.asarray(img, dtype=np.float64)
        if arr.min() < 0 or arr.max() > 65535:
            raise ImageInputError(f"{printable(path)}: {mode} image with values outside 0..65535 is not supported; "
                                  "save it as an 8-bit PNG")
        notes.append(f"16-bit grayscale ({mode}) scaled to [0, 1] and repeated into RGB")
        return np.repeat((arr / 65535.0)[..., None], 3, axis=2), None
    if mode == "F":
        raise ImageInputError(f"{printable(path)}: 32-bit float image (mode F) has no defined value range; "
                              "save it as an 8-bit RGB PNG")
    if mode in ("1", "L"):
        notes.append("grayscale image repeated into RGB")
        img = img.convert("RGB")
    elif mode == "LA" or mode == "PA":
        img = img.convert("RGBA")
    elif mode not in ("RGB", "RGBA", "RGBa"):
        notes.append(f"{mode} image converted to RGB")
        img = img.convert("RGB")
    if img.mode == "RGBa":
        img = img.convert("RGBA")
    arr = np.asarray(img, dtype=np.float64) / 255.0
    return arr[..., :3], (arr[..., 3] if img.mode == "RGBA" else None)


def composite(image: np.ndarray, alpha: np.ndarray, background: Sequence[float]) -> np.ndarray:
    """``image * alpha + background * (1 - alpha)``: ``(H, W, 3)`` RGB over one colour, ``alpha`` ``(H, W)``."""
    a = np.asarray(alpha, dtype=np.float64)[..., None]
    return image * a + np.asarray(background, dtype=np.float64).reshape(1, 1, 3) * (1 - a)


def square_resize(arr: np.ndarray, size: int, notes: list[str], *,
                  shown_size: tuple[int, int] | None = None) -> np.ndarray:
    """Centre-crop ``(H, W, C)`` to a square and resize it (Lanczos) to ``size``; each change in ``notes``.

    Args:
        shown_size: the ``(width, height)`` the notes give ``arr`` (default its own): the file's size for an
            image reduced on reading (:attr:`RawImage.shown_size`), so that the file's one resize is one note
            in the file's pixels, not a reduction and a resize.
    """
    h, w = arr.shape[:2]
    sw, sh = (w, h) if shown_size is None else shown_size
    if h != w:
        s = min(h, w)
        top, left = (h - s) // 2, (w - s) // 2
        arr = arr[top:top + s, left:left + s]
        notes.append(f"centre-cropped from {sw}x{sh} to {min(sw, sh)}x{min(sw, sh)}")
    if arr.shape[0] != size:
        chans = [Image.fromarray(arr[..., c].astype(np.float32), mode="F").resize((size, size), Image.LANCZOS)
                 for c in range(arr.shape[-1])]
        arr = np.clip(np.stack([np.asarray(c, dtype=np.float64) for c in chans], axis=-1), 0.0, 1.0)
        notes.append(f"resized from {min(sw, sh)}x{min(sw, sh)} to {size}x{size}")
    return arr


def _check_background(background: Sequence[float]) -> np.ndarray:
    bg = np.asarray(background, dtype=np.float64).reshape(-1)
    if bg.shape != (3,) or (bg < 0).any() or (bg > 1).any():
        raise ConfigError.about("background", background, "must be 3 values in [0, 1]",
                                "an RGB colour, e.g. `background=(1.0, 1.0, 1.0)`")
    return bg


def open_oriented(path: str | Path, notes: list[str]) -> Image.Image:
    """The first frame of the image file ``path`` with its EXIF orientation applied (each step in ``notes``).

    Raises:
        ImageInputError: not a readable image file (see :func:`load_image`).
    """
    img = _open(Path(path))
    if getattr(img, "n_frames", 1) > 1:
        img.seek(0)
        notes.append(f"{img.n_frames} frames: the first one is used")
    orientation = img.getexif().get(0x0112, 1)
    if orientation not in (0, 1):
        notes.append(f"EXIF orientation {orientation} applied")
        return ImageOps.exif_transpose(img)
    return img


@dataclass
class RawImage:
    """An image file read at (about) its own size, before it is made square.

    Attributes:
        rgb: ``(H, W, 3)`` float64 in [0, 1]; alpha: ``(H, W)`` in [0, 1], or ``None`` without one.
        original_size: ``(width, height)`` in the file (after its EXIF orientation).
        notes: what was done to it.
    """

    rgb: np.ndarray
    alpha: np.ndarray | None
    original_size: tuple[int, int]
    notes: list[str] = field(default_factory=list)

    @property
    def scale(self) -> float:
        """File pixels per pixel of :attr:`rgb`: 1 unless the file was reduced on reading (then 2 or more)."""
        return min(self.original_size) / min(self.rgb.shape[:2])

    @property
    def shown_size(self) -> tuple[int, int] | None:
        """What :func:`square_resize` calls :attr:`rgb` in its notes: the file's size where it was reduced on
        reading (its one resize is said once, in the file's pixels), else ``None`` (its own)."""
        return None if self.scale == 1 else self.original_size


def read_image(path: str | Path, image_size: int) -> RawImage:
    """Read ``path`` for a model of ``image_size`` pixels: oriented, converted to float RGB (and alpha), and
    reduced by a whole factor (box filter, while still 8-bit) when it is 4 or more times the model's size
    (no note of its own: the reduction is the first step of the one resize :func:`square_resize` notes,
    :attr:`RawImage.shown_size`).

    Raises:
        ImageInputError: see the table in the module docstring.
    """
    if int(image_size) <= 0:
        raise ConfigError.about("image_size", image_size, "must be positive",
                                "the model's input size, e.g. `image_size=128`")
    path = Path(path)
    notes: list[str] = []
    oriented = open_oriented(path, notes)
    original = oriented.size
    short = min(oriented.size)
    if short >= 4 * int(image_size):  # shrink while still 8-bit: a float64 copy of a huge image is gigabytes
        factor = short // (2 * int(image_size))
        try:
            oriented = oriented.reduce(factor)
        except (ValueError, NotImplementedError):  # a mode reduce() does not support: convert at full size
            pass
    rgb, alpha = _to_rgba_float(oriented, path, notes)
    return RawImage(rgb, alpha, original, notes)


def load_image(path: str | Path, image_size: int, background: Sequence[float] = (1.0, 1.0, 1.0), *,
               warn: bool = True) -> LoadedImage:
    """Read one image and prepare it for a model trained on ``image_size`` square images.

    Args:
        path: image file (anything Pillow reads).
        image_size: the model's input size in pixels.
        background: the training data's background colour (RGB in [0, 1]); transparent pixels get it.
        warn: emit an :class:`ImageInputWarning` for every change made.
    Raises:
        ImageInputError: see the table in the module docstring.
    """
    path = Path(path)
    bg = _check_background(background)
    raw = read_image(path, image_size)
    notes = raw.notes
    arr = raw.rgb
    if raw.alpha is not None:
        if (raw.alpha < 1).any():
            notes.append(f"alpha composited over the background colour {tuple(round(float(b), 3) for b in bg)}")
        arr = composite(arr, raw.alpha, bg)
    arr = square_resize(arr, int(image_size), notes, shown_size=raw.shown_size)
    return finish(path, arr, raw.original_size, notes, warn=warn)


def finish(path: Path, arr: np.ndarray, original_size: tuple[int, int], notes: list[str], *,
           warn: bool = True) -> LoadedImage:
    """The :class:`LoadedImage` of a prepared ``(S, S, 3)`` array; each note a warning (``warn``)."""
    if warn:
        for note in notes:
            warnings.warn(f"{printable(path)}: {note}", ImageInputWarning, stacklevel=3)
    tensor = torch.from_numpy(np.ascontiguousarray(arr.transpose(2, 0, 1))).float()
    return LoadedImage(path, tensor, original_size, notes)


def load_images(paths: Sequence[str | Path], image_size: int, background: Sequence[float] = (1.0, 1.0, 1.0), *,
                warn: bool = True) -> tuple[Tensor, list[LoadedImage]]:
    """:func:`load_image` for several files; all are checked before any is returned.

    Returns:
        ``(N, 3, S, S)`` float images and the per-file :class:`LoadedImage` records.
    """
    if not paths:
        raise ImageInputError("no input images given")
    loaded = [load_image(p, image_size, background, warn=warn) for p in paths]
    return torch.stack([li.image for li in loaded]), loaded
