"""Pictures: part colours, image grids and PNG writing (PIL only)."""
from __future__ import annotations

import colorsys
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageDraw

from cerberus_core.plumbing.atomic import atomic_write

Tensor = torch.Tensor


def part_colors(n: int) -> Tensor:
    """``(n, 3)`` well-separated RGB colours in [0, 1] (golden-ratio hues)."""
    hues = [(i * 0.618033988749895) % 1.0 for i in range(n)]
    return torch.tensor([colorsys.hsv_to_rgb(h, 0.65, 0.95) for h in hues], dtype=torch.float32)


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
            draw.text((4, y + h * scale // 2 - 5), titles[r][:10], fill=(0, 0, 0))
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
