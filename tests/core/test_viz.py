"""Text in the pictures (cerberus_core.viz): words drawn apart, lines wrapped to a width; the chart frame's map
from data to pixels and its gridlines; the one image grid (batches or lists of images, blank cells, titles fitted
to their cells, inputs checked).

Issue 34: the warning drawn above ``*_figure1.png`` read "its border is notthe training background": Pillow's
default font advances a space by 2 px at 11 px, no more than the gap between two letters.
"""
from __future__ import annotations

import numpy as np
import pytest
import torch
from PIL import Image, ImageDraw

from cerberus_core.errors import ConfigError, ShapeError
from cerberus_core.eval.figures import note_banner
from cerberus_core.viz import (
    GRID,
    GRID_PAD,
    INK,
    ROW_LABEL_WIDTH,
    TITLE_HEIGHT,
    WORD_GAP,
    chart_frame,
    draw_text,
    figure_font,
    image_grid,
    text_width,
    word_positions,
    wrap_text,
)

SENTENCE = "out of the training domain: its border is not the training background (0, 0, 0)"


def _blank_runs(image: Image.Image) -> list[int]:
    """Lengths of the runs of blank columns between the first and last inked column of a one-line picture."""
    ink = (np.asarray(image.convert("L")) < 200).any(0)
    cols = np.nonzero(ink)[0]
    runs, run = [], 0
    for on in ink[cols[0]:cols[-1] + 1]:
        if on and run:
            runs.append(run)
        run = 0 if on else run + 1
    return runs


@pytest.mark.parametrize("size", [7, 9, 11, 12])
def test_drawn_words_are_further_apart_than_letters(size):
    font = figure_font(size)
    image = Image.new("RGB", (800, 3 * size), "white")
    draw_text(ImageDraw.Draw(image), (2, 2), SENTENCE, font=font, fill=(0, 0, 0))
    runs = sorted(_blank_runs(image), reverse=True)
    spaces = SENTENCE.count(" ")
    # every space is a wider gap than any gap inside a word: the widest `spaces` runs are the spaces
    assert min(runs[:spaces]) > max(runs[spaces:]), runs
    positions = word_positions(SENTENCE, font)
    assert [w for _, w in positions] == SENTENCE.split()
    for (x, word), (next_x, _) in zip(positions, positions[1:], strict=False):
        assert next_x - (x + font.getlength(word)) >= WORD_GAP * size  # the layout keeps a space's width


def test_wrapping_keeps_every_word_and_the_width():
    font = figure_font(11)
    text = ("the body is coloured (colour 0.20, training bodies 0.00): the model learned untextured grey renders "
            "only, so a clothed or coloured person is outside what it learned however well it is masked")
    for width in (60, 150, 388):
        lines = wrap_text(text, font, width)
        assert " ".join(lines).split() == text.split() and all(" ".join(line.split()) == line for line in lines)
        assert all(text_width(line, font) <= width or " " not in line for line in lines)  # a lone word may overrun
        assert all(text_width(f"{a} {b.split()[0]}", font) > width for a, b in zip(lines, lines[1:], strict=False))
    assert wrap_text("", font, 100) == [""]


def test_the_figure_note_shows_its_spaces():
    banner = note_banner(SENTENCE, 800)  # one line
    assert banner.height < 20
    assert len([r for r in _blank_runs(banner) if r >= 3]) == SENTENCE.count(" ")  # a gap per space, none else


def _chart():
    """A 300 x 200 px chart whose box spans x 40..270 px and y 20..150 px: data x 10..20, data y -2..3."""
    return chart_frame((300, 200), margins=(40, 30, 20, 50), x_range=(10.0, 20.0), y_range=(-2.0, 3.0))


def _ink(image, box):
    """Whether any pixel of ``box = (x0, y0, x1, y1)`` (px, end exclusive) is dark (text or frame)."""
    return bool((np.asarray(image.crop(box).convert("L")) < 128).any())


def test_the_chart_maps_the_data_ranges_onto_the_frame_edges():
    chart = _chart()
    assert (chart.left, chart.top, chart.right, chart.bottom) == (40, 20, 270, 150)
    assert (chart.x_px(10.0), chart.x_px(20.0), chart.x_px(15.0)) == (40.0, 270.0, 155.0)
    assert (chart.y_px(-2.0), chart.y_px(3.0), chart.y_px(0.0)) == (150.0, 20.0, 98.0)  # y runs up
    image = chart.image
    for corner in ((40, 20), (270, 20), (40, 150), (270, 150)):
        assert image.getpixel(corner) == INK
    assert image.getpixel((155, 98)) == image.getpixel((20, 98)) == (255, 255, 255)


