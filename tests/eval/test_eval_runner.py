"""Standard, Hard Human and part-quality evaluation in one pass, on a real (tiny) rendered test set."""
from __future__ import annotations

import json

import numpy as np
import pytest
import torch
from conftest import IMAGE_SIZE, OracleModel, body_parts

from cerberus_core.eval.report import comparison_table, markdown_report, write_json
from cerberus_core.eval.runner import evaluate_dataset
from cerberus_core.eval.standard import VoxelScorer


def test_oracle_scores_one_and_hard_human_uses_canonical_shapes(tiny_dataset, iou_scorer, renderer, tmp_path):
    model = OracleModel(tiny_dataset)
    scorer = VoxelScorer(factory=iou_scorer)
    res = evaluate_dataset(tiny_dataset, model, batch_size=5, scorer=scorer, renderer=renderer, progress=False)
    n = len(tiny_dataset)
    assert res.standard.count == n and res.standard.mean == pytest.approx(1.0)
    assert set(res.standard.per_group) == {it["subject"] for it in tiny_dataset.items}
    # Canonical image of each subject: pose 0, view 0; every other image is scored in the hard test.
    assert res.canonical == {s: min(i for i, it in enumerate(tiny_dataset.items) if it["subject"] == s)
                             for s in res.standard.per_group}
    assert res.hard.count == n - 2
    for rec in res.records:
        if rec["index"] in res.canonical.values():
            assert "hard_iou" not in rec
        elif rec["pose"] == 0:  # another view of the canonical pose: same transforms, exact
            assert rec["hard_iou"] == pytest.approx(1.0)
        else:  # canonical capsules moved to the new pose's centres but not turned
            assert 0.05 < rec["hard_iou"] < 0.95
    assert res.hard.mean < res.standard.mean
    # Work done once: one forward per image (+ the canonical ones), one GT mesh and grid per pose.
    poses = len({(it["subject"], it["pose"]) for it in tiny_dataset.items})
    assert model.calls == n + 2
    assert tiny_dataset.gt_calls == poses
    assert scorer.cache.misses == poses
    pq = res.part_quality
    assert pq["consistency"] == 1.0 and pq["mean_segmentation_iou"] == pytest.approx(1.0)

    # Visibility: the oracle's parts are the body's capsules, so every image's counts partition the
    # silhouette of the input image itself (rendered over white by the dataset).
    vis = res.part_visibility
    assert vis["images"] == n and vis["image_size"] == [IMAGE_SIZE, IMAGE_SIZE] and len(vis["hidden_fraction"]) == 10
    for rec in res.records:
        image = tiny_dataset.images[rec["index"]]
        assert sum(rec["visible_pixels"]) == int((image < 1.0).any(0).sum())
    counts = np.array([rec["visible_pixels"] for rec in res.records])
    assert vis["hidden_fraction"] == pytest.approx((counts == 0).mean(0).tolist())
    assert vis["mean_visible_pixels"] == pytest.approx(counts.mean(0).tolist())
    assert vis["parts_hidden_in_most_images"] == sum(h > 0.5 for h in vis["hidden_fraction"])

    path = write_json(res, tmp_path / "results.json")
    data = json.loads(path.read_text())
    assert data["standard"]["count"] == n and len(data["records"]) == n
    assert data["part_visibility"]["hidden_fraction"] == pytest.approx(vis["hidden_fraction"])
    md = markdown_report(data, "Oracle")
    assert "| all | 1.0000 |" in md and "Hard Human" in md and "| head | 1.000 |" in md
    assert "| Images | Hidden in input view | Silhouette share |" in md and "parts hidden in most images:" in md


def test_subset_and_switches(tiny_dataset, iou_scorer, renderer):
    model = OracleModel(tiny_dataset)
    res = evaluate_dataset(tiny_dataset, model, indices=[3, 4], hard=False, part_quality=False,
                           scorer=VoxelScorer(factory=iou_scorer), renderer=renderer, progress=False)
    assert res.standard.count == 2 and res.hard is None and res.part_quality is None and res.canonical == {}
    assert res.part_visibility["images"] == 2
    md = markdown_report(res)
    assert "## Part visibility" in md and "| Learned part | Hidden in input view | Silhouette share | Visible pixels |" in md
    res = evaluate_dataset(tiny_dataset, model, indices=[3], hard=False, part_quality=False, visibility=False,
                           scorer=VoxelScorer(factory=iou_scorer), progress=False)
    assert res.part_visibility is None and "visible_pixels" not in res.records[0]
    assert "visibility" not in markdown_report(res)
    res = evaluate_dataset(tiny_dataset, model, indices=[3], part_quality=False, visibility=False,
                           scorer=VoxelScorer(factory=iou_scorer), progress=False)
    assert res.hard.count == 1  # the canonical image is found outside the subset
    with pytest.raises(ValueError, match="no images"):
        evaluate_dataset(tiny_dataset, model, indices=[], progress=False)


def test_model_output_is_checked(tiny_dataset, iou_scorer):
    with pytest.raises(TypeError, match="PartSet"):
        evaluate_dataset(tiny_dataset, lambda images, camera: images, hard=False,
                         scorer=VoxelScorer(factory=iou_scorer), progress=False)


def test_scorer_clamps_escaping_predictions_and_zeroes_rejected_ones(primitive_bodies, iou_scorer):
    body = primitive_bodies[1]
    parts = body_parts(body).part_meshes(0)
    gt = (body.vertices, body.faces)
    scorer = VoxelScorer(factory=iou_scorer)
    assert scorer(parts, gt).iou == pytest.approx(1.0)
    shifted = [(v + np.array([0.3, 0.0, 0.0]), f) for v, f in parts]
    s = scorer(shifted, gt)
    assert s.clipped and s.error is None and 0.0 < s.iou < 0.9
    flat = [(np.zeros_like(v), f) for v, f in parts]
    s = scorer(flat, gt)
    assert s.iou == 0.0 and "degenerate mesh" in s.error
    with pytest.raises(Exception, match="gt"):  # a broken ground truth is a data error, not a score
        scorer(flat, (np.zeros_like(body.vertices), body.faces))


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
