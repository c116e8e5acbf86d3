"""cerberus_core.eval.compare: the paired difference of two evaluations, image by image."""
from __future__ import annotations

import dataclasses
import math
import os
import subprocess
import sys

import pytest

from cerberus_core.errors import DatasetError
from cerberus_core.eval.compare import PairedDifference, paired_difference


def _results(values: dict[int, float | None], key: str = "iou") -> dict:
    return {"standard": {"mean": 0.0}, "records": [{"index": i, key: v} for i, v in values.items()]}


def test_images_are_matched_by_index_not_by_position():
    a = _results({0: 0.5, 1: 0.6, 2: 0.7, 3: 0.8})
    b = _results({3: 0.7, 1: 0.4, 0: 0.6, 2: 0.7})  # another order: a - b = -0.1, 0.2, 0.0, 0.1 by index
    d = paired_difference(a, b)
    assert d.n == 4 and d.better == 2  # 0.2 and 0.1; 0.0 is no image better
    by_index = [-0.1, 0.2, 0.0, 0.1]
    sd = math.sqrt(sum((x - 0.05) ** 2 for x in by_index) / 3)
    assert d.mean == pytest.approx(0.05) and d.sem == pytest.approx(sd / 2)
    by_position = [ra["iou"] - rb["iou"] for ra, rb in zip(a["records"], b["records"], strict=True)]
    assert sum(x > 0 for x in by_position) == 3  # paired by position, three images would look better
    assert paired_difference(a, {"records": b["records"][::-1]}) == d  # the order of the records does not matter


def test_only_the_images_both_scored_count():
    a = _results({0: 0.5, 1: 0.6, 2: 0.9, 5: 0.4, 7: None})
    b = _results({1: 0.5, 2: 0.6, 7: 0.3, 9: 0.1, 0: None})  # shared with a value on both sides: 1 and 2
    d = paired_difference(a, b)
    assert (d.n, d.better) == (2, 2)
    assert d.mean == pytest.approx(0.2)
    assert d.sem == pytest.approx(math.sqrt(((0.1 - 0.2) ** 2 + (0.3 - 0.2) ** 2) / 1) / math.sqrt(2))


def test_mean_standard_error_and_count_by_hand():
    diffs = [0.03, -0.01, 0.05, 0.02, -0.04]
    a = _results({i: 0.5 + x for i, x in enumerate(diffs)})
    b = _results({i: 0.5 for i in range(5)})
    d = paired_difference(a, b)
    mean = sum(diffs) / 5  # 0.01
    sd = math.sqrt(sum((x - mean) ** 2 for x in diffs) / 4)  # the sample standard deviation (n - 1)
    assert d == PairedDifference(pytest.approx(mean), pytest.approx(sd / math.sqrt(5)), 3, 5)
    assert paired_difference(b, a).better == 2 and paired_difference(b, a).mean == pytest.approx(-mean)


def test_two_keys_of_one_evaluation_and_records_without_the_dict():
    records = [{"index": i, "iou": 0.5 + 0.1 * i, "hard_iou": 0.4} for i in range(3)]
    d = paired_difference({"records": records}, {"records": records}, "iou", "hard_iou")
    assert d.mean == pytest.approx(0.2) and (d.better, d.n) == (3, 3)
    assert paired_difference(records, records[::-1], "hard_iou") == paired_difference(records, records, "hard_iou")
    assert paired_difference(records, {"records": records}, "hard_iou").mean == 0  # key_b is key_a by default


@pytest.mark.parametrize("a, b", [
    (None, _results({0: 0.5, 1: 0.6})),
    (_results({0: 0.5, 1: 0.6}), None),
    (_results({0: 0.5, 1: 0.6}), _results({1: 0.4, 2: 0.3})),  # one image shared
    (_results({0: 0.5, 1: 0.6}), _results({2: 0.4, 3: 0.3})),  # none
    (_results({0: 0.5, 1: 0.6}), {"standard": {}}),  # no records
])
def test_none_below_two_shared_images(a, b):
    assert paired_difference(a, b) is None


