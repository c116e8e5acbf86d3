"""``plot_loss_curves``: the loss terms of ``metrics.csv`` on a log10 axis with a gridline at every decade, and a
note in place of the curves when no finite loss was logged."""
from __future__ import annotations

import numpy as np
from PIL import Image

from cerberus_core.train.logs import plot_loss_curves
from cerberus_core.viz import INK


def test_the_decades_are_gridlines_and_the_frame_spans_them(tmp_path):
    csv = tmp_path / "metrics.csv"
    csv.write_text("step,total\n" + "".join(f"{s},{10 ** (1 - s / 50)}\n" for s in range(0, 151, 10)))  # 10 .. 0.01
    image = Image.open(plot_loss_curves(csv, tmp_path / "loss.png", terms=["total"])).convert("RGB")
    assert image.size == (720, 420)  # box 70..590 px across, 20..380 px down: log10 -2 .. 1
    assert [image.getpixel((560, y)) for y in (140, 260)] == [(225, 225, 225)] * 2  # 1e0 and 1e-1
    assert image.getpixel((560, 200)) == (255, 255, 255)
    assert image.getpixel((300, 20)) == image.getpixel((300, 380)) == INK  # 1e1 and 1e-2 on the frame's edges


def test_no_finite_loss_leaves_a_note_in_the_frame(tmp_path):
    csv = tmp_path / "metrics.csv"
    csv.write_text("step,total\n0,nan\n10,\n")
    image = Image.open(plot_loss_curves(csv, tmp_path / "loss.png", terms=["total"])).convert("L")
    assert (np.asarray(image.crop((80, 30, 200, 45))) < 128).any()  # "no finite losses logged"
    assert image.getpixel((70, 200)) == 0 and image.getpixel((300, 200)) == 255
