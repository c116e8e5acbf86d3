"""Text in the pictures (cerberus_core.viz): words drawn apart, lines wrapped to a width.

Issue 34: the warning drawn above ``*_figure1.png`` read "its border is notthe training background": Pillow's
default font advances a space by 2 px at 11 px, no more than the gap between two letters.
"""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image, ImageDraw

from cerberus_core.eval.figures import note_banner
from cerberus_core.viz import WORD_GAP, draw_text, figure_font, text_width, word_positions, wrap_text

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
