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


@pytest.mark.parametrize("protocol", ["kato", "gt_bbox"])
def test_scorer_grids_are_the_voxels_of_its_score_part_by_part(helpers, protocol):
    """``grids``: each part alone on one box with the ground truth; their union scores exactly the IoU
    ``__call__`` gives (a part clamped into the kato grid included), and each part's voxels are what
    voxelizing it alone in the ground truth's frame gives."""
    from cerberus_metrics import voxelize
    from cerberus_metrics.scoring import VoxelIoUScorer

    gt = helpers.blob(3, 0.35)
    gt_pair = (np.asarray(gt.vertices), np.asarray(gt.faces))
    parts = [helpers.blob(4, 0.2, (-0.15, 0.0, 0.0)), helpers.blob(5, 0.2, (0.2, 0.1, 0.0)),
             helpers.box((0.3, -0.2, -0.2), (0.7, 0.2, 0.2))]  # the box leaves the kato grid
    pairs = [(np.asarray(m.vertices), np.asarray(m.faces)) for m in parts]
    scorer = VoxelIoUScorer(protocol, 32)
    grids = scorer.grids(pairs, gt_pair)
    iou, clamped = scorer(pairs, gt_pair)
    assert grids.parts.shape == (3, *grids.gt.shape) and (grids.iou, grids.clamped) == (iou, clamped)
    union = grids.parts.any(0)
    assert iou == np.count_nonzero(union & grids.gt) / np.count_nonzero(union | grids.gt)
    assert clamped == (1 if protocol == "kato" else 0)
    g = voxelize(gt_pair, protocol, 32)
    assert np.count_nonzero(grids.gt) == g.count
    for part, pair in zip(grids.parts, pairs, strict=True):
        alone = voxelize(pair, protocol, frame=g.frame, outside="clamp", check_self_intersections=False)
        assert np.count_nonzero(part) == alone.count
    centres = grids.centers(np.argwhere(grids.gt))
    assert np.allclose(centres, g.centers()) if protocol == "kato" else len(centres) == g.count
