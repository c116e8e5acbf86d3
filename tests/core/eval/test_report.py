"""The evaluation report (cerberus_core.eval.report): results.md shows names from outside as text, JSON is
strict, tables render."""
from __future__ import annotations

import json

import torch

from cerberus_core.eval.report import comparison_table, markdown_report, write_json

HOSTILE_SUBJECT = "<img src=x onerror=alert(1)>|`x`[link](http://e.x)\x1b[31m"


def _result(groups: dict[str, float]) -> dict:
    return {"protocol": "kato", "resolution": 32, "seconds": 1.0, "canonical": {s: 0 for s in groups},
            "standard": {"mean": 0.5, "count": len(groups), "per_group": groups, "clipped": 0, "failed": 0},
            "hard": {"mean": 0.4, "count": 1, "per_group": groups, "clipped": 0, "failed": 0},
            "part_quality": None, "part_visibility": None, "records": []}


def test_results_md_shows_hostile_names_as_text() -> None:
    md = markdown_report(_result({HOSTILE_SUBJECT: 0.5, "plain": 0.25}), title="Evaluation of runs/<b>x</b>")
    assert "<img" not in md and "<b>" not in md and "\x1b" not in md
    assert "# Evaluation of runs/&lt;b&gt;x&lt;/b&gt;" in md
    row = next(line for line in md.splitlines() if "onerror" in line)
    assert row.count(" | ") == 2  # the name's pipe does not open a cell: Subject | Standard | Hard Human
    assert "\\`x\\`" in row and "\\[link\\]" in row and "\\\\x1b" in row
    assert "| plain | 0.2500 | 0.2500 |" in md



def test_json_is_strict_and_tables_render(tmp_path):
    data = {"protocol": "kato", "resolution": 32, "standard": {"mean": float("nan"), "count": 0, "per_group": {}},
            "hard": None, "canonical": {}, "part_quality": None, "records": [], "x": torch.tensor(0.5)}
    text = write_json(data, tmp_path / "r.json").read_text()
    assert "NaN" not in text and json.loads(text)["x"] == 0.5
    table = comparison_table({"NMR": {"Human": 0.2596, "Animal": 0.3},
                              "Cerberus": {"Human": 0.497, "Hard Human": 0.4728}})
    lines = table.splitlines()
    assert lines[0] == "| Model | Human | Animal | Hard Human |"
    assert lines[2] == "| NMR | 0.2596 | 0.3000 | - |"


def test_body_segments_section_and_data_without_segment_labels():
    labelled = {"images": 2, "segments": ["head", "shin.L"], "segment_labels": True, "note": None,
                "voxel_precision": 0.6, "voxel_recall": 0.7, "spare_threshold": 0.003,
                "deletion_loss": [0.1, 0.001, -0.002], "spare_parts": [1, 2], "spare_count": 2,
                "body_share": {"head": 0.4, "shin.L": 0.6}, "recall": {"head": 0.9, "shin.L": 0.43},
                "missed_share": {"head": 0.1, "shin.L": 0.9}, "off_body_share": {"head": 0.7, "shin.L": 0.3},
                "input_view_coverage": {"head": 0.8, "shin.L": 0.35},
                "gt_render_coverage": {"head": 0.85, "shin.L": 0.75}}
    md = markdown_report(_result({"a": 0.5}) | {"segments": labelled})
    assert "## Body segments" in md and "precision 0.6000, recall 0.7000" in md
    assert "| shin.L | 0.600 | 0.430 | 0.900 | 0.300 | 0.350 | 0.750 |" in md
    assert "| 1 | - | 0.0010 | spare |" in md and "spare learned parts (deleting one costs <= 0.003 IoU): 2 of 3" in md
    assert "lowest shin.L 0.43, head 0.90" in md
    bare = labelled | {"segments": ["body"], "segment_labels": False, "note": "no segment labels: ...",
                       **dict.fromkeys(["body_share", "recall", "missed_share", "off_body_share",
                                        "input_view_coverage", "gt_render_coverage"], {})}
    md = markdown_report(_result({"a": 0.5}) | {"segments": bare})
    assert "No segment labels: ..." in md and "| GT segment |" not in md and "| 2 | - | -0.0020 | spare |" in md
