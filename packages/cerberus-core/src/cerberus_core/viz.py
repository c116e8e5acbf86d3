"""Pictures: part colours, text, image grids, chart frames and PNG writing (PIL only).

Text is drawn word by word (:func:`draw_text`, :func:`wrap_text`): Pillow's default font (Aileron, from
``ImageFont.load_default``) advances a space by 2 px at the 7-11 px sizes the figures use, no more than the
gap between two letters, so a sentence drawn whole reads as one word ("notthe"). Words are set
:data:`WORD_GAP` of the font size apart instead.
"""
from __future__ import annotations

import colorsys
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
from PIL import Image, ImageDraw, ImageFont

from cerberus_core.errors import ConfigError, ShapeError
from cerberus_core.plumbing.atomic import atomic_write

Tensor = torch.Tensor

#: Least advance between two drawn words, as a share of the font size (Aileron's own space is 0.18 of it).
WORD_GAP = 0.35

#: RGB of a chart's frame and text, and of its gridlines (:class:`ChartFrame`).
INK, GRID = (0, 0, 0), (228, 228, 228)


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


def atomic_save_png(img: Image.Image, path: str | Path) -> Path:
    """Write a PNG atomically (:func:`cerberus_core.plumbing.atomic.atomic_write`): a reader never sees half a file.
    Returns ``path``."""
    atomic_write(Path(path), lambda fh: img.save(fh, format="PNG"))
    return Path(path)


@dataclass(frozen=True)
class ChartFrame:
    """The plotting box of a line or scatter chart on its canvas, and the linear maps from data to pixels.

    Pixels are PIL's (x right, y down, from the canvas's top-left corner); ``left``/``right`` are the x and
    ``top``/``bottom`` the y of the box's edges, in px. Data ``x_range`` runs from the left edge to the right one
    and ``y_range`` from the bottom edge up to the top one, in the caller's data units (a step, an IoU, the log10
    of a loss). Made with its white canvas and the black frame by :func:`chart_frame`; a chart draws its lines
    and markers with :attr:`draw` at :meth:`x_px`, :meth:`y_px` and its legend in the margins.

    >>> chart = chart_frame((200, 100), margins=(20, 10, 10, 30), x_range=(0.0, 5.0), y_range=(-1.0, 1.0))
    >>> chart.x_px(0.0), chart.x_px(5.0), chart.y_px(-1.0), chart.y_px(1.0)
    (20.0, 190.0, 70.0, 10.0)
    >>> chart.grid_y([-1.0, 0.0, 1.0], "{:+.0f}".format)  # grey lines at y = 70, 40, 10 px, labels at the left
    >>> chart.image.getpixel((100, 40)), chart.image.getpixel((100, 70))  # the frame stays black over a line
    ((228, 228, 228), (0, 0, 0))
    """

    image: Image.Image
    draw: ImageDraw.ImageDraw
    left: int
    top: int
    right: int
    bottom: int
    x_range: tuple[float, float]
    y_range: tuple[float, float]

    def x_px(self, x: float) -> float:
        """The canvas x (px) of data ``x`` (the box's left edge at ``x_range[0]``, its right edge at ``x_range[1]``)."""
        x0, x1 = self.x_range
        return self.left + (x - x0) / (x1 - x0) * (self.right - self.left)

    def y_px(self, y: float) -> float:
        """The canvas y (px) of data ``y`` (the box's bottom edge at ``y_range[0]``, its top edge at ``y_range[1]``)."""
        y0, y1 = self.y_range
        return self.bottom - (y - y0) / (y1 - y0) * (self.bottom - self.top)

    def grid_y(self, values: Iterable[float], label: Callable[[float], str], fill: tuple[int, int, int] = GRID) -> None:
        """A horizontal line across the box at each data y of ``values``, labelled ``label(value)`` 8 px from the
        canvas's left edge (its top 6 px above the line). The frame is drawn again over the lines: a line at a
        range's end leaves the edge black."""
        font = figure_font(10)
        for v in values:
            y = self.y_px(v)
            self.draw.line([self.left, y, self.right, y], fill=fill)
            draw_text(self.draw, (8, y - 6), label(v), font=font, fill=INK)
        self._frame()

    def grid_x(self, values: Iterable[float], label: Callable[[float], str],
               fill: tuple[int, int, int] | None = GRID) -> None:
        """A vertical line up the box at each data x of ``values`` (none where ``fill`` is ``None``: tick labels
        only), labelled ``label(value)`` centred under it, 6 px below the box; the frame drawn again as by :meth:`grid_y`."""
        font = figure_font(10)
        for v in values:
            x = self.x_px(v)
            if fill is not None:
                self.draw.line([x, self.top, x, self.bottom], fill=fill)
            draw_text(self.draw, (x, self.bottom + 6), label(v), font=font, fill=INK, anchor="ma")
        self._frame()

    def axis_titles(self, x: str = "", y: str = "") -> None:
        """``x`` centred under the box, 16 px above the canvas's bottom edge; ``y`` inside the box's top-left
        corner (6 px right of and 4 px below it)."""
        font = figure_font(10)
        draw_text(self.draw, ((self.left + self.right) / 2, self.image.height - 16), x, font=font, fill=INK, anchor="ma")
        draw_text(self.draw, (self.left + 6, self.top + 4), y, font=font, fill=INK)

    def save(self, path: str | Path) -> Path:
        """The canvas written atomically to ``path`` (:func:`atomic_save_png`, which makes the folder)."""
        return atomic_save_png(self.image, path)

    def _frame(self) -> None:
        self.draw.rectangle([self.left, self.top, self.right, self.bottom], outline=INK)


