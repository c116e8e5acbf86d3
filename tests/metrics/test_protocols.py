"""Protocol frames (cerberus_metrics.protocols): degenerate and absurd scales give clear messages."""
from __future__ import annotations

import warnings

import pytest
import trimesh

from cerberus_metrics import MeshInputError, MeshQualityWarning, chamfer_l2, voxel_iou


def test_absurd_scales_give_clear_messages(helpers):
    gt = helpers.blob(1)
    huge = trimesh.Trimesh(gt.vertices * 1e6, gt.faces)
    with pytest.raises(MeshInputError, match=r"pred: mesh reaches .* ground-truth sizes .* same units"):
        voxel_iou(huge, gt, "gt_bbox")
    with pytest.raises(MeshInputError, match=r"pred .* and gt .* times apart in scale or position"):
        chamfer_l2(huge, gt, n_samples=500, normalize=True)
    far = trimesh.Trimesh(gt.vertices + 1e13, gt.faces, process=False)  # size ~0.6 at 1e13: ~300 float steps
    with pytest.raises(MeshInputError, match=r"too small to normalise relative to its position"):
        voxel_iou(gt, far, "gt_bbox")
    speck = trimesh.Trimesh(gt.vertices * 1e-3, gt.faces)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", MeshQualityWarning)
        iou = voxel_iou(speck, gt)
    assert 0 < iou < 0.01
    assert any("pred: mesh spans only" in str(w.message) for w in caught)


def test_the_outside_the_grid_error_names_the_fix_for_a_prediction_and_for_a_ground_truth(helpers, capsys,
                                                                                           tmp_path):
    """Before: a prediction past the kato grid was told `use protocol='gt_bbox'` (Python syntax, and the wrong fix
    for one prediction among normalised ones). Now a prediction is told the library's option (`outside='clamp'`),
    which the command line says as its flag; a ground truth, never clamped, is told to normalise it or use the
    gt_bbox protocol."""
    from cerberus_metrics.cli import main

    gt = helpers.box((-0.25, -0.25, -0.25), (0.25, 0.25, 0.25))
    big = helpers.box((-0.55, -0.55, -0.55), (0.55, 0.55, 0.55))
    with pytest.raises(MeshInputError) as exc:
        voxel_iou(big, gt)
    text = str(exc.value)
    assert text.startswith("pred: mesh lies (partly) outside the kato grid")
    assert "pass outside='clamp' to clamp it to the grid" in text and "gt_bbox" not in text
    assert voxel_iou(big, gt, outside="clamp") == pytest.approx(0.125)  # the fix it names works
    with pytest.raises(MeshInputError) as exc:
        voxel_iou(gt, big, outside="clamp")
    text = str(exc.value)
    assert text.startswith("gt: mesh lies (partly) outside the kato grid")
    assert "a ground truth is never clamped" in text and "gt_bbox protocol" in text and "outside=" not in text
    big.export(tmp_path / "big.obj")
    gt.export(tmp_path / "gt.obj")
    assert main(["iou", str(tmp_path / "big.obj"), str(tmp_path / "gt.obj")]) == 2
    assert "pass --outside clamp to clamp it" in capsys.readouterr().err