def test_the_text_form_the_tables_print():
    assert str(PairedDifference(0.0123, 0.0041, 130, 208)) == "+0.012 ± 0.004 (130 / 208)"
    assert str(PairedDifference(-0.0056, 0.0048, 91, 208)) == "-0.006 ± 0.005 (91 / 208)"
    assert f"{PairedDifference(0.0, 0.0, 0, 2)}" == "+0.000 ± 0.000 (0 / 2)"  # an f-string says the same
    d = paired_difference(_results({0: 0.5, 1: 0.6}), _results({0: 0.4, 1: 0.4}))
    assert str(d or "-") == "+0.150 ± 0.050 (2 / 2)"  # a difference is true, so `d or "-"` picks it
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.mean = 0.0


def test_importing_it_loads_no_torch():
    # a fresh interpreter: the experiments' tables read results.json files with it, without torch
    code = "import sys, cerberus_core.eval.compare\nprint('torch' in sys.modules)"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(sys.path))
    res = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "False"


def test_records_of_different_test_sets_are_refused():
    a = [{"index": 0, "iou": 0.5, "subject": "s1", "pose": 0, "view": 0},
         {"index": 1, "iou": 0.6, "subject": "s1", "pose": 0, "view": 1}]
    b = [dict(a[0], iou=0.4), dict(a[1], iou=0.5, pose=3)]  # index 1 is another image there
    with pytest.raises(DatasetError, match="image 1 is pose 0 in one evaluation and 3 in the other"):
        paired_difference(a, b)
    assert paired_difference(a, [dict(b[0]), dict(a[1], iou=0.5)]).n == 2  # the same images pair
    assert paired_difference(a, _results({0: 0.4, 1: 0.5})).n == 2  # records that do not name their image pair


# ----------------------------------------------------------------------------- reading and comparing evaluations
def _write(folder, evaluation) -> None:
    import json

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "results.json").write_text(json.dumps(evaluation))


def test_an_evaluation_is_found_as_a_file_its_folder_or_a_run(tmp_path):
    from cerberus_core.eval.compare import evaluation_file, evaluation_name, load_evaluation

    evaluation = _results({0: 0.5, 1: 0.6})
    _write(tmp_path / "runs" / "cpu" / "eval", evaluation)
    _write(tmp_path / "heldout", evaluation)
    for path in (tmp_path / "runs" / "cpu", tmp_path / "runs" / "cpu" / "eval",
                 tmp_path / "runs" / "cpu" / "eval" / "results.json"):
        assert evaluation_file(path) == tmp_path / "runs" / "cpu" / "eval" / "results.json"
        assert load_evaluation(path) == evaluation and evaluation_name(path) == "cpu"
    assert load_evaluation(tmp_path / "heldout") == evaluation and evaluation_name(tmp_path / "heldout") == "heldout"


def test_what_is_not_an_evaluation_is_named(tmp_path):
    from cerberus_core.errors import NoEvaluationError
    from cerberus_core.eval.compare import load_evaluation

    with pytest.raises(NoEvaluationError, match="does not exist"):
        load_evaluation(tmp_path / "nothere")
    (tmp_path / "run").mkdir()
    with pytest.raises(NoEvaluationError, match=r"neither .*run/results.json nor .*run/eval/results.json.*cerberus eval"):
        load_evaluation(tmp_path / "run")
    (tmp_path / "bad.json").write_text("{not json")
    with pytest.raises(DatasetError, match="bad.json cannot be read as JSON"):
        load_evaluation(tmp_path / "bad.json")
    (tmp_path / "other.json").write_text('{"standard": {"mean": 0.5}}')
    with pytest.raises(DatasetError, match="no list of per-image 'records'"):
        load_evaluation(tmp_path / "other.json")


@pytest.mark.parametrize(("text", "problem"), [
    ("[" * 100_000 + "]" * 100_000, "nested too deeply"),  # json.loads: a RecursionError
    ('{"records": [], "n": ' + "9" * 5000 + "}", "a number of more than"),  # json.loads: a bare ValueError
    (b"\xff\xfe{}", "can't decode byte"),  # not UTF-8
])
def test_an_unreadable_evaluation_is_a_dataset_error_naming_the_file_and_the_fix(tmp_path, text, problem):
    from cerberus_core.eval.compare import load_evaluation

    path = tmp_path / "eval" / "results.json"
    path.parent.mkdir()
    path.write_bytes(text if isinstance(text, bytes) else text.encode())
    with pytest.raises(DatasetError, match=r"eval/results.json cannot be read as JSON \(.*") as caught:
        load_evaluation(tmp_path)
    assert problem in str(caught.value) and "pass the results.json an evaluation wrote" in str(caught.value)