def chart_frame(size: tuple[int, int], *, margins: tuple[int, int, int, int], x_range: tuple[float, float] = (0.0, 1.0),
                y_range: tuple[float, float] = (0.0, 1.0)) -> ChartFrame:
    """A white ``size = (width, height)`` px canvas with a black frame ``margins = (left, right, top, bottom)`` px
    inside its edges, as a :class:`ChartFrame` mapping ``x_range`` across the frame and ``y_range`` up it.

    Raises:
        ConfigError: a range whose two ends are equal or not finite (no map to pixels).
    """
    for key, (lo, hi) in (("x_range", x_range), ("y_range", y_range)):
        if not (math.isfinite(lo) and math.isfinite(hi) and lo != hi):
            raise ConfigError.about(key, (lo, hi), "a chart axis needs two different finite ends (data units)")
    (w, h), (left, right, top, bottom) = size, margins
    image = Image.new("RGB", size, "white")
    chart = ChartFrame(image, ImageDraw.Draw(image), left, top, w - right, h - bottom, x_range, y_range)
    chart._frame()
    return chart


#: Gap between the cells of an :func:`image_grid` and around them, px (the margin of the evaluation figures'
#: banners and keys too, :mod:`cerberus_core.eval.figures`).
GRID_PAD = 4
#: Height of an :func:`image_grid`'s band of column titles, px (none without column titles).
TITLE_HEIGHT = 18
#: Width of an :func:`image_grid`'s column of row titles, px (none without row titles).
ROW_LABEL_WIDTH = 90


def _fit_title(text: str, width: float, height: float) -> tuple[list[str], ImageFont.ImageFont]:
    """``text`` fitted into a ``width x height`` px box as lines drawn with :func:`draw_text`: a smaller font (12 px
    down to 7), else two lines, else cut with '…' (the titles of small cells would otherwise run into each
    other)."""
    for size in range(12, 6, -1):
        font = figure_font(size)
        if text_width(text, font) <= width:
            return [text], font
    words = text.split()
    for size in range(10, 6, -1):
        font = figure_font(size)
        if 2 * (size + 1) > height:
            continue
        for cut in range(len(words) - 1, 0, -1):
            lines = [" ".join(words[:cut]), " ".join(words[cut:])]
            if all(text_width(line, font) <= width for line in lines):
                return lines, font
    font = figure_font(7)
    while len(text) > 1 and text_width(text + "…", font) > width:
        text = text[:-1]
    return [text + "…"], font


def _draw_title(draw: ImageDraw.ImageDraw, text: str, xy: tuple[float, float], box: tuple[float, float],
                anchor: str) -> None:
    """``text`` fitted into ``box = (width, height)`` px (:func:`_fit_title`), its lines one step apart and centred
    as a block on the y of ``xy``; ``anchor`` as :func:`draw_text`'s."""
    lines, font = _fit_title(text, *box)
    step = font.size + 1 if hasattr(font, "size") else 11
    for k, line in enumerate(lines):
        draw_text(draw, (xy[0], xy[1] + (k - (len(lines) - 1) / 2) * step), line, font=font, fill=INK, anchor=anchor)


def _grid_cells(rows: Sequence[Tensor | Sequence[Tensor | None]]) -> tuple[list[list[Tensor | None]], int, int]:
    """The cells of :func:`image_grid`'s ``rows`` as lists of ``(C, H, W)`` images or ``None``, and their shared
    ``H, W``; the checks of its ``Raises``."""
    out: list[list[Tensor | None]] = []
    for r, row in enumerate(rows):
        if isinstance(row, Tensor) and row.ndim != 4:
            raise ShapeError(f"image_grid: row {r} is a tensor of shape {tuple(row.shape)}; pass a (B, C, H, W) batch "
                             "or a list of (C, H, W) images (one image: `[image]`)")
        out.append(list(row))
    cells = [c for row in out for c in row if c is not None]
    if not cells:
        raise ConfigError("image_grid: no images; pass at least one row with one image", key="rows")
    bad = next((c for c in cells if not isinstance(c, Tensor) or c.ndim != 3 or c.shape[0] not in (1, 3)), None)
    if bad is not None:
        raise ShapeError(f"image_grid: a cell of shape {tuple(getattr(bad, 'shape', ()))} ({type(bad).__name__}); "
                         "each image is a (C, H, W) tensor with C = 1 (grey) or 3 (RGB), or None for a blank cell")
    h, w = cells[0].shape[-2:]
    sizes = sorted({tuple(c.shape[-2:]) for c in cells})
    if len(sizes) > 1:
        raise ShapeError(f"image_grid: images of sizes {sizes} (H, W); resize them to one (H, W)")
    return out, h, w


