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


def _sphere_and_capless():
    """An icosphere of radius 0.4 (mesh units, closed) and the same sphere with its top cap removed (open)."""
    s = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
    v, f = np.asarray(s.vertices), np.asarray(s.faces)
    return (v, f), (v, f[s.triangles_center[:, 2] < 0.3])


def test_an_open_ground_truth_is_refused_not_scored_as_a_hollow_shell():
    """Before: the scorer silenced the ground truth's quality warnings too, so a ground truth without its top cap
    was scored as the shell the flood fill leaves (2,632 voxels instead of 9,448): IoU 0.2786 against the closed
    sphere, without a word. Now it is an OpenMeshError naming the mesh, the defect and the fix; closing its holes
    (gt_open_mesh='close') scores it as the closed sphere it was."""
    from cerberus_metrics import MeshInputError, MeshQualityWarning, OpenMeshError
    from cerberus_metrics.scoring import VoxelIoUScorer

    closed, capless = _sphere_and_capless()
    with pytest.raises(OpenMeshError) as exc:
        VoxelIoUScorer()([closed], capless)
    text = str(exc.value)
    for words in ("gt:", "not watertight", "boundary (open) edges", "hollow shell", "close the mesh",
                  "gt_open_mesh='close'", "pymeshlab"):
        assert words in text, words
    assert isinstance(exc.value, MeshInputError) and exc.value.report.boundary_edges > 0
    with pytest.warns(MeshQualityWarning, match=r"gt: closed holes with pymeshlab \(gt_open_mesh='close'\)"):
        iou, clamped = VoxelIoUScorer(gt_open_mesh="close")([closed], capless)
    assert iou > 0.9 and clamped == 0
    with pytest.raises(MeshInputError, match="gt_open_mesh must be one of"):
        VoxelIoUScorer(gt_open_mesh="ignore")


def test_the_ground_truth_warnings_name_the_scorer_option_gt_open_mesh():
    """Before: the warnings on a ground truth said open_mesh='close' / open_mesh='error', an option the scorer has
    not; now they name the one it has, gt_open_mesh, whether its holes were closed or it is scored open."""
    import re

    from cerberus_metrics import MeshQualityWarning
    from cerberus_metrics.scoring import VoxelIoUScorer

    box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    cube, lidless = (np.asarray(box.vertices), np.asarray(box.faces)), (np.asarray(box.vertices), box.faces[2:])
    with pytest.warns(MeshQualityWarning) as closed:
        VoxelIoUScorer(gt_open_mesh="close")([cube], lidless)
    with pytest.warns(MeshQualityWarning) as scored_open:
        iou, _ = VoxelIoUScorer(gt_open_mesh="warn")([cube], lidless)
    assert iou < 1.0  # the open ground truth is the hollow shell the fill leaves, as gt_open_mesh='warn' says
    texts = [str(w.message) for w in [*closed, *scored_open]]
    assert texts == ["gt: closed holes with pymeshlab (gt_open_mesh='close'), adding 2 faces",
                     "gt: mesh is not watertight (4 boundary (open) edges). Treatment: surface rule: voxels touched by "
                     "the surface are exact, but the exterior flood fill enters through holes wider than about one "
                     "voxel, so an open region counts only its surface voxels. Use gt_open_mesh='close' to fill holes "
                     "with pymeshlab, or gt_open_mesh='error' to reject such meshes."]
    assert not any(re.search(r"(?<!gt_)open_mesh=", t) for t in texts)


def test_predictions_keep_their_tolerance_and_ground_truth_warnings_are_raised(recwarn):
    """The prediction is scored as before (an open part: no error, no warning); a ground-truth quality warning is
    no longer silenced (before: a ground truth spanning less than a voxel scored without a word)."""
    from cerberus_metrics import MeshQualityWarning
    from cerberus_metrics.scoring import VoxelIoUScorer

    closed, capless = _sphere_and_capless()
    scorer = VoxelIoUScorer()
    iou, _ = scorer([capless], closed)  # an open prediction: its fill leaks, quietly, as before
    assert 0.2 < iou < 0.35 and not [w for w in recwarn if issubclass(w.category, MeshQualityWarning)]
    box = trimesh.creation.box(extents=(0.01, 0.01, 0.01))  # 0.31 voxels at 32^3
    with pytest.warns(MeshQualityWarning, match="gt: mesh spans only"):
        scorer([closed], (np.asarray(box.vertices), np.asarray(box.faces)))


def test_the_scorer_names_the_errors_of_a_rejected_prediction():
    """``rejects``: what a caller may score 0 (the metric's input error), nothing broader."""
    from cerberus_metrics import MeshInputError, MetricsError
    from cerberus_metrics.scoring import VoxelIoUScorer

    scorer = VoxelIoUScorer()
    assert scorer.rejects == (MeshInputError,)
    closed, _ = _sphere_and_capless()
    with pytest.raises(scorer.rejects, match="pred.*degenerate mesh"):
        scorer([(np.zeros_like(closed[0]), closed[1])], closed)
    assert not issubclass(MemoryError, scorer.rejects) and not issubclass(RecursionError, scorer.rejects)
    assert issubclass(MeshInputError, MetricsError)