def test_an_evaluation_that_cannot_be_opened_is_a_dataset_error(tmp_path, monkeypatch):
    from pathlib import Path

    from cerberus_core.eval.compare import load_evaluation

    _write(tmp_path, _results({0: 0.5}))

    def refused(self, *args, **kwargs):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_text", refused)
    with pytest.raises(DatasetError, match="results.json cannot be read .*Permission denied.*make it readable"):
        load_evaluation(tmp_path)


def test_rows_pair_each_evaluation_with_the_first():
    from cerberus_core.eval.compare import comparison_rows

    base = _results({0: 0.5, 1: 0.6, 2: 0.7}) | {"standard": {"mean": 0.6}}
    new = {"standard": {"mean": 0.65}, "hard": {"mean": 0.55},
           "records": [{"index": i, "iou": v, "hard_iou": v - 0.1} for i, v in enumerate((0.55, 0.62, 0.78))]}
    header, rows = comparison_rows({"base": base, "new": new})
    assert header == ["model", "images", "voxel IoU", "Δ voxel IoU", "Hard Human", "Δ Hard Human"]  # no precision
    assert rows[0] == ["base", 3, pytest.approx(0.6), None, None, None]
    assert rows[1][:3] == ["new", 3, pytest.approx(0.65)] and rows[1][3] == paired_difference(new, base)
    assert rows[1][3].better == 3 and rows[1][4] == pytest.approx(0.55)
    assert rows[1][5] is None  # the base has no Hard Human
    moved = {"standard": {"mean": 0.6}, "records": [{"index": 0, "subject": "s1", "iou": 0.5},
                                                    {"index": 1, "subject": "s1", "iou": 0.5}]}
    other = {"standard": {"mean": 0.6}, "records": [{"index": 0, "subject": "s2", "iou": 0.5},
                                                    {"index": 1, "subject": "s2", "iou": 0.5}]}
    with pytest.raises(DatasetError, match="different test sets"):
        comparison_rows({"a": moved, "b": other})


def test_the_paired_plot_puts_a_better_model_above_the_diagonal(tmp_path):
    from collections import Counter

    from PIL import Image

    from cerberus_core.eval.figures import paired_plot

    base = _results({i: 0.3 + 0.05 * i for i in range(10)})
    better = _results({i: 0.4 + 0.05 * i for i in range(10)})
    worse = _results({i: 0.2 + 0.05 * i for i in range(10)})
    image = Image.open(paired_plot({"base": base, "better": better, "worse": worse}, tmp_path / "p.png")).convert("RGB")
    width, height = image.size

    def saturated(ys: range) -> list[tuple[int, int, int]]:  # the coloured pixels of rows ys, most common first
        count = Counter(image.getpixel((x, y)) for x in range(width) for y in ys)
        return [c for c, _ in count.most_common() if max(c) - min(c) > 60]

    marks = saturated(range(36, height))[:2]  # below the two legend lines: each model's points, one exact colour
    sums = []
    for line in (0, 1):  # legend line i names model i in its colour (its text blended at the edges: match the hue)
        hue = max(range(3), key=saturated(range(16 * line, 16 + 16 * line))[0].__getitem__)
        colour = next(c for c in marks if max(range(3), key=c.__getitem__) == hue)
        points = [(x, y) for x in range(width) for y in range(36, height) if image.getpixel((x, y)) == colour]
        assert len(points) >= 10 * 9 // 2  # ten points of 3 x 3 px, some overlapping each other
        sums.append(sum(x + y for x, y in points) / len(points))  # the diagonal runs up to the right: x + y smaller above
    assert sums[0] < sums[1] - 50  # the better model above, the worse below
    with pytest.raises(DatasetError, match="two evaluations or more"):
        paired_plot({"base": base}, tmp_path / "one.png")


