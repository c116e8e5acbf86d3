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
