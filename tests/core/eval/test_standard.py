"""Standard voxel IoU through the metric's scorer: parts leaving the kato grid are clamped and counted."""
from __future__ import annotations

import numpy as np
import pytest

from cerberus_core.eval.standard import Score, VoxelScorer, summarize
from tests.support.oracle import body_parts


@pytest.mark.parametrize("direction", [(1, 0, 0), (1, -1, 0), (-1, 1, 1)], ids=["face", "edge", "corner"])
def test_a_part_past_a_face_edge_or_corner_is_clamped_and_counted_not_a_failed_prediction(
        primitive_bodies, iou_scorer, direction):
    """Before: vertices were clamped to [-0.5, 0.5]^3 one by one, so a part wholly past an edge or a corner
    collapsed to a line or a point and the whole prediction was rejected (IoU 0, 'failed'). Now one rule
    holds in every direction: the part's voxels outside the grid are dropped, and the part is counted."""
    body = primitive_bodies[1]
    parts = body_parts(body).part_meshes(0)
    gt = (body.vertices, body.faces)
    scorer = VoxelScorer(factory=iou_scorer)
    moved = [(v + 2.0 * np.asarray(direction), f) if i == 0 else (v, f) for i, (v, f) in enumerate(parts)]
    without = scorer(parts[1:], gt)  # the prediction minus the part that left the grid
    s = scorer(moved, gt)
    assert s.error is None and s.clipped == 1
    assert s.iou == pytest.approx(without.iou) and 0.5 < s.iou < 1.0
    summary = summarize([s, scorer(parts, gt), s], ["a", "a", "b"])
    assert (summary.clipped, summary.clipped_parts, summary.failed) == (2, 2, 0)
    assert summary.to_dict()["clipped_parts"] == 2


def test_summary_counts_images_and_parts_clamped():
    scores = [Score(0.5, 3), Score(0.7, 0), Score(0.0, 0, "MeshInputError: x"), Score(0.9, 1)]
    s = summarize(scores, ["a", "a", "b", "b"])
    assert (s.clipped, s.clipped_parts, s.failed, s.count) == (2, 4, 1, 4)



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


def test_only_the_metrics_input_error_is_a_rejected_prediction(primitive_bodies, iou_scorer):
    """Before: ``VoxelScorer.voxels`` caught every exception as a rejected prediction scored 0, so a failure that
    says nothing about the prediction (here Python's recursion limit, reached by a prediction nested in lists
    deeper than it; a MemoryError or a bug alike) became an IoU of 0 among the scores. Now only the metric's input
    error (``scorer.rejects``) scores 0; anything else propagates."""
    body = primitive_bodies[1]
    parts = body_parts(body).part_meshes(0)
    gt = (body.vertices, body.faces)
    scorer = VoxelScorer(factory=iou_scorer)
    flat = [(np.zeros_like(v), f) for v, f in parts]
    s = scorer(flat, gt)  # the metric's input error: still a rejected prediction
    assert s.iou == 0.0 and s.error.startswith("MeshInputError")
    nested: list = [parts[0]]
    for _ in range(5000):
        nested = [nested]
    with pytest.raises(RecursionError):
        scorer(nested, gt)


def test_an_open_ground_truth_raises_instead_of_scoring_a_hollow_shell(iou_scorer):
    """Before: a ground truth without its top cap was voxelized as the shell the flood fill leaves and scored
    0.2786 against the closed sphere, silently. Now the metric refuses it, and the evaluation raises (a ground
    truth the metric refuses is a data error, not a score): a DatasetError naming the image and the fix in this
    package's terms, ``gt_open_mesh`` (the CLI says it as ``--gt-open-mesh``), never the metric's keyword.
    ``gt_open_mesh`` passes the metric the other policies: close its holes, or score it as it is."""
    import trimesh

    from cerberus_core.errors import DatasetError

    s = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    capless = (v, f[s.triangles_center[:, 2] < 0.3])
    scorer = VoxelScorer(factory=iou_scorer)
    assert scorer.gt_open_mesh == "error"
    with pytest.raises(DatasetError) as err:
        scorer([(v, f)], capless, "the ground truth of image 7 (subject s, pose 2)")
    message = str(err.value)
    assert message.startswith("the ground truth of image 7 (subject s, pose 2) is not watertight (40 boundary (open) "
                              "edges): ")
    assert "hollow shell" in message and "`gt_open_mesh=close`" in message and "`gt_open_mesh=warn`" in message
    assert "gt_open_mesh='close'" not in message
    assert scorer([(v, f)], (v, f)).iou == 1.0
    with pytest.warns(UserWarning, match="closed holes with pymeshlab"):
        closed = VoxelScorer(factory=iou_scorer, gt_open_mesh="close")([(v, f)], capless)
    with pytest.warns(UserWarning, match="not watertight"):
        shell = VoxelScorer(factory=iou_scorer, gt_open_mesh="warn")([(v, f)], capless)
    assert closed.iou > 0.9 and shell.iou < 0.3 and closed.error is None and shell.error is None
