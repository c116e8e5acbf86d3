"""The scorer evaluation uses (cerberus_metrics.scoring.VoxelIoUScorer): parts past the kato grid are
clamped and counted, ground truths cached."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh


def test_scorer_entry_point_clamps_into_the_kato_cube_and_caches_ground_truths():
    """``voxel_iou_scorer``: what evaluation uses; escaping predictions are clamped and reported."""

    from cerberus_metrics.scoring import VoxelIoUScorer

    box = trimesh.creation.box(extents=(0.6, 0.6, 0.6))
    gt = (np.asarray(box.vertices), np.asarray(box.faces))
    scorer = VoxelIoUScorer("kato", 32)
    iou, clipped = scorer([gt], gt)
    assert iou == 1.0 and not clipped
    big = (np.asarray(box.vertices) * 3.0, np.asarray(box.faces))  # leaves [-0.5, 0.5]^3
    iou_big, clipped_big = scorer([big], gt)
    assert clipped_big and 0.0 < iou_big < 1.0
    assert (scorer.cache.misses, scorer.cache.hits) == (1, 1)
    with pytest.raises(Exception, match="unknown protocol"):
        VoxelIoUScorer("foo")


@pytest.mark.parametrize("direction", [(1, 0, 0), (1, 1, 0), (1, 1, 1)], ids=["face", "edge", "corner"])
def test_scorer_keeps_the_prediction_when_a_part_lies_wholly_past_a_face_edge_or_corner(helpers, direction):
    """Before: a part wholly past an edge or a corner collapsed to a line or a point when its vertices
    were clamped, so the whole prediction was rejected (IoU 0); past a face it became a slab of false
    voxels. Now such a part adds no voxel, in every direction alike, and is counted."""
    from cerberus_metrics.scoring import VoxelIoUScorer

    gt = helpers.box((-0.3, -0.3, -0.3), (0.3, 0.3, 0.3))
    gt_pair = (np.asarray(gt.vertices), np.asarray(gt.faces))
    far = helpers.box(0.75 * np.asarray(direction) - 0.05, 0.75 * np.asarray(direction) + 0.05)
    scorer = VoxelIoUScorer("kato", 32)
    iou, clamped = scorer([gt_pair, (np.asarray(far.vertices), np.asarray(far.faces))], gt_pair)
    assert (iou, clamped) == (1.0, 1)
    iou, clamped = scorer([gt_pair], gt_pair)
    assert (iou, clamped) == (1.0, 0)