def test_precision_and_recall_are_the_per_image_means_their_difference_pairs():
    from cerberus_core.eval.compare import comparison_rows

    def evaluation(precision, recall, pooled):  # the segments summary pools the voxels: not the per-image mean
        records = [{"index": i, "iou": 0.5, "voxel_precision": p, "voxel_recall": r}
                   for i, (p, r) in enumerate(zip(precision, recall, strict=True))]
        return {"standard": {"mean": 0.5}, "segments": {"voxel_precision": pooled, "voxel_recall": pooled},
                "records": records}

    base = evaluation([0.6, 0.8, 0.7], [0.9, 0.8, None], pooled=0.99)
    new = evaluation([0.7, 0.8, 0.9], [0.95, 0.85, 0.5], pooled=0.01)
    header, rows = comparison_rows({"base": base, "new": new})
    assert header[4:] == ["precision", "Δ precision", "recall", "Δ recall"]
    assert rows[0][4] == pytest.approx(0.7) and rows[1][4] == pytest.approx(0.8)  # not 0.99, 0.01
    assert rows[1][5].mean == pytest.approx(rows[1][4] - rows[0][4])  # the same images: Δ is the columns' difference
    assert rows[0][6] == pytest.approx(0.85) and rows[1][6] == pytest.approx(0.7667, abs=1e-4)  # over its own images
    assert rows[1][7].n == 2 and rows[1][7].mean == pytest.approx(0.05)  # Δ over the two images both scored


def test_the_paired_plot_refuses_different_test_sets_as_the_table_does(tmp_path):
    from cerberus_core.eval.compare import comparison_rows
    from cerberus_core.eval.figures import paired_plot

    base = {"records": [{"index": i, "subject": "s1", "pose": 0, "view": i, "iou": 0.5} for i in range(3)]}
    other = {"records": [dict(r, pose=1, iou=0.6) for r in base["records"]]}
    same = {"records": [dict(r, iou=0.6) for r in base["records"]]}
    for draw in (lambda e: comparison_rows(e), lambda e: paired_plot(e, tmp_path / "p.png")):
        with pytest.raises(DatasetError, match="image 0 is pose 1 in one evaluation and 0 in the other: they scored "
                                               "different test sets"):
            draw({"base": base, "same": same, "other": other})
    assert not (tmp_path / "p.png").exists()  # refused before anything is drawn
    assert paired_plot({"base": base, "same": same}, tmp_path / "p.png").is_file()


def test_image_pairs_is_the_pairing_of_the_difference():
    from cerberus_core.eval.compare import image_pairs

    a = _results({0: 0.5, 1: 0.6, 2: 0.9, 5: 0.4, 7: None})
    b = _results({1: 0.5, 2: 0.6, 7: 0.3, 9: 0.1, 0: None})
    assert image_pairs(a, b) == [(0.6, 0.5), (0.9, 0.6)]  # a's order, only the images both scored
    d = paired_difference(a, b)
    assert d.n == 2 and d.mean == pytest.approx(sum(x - y for x, y in image_pairs(a, b)) / 2)
    assert image_pairs(a, {"standard": {}}) == []


# ----------------------------------------------------------------------------- evaluations measured alike
def _measured(folder, values: dict[int, float], **settings):
    """A results.json written to ``folder`` as ``cerberus eval`` writes one (``settings`` over the defaults: protocol
    kato, resolution 32, gt_open_mesh error; a setting given as None is left out, as older files lack it), read
    back as ``cerberus compare`` reads it."""
    from cerberus_core.eval.compare import load_evaluation

    recorded = {"protocol": "kato", "resolution": 32, "gt_open_mesh": "error"} | settings
    _write(folder, {k: v for k, v in recorded.items() if v is not None} | _results(values))
    return load_evaluation(folder)


def test_an_older_evaluation_without_gt_open_mesh_pairs_with_one_that_records_error(tmp_path):
    from cerberus_core.eval.compare import check_comparable, comparison_rows, measurement

    old = _measured(tmp_path / "old", {0: 0.5, 1: 0.6, 2: 0.7}, gt_open_mesh=None)
    new = _measured(tmp_path / "new", {0: 0.55, 1: 0.62, 2: 0.78})
    assert "gt_open_mesh" not in old and measurement(old) == measurement(new) == {
        "protocol": "kato", "resolution": 32, "gt_open_mesh": "error", "data_id": None}
    check_comparable({"old": old, "new": new})
    header, rows = comparison_rows({"old": old, "new": new})
    assert rows[1][3] == paired_difference(new, old) and rows[1][3].n == 3
    records = new["records"]  # bare records know no setting: they pair with any evaluation
    assert paired_difference(records, _measured(tmp_path / "close", {0: 0.4, 1: 0.5}, gt_open_mesh="close")).n == 2