def test_the_gridlines_land_on_their_values_and_keep_the_frame():
    chart = _chart()
    chart.grid_y([-2.0, 0.0], "{:.1f}".format)
    chart.grid_x([15.0], "{:.0f}".format)
    image = chart.image
    assert image.getpixel((100, 98)) == GRID and image.getpixel((100, 72)) == (255, 255, 255)  # y = 0, not y = 1
    assert image.getpixel((100, 97)) == image.getpixel((100, 99)) == (255, 255, 255)  # one pixel thick
    assert image.getpixel((155, 60)) == GRID  # x = 15 up the box
    assert image.getpixel((100, 150)) == INK  # the line at y = -2 lies on the bottom edge, which stays black
    assert _ink(image, (0, 90, 40, 100)) and not _ink(image, (0, 105, 40, 140))  # "0.0" in the left margin by its line
    assert _ink(image, (145, 156, 165, 170)) and not _ink(image, (45, 156, 135, 170))  # "15" under x = 15
    chart.grid_x([10.0, 20.0], "{:.0f}".format, fill=None)  # tick labels only: the frame edges stay black
    assert image.getpixel((40, 60)) == image.getpixel((270, 60)) == INK


@pytest.mark.parametrize("x_range, y_range", [((1.0, 1.0), (0.0, 1.0)), ((0.0, 1.0), (0.0, float("nan")))])
def test_a_chart_axis_needs_two_different_ends(x_range, y_range):
    with pytest.raises(ConfigError, match="two different finite ends"):
        chart_frame((100, 100), margins=(10, 10, 10, 10), x_range=x_range, y_range=y_range)


def _batch(n=3, size=8, channels=3):
    """``(n, channels, size, size)`` images, image ``k`` filled with ``(k + 1) / (n + 1)``."""
    return torch.arange(1, n + 1, dtype=torch.float32).div(n + 1).view(n, 1, 1, 1).expand(n, channels, size, size)


def test_a_batch_row_draws_as_its_list_of_images():
    batch = _batch()
    as_batch = image_grid([batch, batch[:2]], row_titles=["one", "two"], scale=2)
    as_lists = image_grid([list(batch), [batch[0], batch[1]]], row_titles=["one", "two"], scale=2)
    assert np.array_equal(np.asarray(as_batch), np.asarray(as_lists))
    cell = 2 * 8 + GRID_PAD
    assert as_batch.size == (ROW_LABEL_WIDTH + 3 * cell + GRID_PAD, 2 * cell + GRID_PAD)
    x, y = ROW_LABEL_WIDTH + GRID_PAD + 2 * cell, GRID_PAD + cell  # the missing third cell of the short row
    assert as_batch.getpixel((x + 8, y + 8)) == (255, 255, 255)
    assert as_batch.getpixel((x + 8, y + 8 - cell)) == (191, 191, 191)  # image 3 of 3: 0.75


def test_none_cells_stay_blank_and_grey_images_are_grey():
    grey = _batch(2, channels=1)
    picture = image_grid([[grey[0], None], [None, grey[1]]], column_titles=["a", "b"])
    cell = 8 + GRID_PAD
    assert picture.size == (2 * cell + GRID_PAD, TITLE_HEIGHT + 2 * cell + GRID_PAD)
    at = lambda r, c: picture.getpixel((GRID_PAD + c * cell + 4, TITLE_HEIGHT + GRID_PAD + r * cell + 4))  # noqa: E731
    assert (at(0, 0), at(0, 1), at(1, 0), at(1, 1)) == ((85, 85, 85), (255,) * 3, (255,) * 3, (170, 170, 170))


def test_a_long_row_title_is_fitted_into_its_column():
    """The row titles used to be cut at 10 characters whatever their width; now a title that is too wide is set
    smaller, then on two lines, then cut: no ink runs into the cells."""
    for title in ("s12 1234/5678", "subject 3 pose 1234567890 0.53", "W" * 40):
        picture = np.asarray(image_grid([_batch(1, size=32)], row_titles=[title]).convert("L"))
        label = picture[:, :ROW_LABEL_WIDTH + GRID_PAD]
        assert (label < 128).any(), title
        assert (label[:, ROW_LABEL_WIDTH - 2:] == 255).all(), f"{title!r} runs into the cells"


@pytest.mark.parametrize("rows, options, error, match", [
    ([], {}, ConfigError, "no images"),
    ([[None, None]], {}, ConfigError, "no images"),
    ([_batch()[0]], {}, ShapeError, r"row 0 is a tensor of shape \(3, 8, 8\); pass a \(B, C, H, W\) batch"),
    ([[torch.zeros(2, 8, 8)]], {}, ShapeError, "C = 1 .grey. or 3"),
    ([[np.zeros((3, 8, 8))]], {}, ShapeError, "ndarray"),
    ([[_batch(1)[0], _batch(1, size=4)[0]]], {}, ShapeError, "resize them to one"),
    ([_batch(2)], {"column_titles": ["a"]}, ShapeError, "1 column titles for 2 columns"),
    ([_batch(2)], {"row_titles": ["a", "b"]}, ShapeError, "2 row titles for 1 rows"),
    ([_batch(2)], {"scale": 0}, ConfigError, "scale = 0: image_grid: the upscaling is a whole number"),
    ([_batch(2)], {"scale": 1.5}, ConfigError, "whole number"),
])
def test_image_grid_says_what_is_wrong(rows, options, error, match):
    with pytest.raises(error, match=match):
        image_grid(rows, **options)


def test_titles_are_keywords():
    """The row titles were the second positional argument of the old grid, the column titles of the other one:
    the titles are named, never guessed from a position."""
    with pytest.raises(TypeError):
        image_grid([_batch()], ["a", "b", "c"])  # type: ignore[misc]