def image_grid(rows: Sequence[Tensor | Sequence[Tensor | None]], *, column_titles: Sequence[str] | None = None,
               row_titles: Sequence[str] | None = None, scale: int = 1) -> Image.Image:
    """Images laid out as one picture: a table of cells, with optional titles above the columns and left of the rows.

    Args:
        rows: each row a ``(B, C, H, W)`` batch, or a sequence of ``(C, H, W)`` images or ``None`` (a blank cell);
            values in [0, 1] (clamped), ``C`` 1 (grey) or 3 (RGB), ``H, W`` in px and the same for every image.
            Rows may differ in length: the table is as wide as the longest, a shorter row ends blank.
        column_titles: one per column, centred above it in a :data:`TITLE_HEIGHT` px band; a title wider than its
            cell is set smaller, then on two lines, then cut with '…'.
        row_titles: one per row, at the left in a :data:`ROW_LABEL_WIDTH` px column, fitted the same way.
        scale: nearest-neighbour upscaling of every cell, a whole number (a cell is ``H * scale x W * scale`` px).
    Returns:
        An RGB picture of ``R`` rows of at most ``K`` cells, white around and between them: ``L + K * (W * scale +
        GRID_PAD) + GRID_PAD`` px wide and ``T + R * (H * scale + GRID_PAD) + GRID_PAD`` px high, ``T`` being
        :data:`TITLE_HEIGHT` with column titles (else 0) and ``L`` :data:`ROW_LABEL_WIDTH` with row titles (else 0).

    Raises:
        ConfigError: no image at all (``key="rows"``), or ``scale`` not a whole number of at least 1.
        ShapeError: a row that is a tensor but not ``(B, C, H, W)``; a cell that is not a ``(C, H, W)`` tensor
            with ``C`` 1 or 3; images of different sizes; titles that are not one per column, or one per row.

    >>> two = torch.rand(2, 3, 8, 8)  # a batch of two 8 x 8 px images: one row
    >>> image_grid([two]).size  # (width, height) in px: 2 * (8 + 4) + 4, (8 + 4) + 4
    (28, 16)
    >>> grid = image_grid([[two[0], None], [None, two[1]]], column_titles=["a", "b"], row_titles=["x", "y"], scale=2)
    >>> grid.size  # 90 + 2 * (16 + 4) + 4, 18 + 2 * (16 + 4) + 4
    (134, 62)
    """
    cells, h, w = _grid_cells(rows)
    if isinstance(scale, bool) or not isinstance(scale, int) or scale < 1:
        raise ConfigError.about("scale", scale, "image_grid: the upscaling is a whole number of at least 1",
                                "`scale=1` or more")
    ncols = max(len(row) for row in cells)
    if column_titles is not None and len(column_titles) != ncols:
        raise ShapeError(f"image_grid: {len(column_titles)} column titles for {ncols} columns; pass one title "
                         "per column, or `column_titles=None`")
    if row_titles is not None and len(row_titles) != len(cells):
        raise ShapeError(f"image_grid: {len(row_titles)} row titles for {len(cells)} rows; pass one title per row, "
                         "or `row_titles=None`")
    top = TITLE_HEIGHT if column_titles else 0
    left = ROW_LABEL_WIDTH if row_titles else 0
    cw, ch = w * scale, h * scale
    size = (left + ncols * (cw + GRID_PAD) + GRID_PAD, top + len(cells) * (ch + GRID_PAD) + GRID_PAD)
    canvas = Image.new("RGB", size, "white")
    draw = ImageDraw.Draw(canvas)
    for c, title in enumerate(column_titles or []):
        x = left + GRID_PAD + c * (cw + GRID_PAD)
        _draw_title(draw, title, (x + cw / 2, top / 2 + 1), (cw + GRID_PAD - 2, top - 2), "mm")
    for r, row in enumerate(cells):
        y = top + GRID_PAD + r * (ch + GRID_PAD)
        if row_titles:
            _draw_title(draw, row_titles[r], (4, y + ch / 2), (left - 6, ch), "lm")
        for c, cell in enumerate(row):
            if cell is None:
                continue
            tile = Image.fromarray(to_uint8(cell.unsqueeze(0))[0])
            if scale != 1:
                tile = tile.resize((cw, ch), Image.NEAREST)
            canvas.paste(tile, (left + GRID_PAD + c * (cw + GRID_PAD), y))
    return canvas
