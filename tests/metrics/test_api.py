"""The metric functions as entry points (cerberus_metrics.api through ``cerberus.metrics``)."""
from __future__ import annotations

import warnings
from importlib.metadata import entry_points

import numpy as np
import pytest
import trimesh


def test_entry_points_discover_metrics(helpers):
    eps = {ep.name: ep for ep in entry_points(group="cerberus.metrics")}
    assert {"voxel_iou", "chamfer_l2", "fscore"} <= set(eps)
    voxel = eps["voxel_iou"].load()
    a = helpers.box((-0.3, -0.3, -0.3), (0.1, 0.1, 0.1))
    parts = [(np.asarray(a.vertices), np.asarray(a.faces)), trimesh.creation.icosphere(radius=0.1)]
    iou = voxel(parts, a, protocol="kato", resolution=32)
    assert isinstance(iou, float) and 0 < iou <= 1
    assert isinstance(eps["fscore"].load()(a, a, n_samples=1000), float)


def _cube_lidless_big():
    """A closed cube of side 0.5 (mesh units), the same cube without one side (two triangles: open, 4 boundary
    edges) and the cube scaled by 2.2 (side 1.1, past the kato grid [-16/31, 16/31]^3 on every side)."""
    box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    return (v, f), (v, f[2:]), (v * 2.2, f)


def test_the_scorer_voxelizes_through_prediction_grids_with_its_options():
    """Before: VoxelIoUScorer voxelized its own way (prediction_grids took no ground-truth options of its own).
    Now prediction_grids with the scorer's options (ground truth: its own open-mesh policy, no self-intersection
    test; prediction: quiet, clamped) gives exactly the scorer's grids, part by part."""
    from cerberus_metrics import MeshQualityWarning, grid_iou
    from cerberus_metrics.api import prediction_grids
    from cerberus_metrics.scoring import VoxelIoUScorer

    cube, lidless, big = _cube_lidless_big()
    pred = [lidless, big]  # an open part (quiet) and a part clamped into the grid
    with pytest.warns(MeshQualityWarning, match=r"gt: closed holes with pymeshlab \(gt_open_mesh='close'\)"):
        scored = VoxelIoUScorer(gt_open_mesh="close").grids(pred, lidless)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        parts, gt = prediction_grids(pred, lidless, "kato", 32, None, "clamp", False, "warn", gt_open_mesh="close",
                                     gt_check_self_intersections=False, quiet_pred=True)
    closed = "gt: closed holes with pymeshlab (gt_open_mesh='close'), adding 2 faces"
    assert [str(w.message) for w in caught] == [closed]
    assert parts.origin == gt.origin == scored.origin == (0, 0, 0) and parts.frame == gt.frame == scored.frame
    assert np.array_equal(parts.occupancy, scored.parts) and np.array_equal(gt.occupancy, scored.gt)
    assert (grid_iou(parts.union(), gt), parts.clamped) == (scored.iou, scored.clamped) == (0.125, 1)
    # the ground truth's own policy matters: under the prediction's ("warn") it is the hollow shell the fill leaves
    with pytest.warns(MeshQualityWarning, match="gt: mesh is not watertight"):
        _, shell = prediction_grids(pred, lidless, "kato", 32, None, "clamp", False, "warn", quiet_pred=True)
    assert shell.count < gt.count == 4096


def test_prediction_grids_ground_truth_options_name_themselves():
    """An open ground truth refused by gt_open_mesh='error' raises the OpenMeshError that names gt_open_mesh (the
    scorer's), under open_mesh='error' the one that names open_mesh, as before; an unknown policy is an input
    error naming gt_open_mesh; without quiet_pred the prediction's warnings are issued and name open_mesh."""
    from cerberus_metrics import MeshInputError, MeshQualityWarning, OpenMeshError
    from cerberus_metrics.api import prediction_grids

    cube, lidless, _ = _cube_lidless_big()
    with pytest.raises(OpenMeshError, match=r"gt: the ground truth is not watertight \(4 boundary .* hollow shell "
                       r".* gt_open_mesh='close'"):
        prediction_grids([cube], lidless, "kato", 32, None, "clamp", gt_open_mesh="error")
    with pytest.raises(OpenMeshError, match="gt: mesh is not watertight .* and open_mesh='error'"):
        prediction_grids([cube], lidless, "kato", 32, None, "clamp", open_mesh="error")
    with pytest.raises(MeshInputError, match="gt_open_mesh must be one of"):
        prediction_grids([cube], cube, "kato", 32, None, "clamp", gt_open_mesh="ignore")
    with pytest.warns(MeshQualityWarning, match="pred: mesh is not watertight .* Use open_mesh='close'"):
        prediction_grids([lidless], cube, "kato", 32, None, "clamp", gt_open_mesh="error")


def test_cache_keys_of_existing_caches_stay_and_a_shared_cache_replays_the_right_option():
    """The default options key ground truths as before (existing caches stay valid: voxel_iou's, and the scorer's
    with gt_open_mesh='error'); a ground truth whose cached warnings name gt_open_mesh gets a key of its own, so a
    cache shared with voxel_iou replays to each the option its caller set."""
    from cerberus_metrics import GridCache, MeshQualityWarning, voxel_iou
    from cerberus_metrics.io import content_digest
    from cerberus_metrics.scoring import VoxelIoUScorer

    cube, lidless, _ = _cube_lidless_big()
    cache = GridCache()
    voxel_iou(cube, cube, cache=cache)
    VoxelIoUScorer(cache=cache)([cube], cube)
    old = dict(protocol="kato", resolution=32, frame=None, fill=True)  # _grid's key fields before gt_open_mesh
    digest = content_digest(cube)
    assert set(cache._mem) == {GridCache.make_key(digest, **old, self_intersections=True, open_mesh="warn"),
                               GridCache.make_key(digest, **old, self_intersections=False, open_mesh="error")}
    scorer = VoxelIoUScorer(cache=cache, gt_open_mesh="close")
    for _ in range(2):  # voxelized, then replayed from the cache
        with pytest.warns(MeshQualityWarning, match=r"\(gt_open_mesh='close'\)"):
            scorer([cube], lidless)
        with pytest.warns(MeshQualityWarning, match=r"\(open_mesh='close'\)"):
            voxel_iou(cube, lidless, cache=cache, open_mesh="close", check_self_intersections=False)
    assert (cache.misses, cache.hits) == (4, 2)
