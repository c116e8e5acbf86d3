"""The optional column groups of ``cerberus compare`` (:data:`cerberus_core.eval.compare.COLUMN_GROUPS`), read from real
``results.json`` files, ``metrics.csv`` and ``eval_train/`` written to a run folder: each cell reads the key it names
(every decoy beside it holds another figure), and ``trade_plot`` draws each run where its two IoUs put it."""
from __future__ import annotations

import json

import pytest

from cerberus_core.bodies.human_heldout import FAMILIES, heldout_pose_id
from cerberus_core.errors import ConfigError, DatasetError
from cerberus_core.eval.compare import (
    COLUMN_GROUPS,
    column_groups,
    comparison_rows,
    group_means,
    load_evaluation,
    paired_difference,
    run_folder,
)

#: A results.json with every summary the columns read, and a decoy beside each key they read.
SUMMARIES = {
    "segments": {"spare_count": 2, "spare_parts": [1, 3], "deletion_loss": [0.01, 0.0, 0.02, 0.001, 0.03],
                 "recall": {"head": 0.9, "lower_arm.L": 0.123, "lower_arm.R": 0.456, "shin.L": None},
                 "body_share": {"head": 0.5, "lower_arm.L": 0.25, "lower_arm.R": 0.25}, "voxel_recall": 0.8},
    "allocation": {"keypoint_spread": [1.0, 7.3, 2.0, 6.1, 3.4], "low_coverage_parts": [0, 1, 2],
                   "segment_to_keypoint": {"head": 3.0, "lower_arm.L": 12.3, "lower_arm.R": None},
                   "segment_spread": {"head": 99.0, "lower_arm.L": 98.0, "lower_arm.R": 97.0}},
    "part_quality": {"consistency": 0.7123, "mean_entropy_bits": 0.3,
                     "parts": [{"part": 0, "label": "head", "agreement": 0.95},
                               {"part": 1, "label": "shin.L", "agreement": 0.45},
                               {"part": 2, "label": None, "images": 0},
                               {"part": 3, "label": "shin.R", "agreement": 0.55}],
                     "sides_merged": {"consistency": 0.8,
                                      "parts": [{"part": 0, "label": "head", "agreement": 0.95},
                                                {"part": 1, "label": "shin", "agreement": 0.9},
                                                {"part": 2, "label": None, "images": 0},
                                                {"part": 3, "label": "torso", "agreement": 0.3}]}},
    "part_visibility": {"parts_hidden_in_most_images": 3, "hidden_in_most_images": [0, 1, 2, 3, 4]},
    "depth": {"poses": 2, "mean_translation_disagreement": 0.0456, "translation_disagreement": [0.1, 0.2],
              "input_view_silhouette_iou": 0.777, "turned_view_silhouette_iou": 0.6543},
}


def _results(ious, hard=None, **summaries) -> dict:
    records = [{"index": i, "subject": "s", "iou": v} | ({} if hard is None else {"hard_iou": v + hard})
               for i, v in enumerate(ious)]
    return {"standard": {"mean": 0.0, "count": 999}, "records": records} | summaries


def _write(folder, results) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "results.json").write_text(json.dumps(results))


def _columns(header, row, groups) -> dict:
    """``{header: cell}`` of the columns the groups added."""
    extra = [c.header for g in column_groups(groups) for c in g.columns]
    return dict(zip(header[-len(extra):], row[-len(extra):], strict=True))


def test_the_parts_and_depth_columns_read_the_figures_they_name(tmp_path):
    _write(tmp_path / "run" / "eval", _results([0.5, 0.6, 0.7], **SUMMARIES))
    evaluation = load_evaluation(tmp_path / "run")
    header, rows = comparison_rows({"run": evaluation}, "parts,depth")
    assert header[:4] == ["model", "images", "voxel IoU", "Δ voxel IoU"]  # the paired columns first, as without
    assert _columns(header, rows[0], "parts,depth") == {
        "spare parts": "2 of 5",  # not the 3 low-coverage parts
        "keypoint spread, top 4 (px)": "7.3 6.1 3.4 2.0",  # the four largest, largest first
        "segment → keypoint (px)": "head 3.0, lower_arm.L 12.3",  # not the segment spread; unset left out
        "segment recall": "head 0.90, lower_arm.L 0.12, lower_arm.R 0.46",  # not the body share
        "part consistency": "0.712",  # per side, not the merged 0.8
        "merged labels ≥ 0.5": "head, shin",  # left and right merged (not shin.R), torso below 0.5
        "part labels (agreement)": "head (0.95), shin.R (0.55), shin.L (0.45)",  # per side, most consistent first
        "parts hidden in most images": 3,
        "input-view silhouette IoU": "0.777",
        "turned-view silhouette IoU": "0.654",
        "translation disagreement": "0.046",  # the mean, not a pose's
    }


