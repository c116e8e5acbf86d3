"""End to end: a generated dataset on disk, the (untrained) Cerberus model, every evaluation."""
from __future__ import annotations

import math

import pytest
import torch

from cerberus_core.cli import main as cerberus_main
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.report import markdown_report
from cerberus_core.eval.runner import evaluate_dataset
from cerberus_core.eval.standard import VoxelScorer


@pytest.mark.slow
def test_untrained_model_on_generated_primitives(tmp_path, iou_scorer):
    from cerberus_core.model import Cerberus, ModelConfig

    root = tmp_path / "prim"
    assert cerberus_main(["data", "generate", "--dataset", "primitives", "--size", "tiny", "--out", str(root),
                          "--quiet"]) == 0
    ds = Dataset.open(root).views()
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(depth_offset=ds.scene.distance)).eval()
    res = evaluate_dataset(ds, model.reconstruct, batch_size=6, scorer=VoxelScorer(factory=iou_scorer), progress=False)
    assert res.standard.count == len(ds)
    assert set(res.standard.per_group) <= set(ds.subject_names)
    assert res["canonical"] and all(ds.records["canonical"][i] for i in res["canonical"].values())
    assert res["hard"].count == len(ds) - len(res["canonical"])
    assert all(0.0 <= r["iou"] <= 1.0 for r in res.records)
    pq = res["part_quality"]
    assert pq["gt_parts"] == ds.part_names and len(pq["parts"]) == model.num_parts
    assert not math.isnan(pq["mean_segmentation_iou"])
    vis = res["part_visibility"]  # rendered with make_renderer("auto"): no renderer was passed
    assert vis["images"] == len(ds) and len(vis["hidden_fraction"]) == model.num_parts
    assert "| all |" in markdown_report(res)
