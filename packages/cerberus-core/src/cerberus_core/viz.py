"""Pictures: part colours, text, image grids and PNG writing (PIL only).

Text is drawn word by word (:func:`draw_text`, :func:`wrap_text`): Pillow's default font (Aileron, from
``ImageFont.load_default``) advances a space by 2 px at the 7-11 px sizes the figures use, no more than the
gap between two letters, so a sentence drawn whole reads as one word ("notthe"). Words are set
:data:`WORD_GAP` of the font size apart instead.
"""
from __future__ import annotations

import colorsys
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageDraw, ImageFont

from cerberus_core.plumbing.atomic import atomic_write

Tensor = torch.Tensor

#: Least advance between two drawn words, as a share of the font size (Aileron's own space is 0.18 of it).
WORD_GAP = 0.35


def part_colors(n: int) -> Tensor:
    """``(n, 3)`` well-separated RGB colours in [0, 1] (golden-ratio hues)."""
    hues = [(i * 0.618033988749895) % 1.0 for i in range(n)]
    return torch.tensor([colorsys.hsv_to_rgb(h, 0.65, 0.95) for h in hues], dtype=torch.float32)


def figure_font(size: int = 12) -> ImageFont.ImageFont:
    """Pillow's default font at ``size`` pixels (the fixed bitmap font on Pillow < 10.1, which has no sizes)."""
    try:
        return ImageFont.load_default(size=size)
    except TypeError:  # Pillow < 10.1 without FreeType sizes
        return ImageFont.load_default()


def word_gap(font: ImageFont.ImageFont) -> float:
    """Pixels from the end of one drawn word to the start of the next: :data:`WORD_GAP` of the font size, or
    the font's own space where that is wider."""
    size = getattr(font, "size", 10)
    return max(float(font.getlength(" ")), float(math.ceil(WORD_GAP * size)))


def word_positions(text: str, font: ImageFont.ImageFont) -> list[tuple[float, str]]:
    """Each word of one line of ``text`` (split at white space) with its x offset in pixels from the line's start:
    the previous word's advance plus :func:`word_gap`."""
    out, x = [], 0.0
    for word in text.split():
        out.append((x, word))
        x += float(font.getlength(word)) + word_gap(font)
    return out


def text_width(text: str, font: ImageFont.ImageFont) -> float:
    """Width in pixels of one line of ``text`` as :func:`draw_text` draws it (0 for no words)."""
    words = word_positions(text, font)
    return words[-1][0] + float(font.getlength(words[-1][1])) if words else 0.0


def wrap_text(text: str, font: ImageFont.ImageFont, width: float) -> list[str]:
    """``text`` broken at white space into lines of at most ``width`` pixels as :func:`draw_text` draws them (a
    word wider than that alone on its line); every word kept, in order."""
    lines: list[str] = []
    for word in text.split():
        if lines and text_width(f"{lines[-1]} {word}", font) <= width:
            lines[-1] = f"{lines[-1]} {word}"
        else:
            lines.append(word)
    return lines or [""]


def draw_text(draw: ImageDraw.ImageDraw, xy: tuple[float, float], text: str, *, font: ImageFont.ImageFont,
              fill: tuple[int, int, int], anchor: str = "la") -> None:
    """Draw one line of ``text`` at ``xy``, word by word (:func:`word_positions`).

    Args:
        anchor: Pillow's two-letter text anchor: ``l``/``m``/``r`` (the line's left, middle, right at ``x``), then
            the vertical one (``a`` ascender, ``m`` middle, ...) applied to every word.
    """
    x0 = xy[0] - {"l": 0.0, "m": text_width(text, font) / 2, "r": text_width(text, font)}[anchor[0]]
    for x, word in word_positions(text, font):
        draw.text((x0 + x, xy[1]), word, fill=fill, font=font, anchor=f"l{anchor[1]}")


def to_uint8(images: Tensor) -> np.ndarray:
    """``(B, C, H, W)`` float in [0, 1] → ``(B, H, W, 3)`` uint8 (grey images are repeated)."""
    x = images.detach().float().cpu().clamp(0, 1)
    if x.shape[1] == 1:
        x = x.expand(-1, 3, -1, -1)
    return (x[:, :3].permute(0, 2, 3, 1) * 255 + 0.5).to(torch.uint8).numpy()


def atomic_save_png(img: Image.Image, path: str | Path) -> None:
    """Write a PNG atomically (:func:`cerberus_core.plumbing.atomic.atomic_write`): a reader never sees half a file."""
    atomic_write(Path(path), lambda fh: img.save(fh, format="PNG"))


def image_grid(rows: Sequence[Tensor], titles: Sequence[str] | None = None, scale: int = 1, pad: int = 2) -> Image.Image:
    """Lay out rows of image batches as one picture.

    Args:
        rows: each ``(B, C, H, W)`` in [0, 1]; all rows share ``H, W`` (B may differ).
        titles: optional label drawn at the left of each row.
        scale: nearest-neighbour upscaling factor.
    """
    arrays = [to_uint8(r) for r in rows]
    h, w = arrays[0].shape[1:3]
    label_w = 60 if titles else 0
    ncols = max(a.shape[0] for a in arrays)
    canvas = Image.new("RGB", (label_w + ncols * (w * scale + pad) + pad, len(arrays) * (h * scale + pad) + pad), "white")
    draw = ImageDraw.Draw(canvas)
    for r, arr in enumerate(arrays):
        y = pad + r * (h * scale + pad)
        if titles:
            draw_text(draw, (4, y + h * scale // 2), titles[r][:10], font=figure_font(10), fill=(0, 0, 0), anchor="lm")
        for c, im in enumerate(arr):
            tile = Image.fromarray(im)
            if scale != 1:
                tile = tile.resize((w * scale, h * scale), Image.NEAREST)
            canvas.paste(tile, (label_w + pad + c * (w * scale + pad), y))
    return canvas


def save_image_grid(rows: Sequence[Tensor], path: str | Path, titles: Sequence[str] | None = None, scale: int = 1) -> Path:
    """:func:`image_grid` written atomically to ``path``."""
    atomic_save_png(image_grid(rows, titles, scale), path)
    return Path(path)