def test_the_run_folder_columns_read_its_training_log_and_own_images(tmp_path):
    run = tmp_path / "run"
    _write(run / "eval", _results([0.5, 0.6, 0.7]))
    _write(run / "eval_train", _results([0.8, 0.9]) | {"standard": {"mean": 0.1, "count": 7}})
    # two sittings: 120 s to step 600, then resumed at 600 and 240 s more to step 900
    (run / "metrics.csv").write_text("step,elapsed_s,total\n300,60,1\n600,120,1\n700,40,1\n900,240,1\n1000,,1\n")
    _write(tmp_path / "heldout", _results([0.4, 0.5]))  # an evaluation of its own: no run folder
    named = {"run": run, "other": tmp_path / "heldout"}
    assert run_folder(run) == run_folder(run / "eval") == run and run_folder(tmp_path / "heldout") is None
    evaluations = {name: load_evaluation(path) for name, path in named.items()}
    header, rows = comparison_rows(evaluations, ["training", "own-images"],
                                   {name: run_folder(path) for name, path in named.items()})
    assert _columns(header, rows[0], "training,own-images") == {
        "steps": 900, "minutes": "6",  # 120 + 240 s over the two sittings, not the last row's 240
        "steps/s": "2.50", "own training images (n)": "0.8500 (2)",  # the images' mean, of eval_train/
        "gap": "0.250"}  # 0.85 - 0.6
    assert set(_columns(header, rows[1], "training,own-images").values()) == {None}
    header, rows = comparison_rows(evaluations, "training")  # no run folders given: nothing to read
    assert rows[0][-3:] == [None, None, None]


def test_the_heldout_columns_are_the_families_means(tmp_path):
    poses = [heldout_pose_id(k) for k in range(len(FAMILIES))] * 2 + [5, 6]  # two of each family, two canonical
    ious = [0.1 * (k % len(FAMILIES)) + 0.02 * (k // len(FAMILIES)) for k in range(2 * len(FAMILIES))] + [0.8, 0.9]
    records = [{"index": i, "pose": p, "iou": v} for i, (p, v) in enumerate(zip(poses, ious, strict=True))]
    header, rows = comparison_rows({"a": {"records": records}, "b": _results([0.5, 0.6])}, "heldout")
    assert header[-len(FAMILIES) - 1:] == [*FAMILIES, "canonical"]
    assert rows[0][-len(FAMILIES) - 1:] == [f"{0.1 * k + 0.01:.3f}" for k in range(len(FAMILIES))] + ["0.850"]
    assert rows[1][-len(FAMILIES) - 1:] == [None] * (len(FAMILIES) + 1)  # no held-out pose: no breakdown
    assert group_means(records, "pose")[5] == 0.8


def test_no_groups_leave_the_table_as_it_was_and_an_evaluation_without_summaries_shows_none():
    base, new = _results([0.5, 0.6, 0.7], hard=-0.1), _results([0.55, 0.62, 0.69], hard=-0.05)
    header, rows = comparison_rows({"base": base, "new": new})
    assert header == ["model", "images", "voxel IoU", "Δ voxel IoU", "Hard Human", "Δ Hard Human"]
    assert rows[1][3] == paired_difference(new, base) and len(rows[1]) == len(header)
    assert comparison_rows({"base": base, "new": new}, "") == (header, rows)
    everything = ",".join(g.name for g in COLUMN_GROUPS)
    wide, wide_rows = comparison_rows({"base": base, "new": new}, everything)
    assert len(wide) == 6 + sum(len(g.columns) for g in COLUMN_GROUPS) and wide[:6] == header
    assert [row[:6] for row in wide_rows] == rows and set(wide_rows[0][6:]) == {None}


def test_an_unknown_group_is_a_config_error_naming_the_groups():
    with pytest.raises(ConfigError, match=r"no column group 'dpeth' \(did you mean 'depth'\?\); the groups are "
                                          r"parts, depth, training, own-images, heldout") as caught:
        column_groups("parts,dpeth")
    assert caught.value.key == "columns" and caught.value.value == "parts,dpeth"
    assert [g.name for g in column_groups(["depth", "parts", "depth"])] == ["depth", "parts"]


def test_the_trade_plot_puts_each_run_at_its_two_ious(tmp_path):
    from PIL import Image

    from cerberus_core.eval.figures import TRADE_POINT, trade_plot

    a, b = _results([0.40, 0.50, 0.60], hard=-0.05), _results([0.42, 0.53, 0.59], hard=-0.165)  # Hard 0.45, 0.35
    image = Image.open(trade_plot({"a": a, "b": b, "no hard": _results([0.5, 0.5])}, tmp_path / "t.png")).convert("RGB")
    points = [(x, y) for x in range(image.width) for y in range(image.height) if image.getpixel((x, y)) == TRADE_POINT]
    ys = sorted({y for _, y in points})
    assert len(ys) > 10 and ys[-1] - ys[0] > 100  # Hard Human 0.45 against 0.35: far apart vertically
    middle = (ys[0] + ys[-1]) / 2
    upper, lower = ([x for x, y in points if (y < middle) == up] for up in (True, False))
    assert max(upper) < min(lower)  # a (IoU 0.500) up and to the left of b (0.513)
    with pytest.raises(DatasetError, match="no evaluation .* has both a voxel IoU and a Hard Human IoU"):
        trade_plot({"no hard": _results([0.5, 0.5])}, tmp_path / "none.png")
    assert not (tmp_path / "none.png").exists()