def test_evaluations_measured_differently_are_refused_naming_each_setting_and_value(tmp_path):
    from cerberus_core.errors import IncomparableEvaluationsError
    from cerberus_core.eval.compare import comparison_rows
    from cerberus_core.eval.figures import paired_plot

    values = {0: 0.5, 1: 0.6, 2: 0.7}
    base = _measured(tmp_path / "base", values, gt_open_mesh=None)  # older: made under gt_open_mesh error
    same = _measured(tmp_path / "same", values)
    closed = _measured(tmp_path / "closed", values, gt_open_mesh="close", resolution=64)
    evaluations = {"base": base, "same": same, "closed": closed}
    for draw in (lambda: comparison_rows(evaluations), lambda: paired_plot(evaluations, tmp_path / "p.png")):
        with pytest.raises(IncomparableEvaluationsError) as caught:
            draw()
        message = str(caught.value)
        assert message == ("evaluations measured under different settings cannot be paired image by image: "
                           "resolution is 32 in base and same, 64 in closed; gt_open_mesh is 'error' in base and "
                           "same, 'close' in closed; evaluate them again with the same `resolution` and "
                           "`gt_open_mesh`, or compare only those that agree")
        assert caught.value.differences == {"resolution": {"base": 32, "same": 32, "closed": 64},
                                            "gt_open_mesh": {"base": "error", "same": "error", "closed": "close"}}
        assert isinstance(caught.value, DatasetError) and "--" not in message  # Python terms, no flag
    assert not (tmp_path / "p.png").exists()  # refused before anything is drawn
    with pytest.raises(IncomparableEvaluationsError, match="protocol is 'kato' in a, 'other' in b; evaluate them "
                                                           "again with the same `protocol`"):
        paired_difference(base, base | {"protocol": "other"})  # the one pairing checks too, its arguments named
    assert comparison_rows({"base": base, "same": same})[1][1][3].n == 3  # those that agree still pair


def test_evaluations_of_different_data_are_refused_while_one_without_data_id_pairs_with_any(tmp_path):
    """Two datasets whose images share subject, pose and view names (another generation, another preset's split)
    pair by index without a complaint from the records: ``data_id`` (the split's content, results.json) tells them
    apart. A results.json from before it was recorded knows no data, and pairs as before."""
    from cerberus_core.errors import IncomparableEvaluationsError
    from cerberus_core.eval.compare import MEASUREMENT, check_comparable, comparison_rows, measurement

    values = {0: 0.5, 1: 0.6, 2: 0.7}
    old = _measured(tmp_path / "old", values)  # no data_id: not known, not compared
    large = _measured(tmp_path / "large", {0: 0.55, 1: 0.62, 2: 0.78}, data_id="49bc547ce46b9202")
    again = _measured(tmp_path / "again", {0: 0.52, 1: 0.6, 2: 0.71}, data_id="49bc547ce46b9202")
    other = _measured(tmp_path / "other", values, data_id="0f1e2d3c4b5a6978")
    assert [s.default for s in MEASUREMENT if s.key == "data_id"] == [None] and measurement(old)["data_id"] is None
    check_comparable({"old": old, "large": large, "other": other["records"]})  # bare records know no data either
    assert paired_difference(large, old).n == paired_difference(again, large).n == 3
    with pytest.raises(IncomparableEvaluationsError) as caught:
        comparison_rows({"old": old, "large": large, "again": again, "other": other})
    assert str(caught.value) == ("evaluations measured under different settings cannot be paired image by image: the "
                                 "data scored (data_id) is '49bc547ce46b9202' in large and again, '0f1e2d3c4b5a6978' "
                                 "in other; evaluate them again with the same `data` and `split`, or compare only "
                                 "those that agree")
    assert caught.value.differences == {"data_id": {"large": "49bc547ce46b9202", "again": "49bc547ce46b9202",
                                                    "other": "0f1e2d3c4b5a6978"}}
    with pytest.raises(IncomparableEvaluationsError, match=r"data_id\) is .* evaluate them again with the same "
                                                           "`resolution` and `data` and `split`"):
        paired_difference(large, other | {"resolution": 64})
