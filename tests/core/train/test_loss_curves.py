"""``plot_loss_curves``: the loss terms of ``metrics.csv`` on a log10 axis with a gridline at every decade, and a
note in place of the curves when no finite loss was logged. ``training_time``: the steps and the seconds of
``metrics.csv``, summed over the sittings of a resumed run."""
from __future__ import annotations

import numpy as np
from PIL import Image

from cerberus_core.plumbing.metrics_csv import TrainingTime, training_time
from cerberus_core.train.logs import MetricsLog, plot_loss_curves
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


def test_training_time_sums_the_sittings_of_a_resumed_run(tmp_path):
    log = MetricsLog(tmp_path, tensorboard=False)
    for step, elapsed in ((20, 5.0), (40, 10.0), (60, 15.0)):  # interrupted after a checkpoint at step 40
        log.log(step, {"elapsed_s": elapsed})
    log.close()
    log = MetricsLog(tmp_path, start_step=40, tensorboard=False)  # --resume: drops step 60, restarts the clock
    for step, elapsed in ((60, 4.0), (80, 9.0)):
        log.log(step, {"elapsed_s": elapsed})
    log.close()
    assert training_time(tmp_path / "metrics.csv") == TrainingTime(steps=80, seconds=19.0)  # 10 + 9, not 9


def test_training_time_of_one_sitting_is_its_last_row_and_none_without_a_log(tmp_path):
    csv = tmp_path / "metrics.csv"
    csv.write_text("step,elapsed_s,total\n20,4.5,1.0\n40,9.0,0.5\n60,,0.4\n")  # the last row has no time
    assert training_time(csv) == TrainingTime(steps=40, seconds=9.0)
    assert training_time(tmp_path / "missing.csv") is None
