"""``cerberus compare``: evaluations side by side, each paired with the first; what is not one is named."""
from __future__ import annotations

import json

import pytest

from cerberus_core.cli import main


def _evaluation(folder, values, hard=None):
    folder.mkdir(parents=True)
    records = [{"index": i, "subject": "s", "iou": v} | ({} if hard is None else {"hard_iou": v + hard})
               for i, v in enumerate(values)]
    result = {"standard": {"mean": sum(values) / len(values)}, "hard": None if hard is None else {"mean": 0.5},
              "records": records}
    (folder / "results.json").write_text(json.dumps(result))
    return folder


def test_two_runs_side_by_side_with_the_plot(tmp_path, capsys):
    base = _evaluation(tmp_path / "runs" / "base" / "eval", [0.5, 0.6, 0.7])
    new = _evaluation(tmp_path / "eval_new", [0.55, 0.62, 0.69], hard=-0.1)
    plot = tmp_path / "figs" / "pairs.png"
    assert main(["compare", str(base.parent), f"ours={new}", "--plot", str(plot)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split("|")[1:-1] == [" model ", " images ", " voxel IoU ", " Δ voxel IoU ", " Hard Human ",
                                        " Δ Hard Human "]
    assert out[2].startswith("| base | 3 | 0.6000 | - |")
    assert out[3].startswith("| ours | 3 | 0.6200 | +0.020 ± 0.017 (2 / 3) | 0.5200 | - |")  # its images' mean
    assert "paired difference to base" in out[5] and out[6] == f"plot: {plot}" and plot.stat().st_size > 0


@pytest.mark.parametrize(("argv", "words"), [
    (["RUN"], "EVAL base: compare needs two evaluations or more, the baseline first"),
    (["RUN", "RUN/eval"], "a second evaluation named 'base'; name each one: NAME=PATH"),
    (["RUN", "nothere"], "no evaluation at nothere: nothere does not exist"),
    (["RUN", "RUN", "--plot", "figs"], "--plot figs: is a folder; pass a file path"),
    (["RUN", "RUN", "--plot", "RUN/eval/results.json"], "writing it would replace it; choose another --plot"),
    (["RUN", "RUN", "--trade-plot", "figs"], "--trade-plot figs: is a folder; pass a file path"),
    (["RUN", "RUN", "--columns", "parts,bogus"], "--columns parts,bogus: no column group 'bogus'; the groups are "
                                                 "parts, depth, training, own-images, heldout"),
])
def test_what_cannot_be_compared_is_one_line(tmp_path, capsys, monkeypatch, argv, words):
    _evaluation(tmp_path / "base" / "eval", [0.5, 0.6])
    (tmp_path / "figs").mkdir()
    monkeypatch.chdir(tmp_path)
    args = ["compare", *(a.replace("RUN", "base") for a in argv)]
    if args[1:3] == ["base", "base"]:
        args[2] = "other=base"
    assert main(args) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1 and words in captured.err


def test_column_groups_of_two_runs_and_the_trade_plot(tmp_path, capsys):
    for name, values, hard, minutes in (("a", [0.40, 0.50, 0.60], 0.05, 30), ("b", [0.42, 0.53, 0.59], -0.15, 45)):
        folder = _evaluation(tmp_path / name / "eval", values, hard=hard)
        results = json.loads((folder / "results.json").read_text())
        results["depth"] = {"turned_view_silhouette_iou": 0.6 + hard, "mean_translation_disagreement": 0.02}
        (folder / "results.json").write_text(json.dumps(results))
        (tmp_path / name / "metrics.csv").write_text(f"step,elapsed_s\n100,30\n200,{60 * minutes}\n")
    plot = tmp_path / "trade.png"
    assert main(["compare", str(tmp_path / "a"), str(tmp_path / "b"), "--columns", "depth,training",
                 "--trade-plot", str(plot)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].split("|")[7:-1] == [" input-view silhouette IoU ", " turned-view silhouette IoU ",
                                       " translation disagreement ", " steps ", " minutes ", " steps/s "]
    assert out[2].endswith("| - | 0.650 | 0.020 | 200 | 30 | 0.11 |")
    assert out[3].startswith("| b | 3 | 0.5133 | +0.013 ± 0.012 (2 / 3) | 0.3633 |")
    assert out[3].endswith("| - | 0.450 | 0.020 | 200 | 45 | 0.07 |")
    assert out[5].endswith("Then the columns of depth, training (cerberus compare --help)")
    assert out[6] == f"trade plot: {plot}" and plot.stat().st_size > 0


def test_the_help_says_each_column_group_in_one_line():
    from cerberus_core.cli import build_parser
    from cerberus_core.eval.compare import COLUMN_GROUPS

    parser = build_parser("compare")._subparsers._group_actions[0].choices["compare"]
    lines = parser.format_help().splitlines()
    for group in COLUMN_GROUPS:
        assert sum(line.split() == [group.name, *group.summary.split()] for line in lines) == 1, group.name


def test_evaluations_measured_differently_are_refused_in_one_line_naming_the_eval_flags(tmp_path, capsys):
    from cerberus_core.cli import build_parser
    from cerberus_core.eval.compare import MEASUREMENT

    old = _evaluation(tmp_path / "old" / "eval", [0.5, 0.6])  # no gt_open_mesh recorded: made under error
    closed = _evaluation(tmp_path / "closed" / "eval", [0.55, 0.62])
    results = json.loads((closed / "results.json").read_text()) | {"gt_open_mesh": "close"}
    (closed / "results.json").write_text(json.dumps(results))
    plot = tmp_path / "pairs.png"
    assert main(["compare", str(old), str(closed), "--plot", str(plot)]) == 2
    captured = capsys.readouterr()
    assert captured.out == "" and captured.err.count("\n") == 1 and not plot.exists()
    assert captured.err == ("cerberus compare: evaluations measured under different settings cannot be paired image "
                            "by image: gt_open_mesh is 'error' in old, 'close' in closed; evaluate them again with the "
                            "same cerberus eval --gt-open-mesh, or compare only those that agree\n")
    evaluate = build_parser("eval")._subparsers._group_actions[0].choices["eval"]
    flags = {flag for action in evaluate._actions for flag in action.option_strings}
    chosen = {f"--{key.replace('_', '-')}" for setting in MEASUREMENT for key in setting.choices}
    assert chosen == {"--protocol", "--resolution", "--gt-open-mesh", "--data", "--split"} <= flags  # eval has each


def test_evaluations_of_different_data_are_refused_naming_eval_s_data_and_split(tmp_path, capsys):
    """``data_id`` (the split's content) is chosen by ``cerberus eval --data`` and ``--split``: the fix names those,
    not a flag made of the key."""
    folders = {}
    for name, data_id in (("large", "49bc547ce46b9202"), ("other", "0f1e2d3c4b5a6978")):
        folders[name] = _evaluation(tmp_path / name / "eval", [0.5, 0.6])
        results = json.loads((folders[name] / "results.json").read_text()) | {"data_id": data_id}
        (folders[name] / "results.json").write_text(json.dumps(results))
    assert main(["compare", str(folders["large"]), str(folders["other"])]) == 2
    assert capsys.readouterr().err == (
        "cerberus compare: evaluations measured under different settings cannot be paired image by image: the data "
        "scored (data_id) is '49bc547ce46b9202' in large, '0f1e2d3c4b5a6978' in other; evaluate them again with the "
        "same cerberus eval --data and cerberus eval --split, or compare only those that agree\n")
