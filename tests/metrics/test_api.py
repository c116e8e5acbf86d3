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


def _open_with_a_fin():
    """The lidless cube of :func:`_cube_lidless_big` with a fin: a triangle on one of its edges to the cube's centre,
    so the mesh is open (boundary edges) and non-manifold (an edge of three faces), which pymeshlab cannot close."""
    box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    return np.vstack([v, [[0.0, 0.0, 0.0]]]), np.vstack([f[2:], [[2, 3, 8]]])  # vertices 2, 3: an edge of f[2:]


def test_every_open_mesh_message_names_the_option_that_set_the_policy():
    """Before: under gt_open_mesh the loader's own messages still said open_mesh (``gt: open_mesh='close' cannot
    close holes of a non-manifold mesh ...; repair it, or use open_mesh='warn'``), an option the scorer has not and
    the caller did not set. Now the option's name is passed down to the loader (load_parts' open_mesh_option), so
    its errors name gt_open_mesh for a ground truth under its own policy, and open_mesh, as before, otherwise."""
    import re

    from cerberus_metrics import MeshInputError, OpenMeshError
    from cerberus_metrics.api import prediction_grids
    from cerberus_metrics.io import load_parts
    from cerberus_metrics.scoring import VoxelIoUScorer

    cube, lidless, _ = _cube_lidless_big()
    fin = _open_with_a_fin()
    said = []
    for run in (lambda: prediction_grids([cube], fin, "kato", 32, None, "clamp", gt_open_mesh="close"),
                lambda: VoxelIoUScorer(gt_open_mesh="close")([cube], fin)):
        with pytest.raises(MeshInputError, match=r"^gt: gt_open_mesh='close' cannot close holes of a non-manifold "
                                                 r"mesh \(\d+ non-manifold edges\); repair it, or use "
                                                 r"gt_open_mesh='warn'$") as exc:
            run()
        said.append(str(exc.value))
    with pytest.raises(OpenMeshError, match=r"^gt: mesh is not watertight \(4 boundary \(open\) edges\) and "
                                            r"gt_open_mesh='error'; repair the mesh, or use gt_open_mesh='warn'") as exc:
        load_parts(lidless, "gt", open_mesh="error", open_mesh_option="gt_open_mesh")
    said.append(str(exc.value))
    with pytest.raises(MeshInputError, match="^gt_open_mesh must be one of") as exc:
        load_parts(lidless, "gt", open_mesh="ignore", open_mesh_option="gt_open_mesh")
    said.append(str(exc.value))
    assert not [s for s in said if re.search(r"(?<!gt_)open_mesh=", s)], said
    # the prediction's own option, and the ground truth's when it follows the prediction's: open_mesh, as before
    with pytest.raises(MeshInputError, match=r"^gt: open_mesh='close' cannot close holes .* use open_mesh='warn'$"):
        prediction_grids([cube], fin, "kato", 32, None, "clamp", open_mesh="close")
    with pytest.raises(MeshInputError, match=r"^pred: open_mesh='close' cannot close holes"):
        prediction_grids([fin], cube, "kato", 32, None, "clamp", open_mesh="close", gt_open_mesh="error")


def test_quality_warnings_name_the_ground_truth_file(tmp_path):
    """A set of open scans under gt_open_mesh='warn': each warning names its scan by its file's path, one line per
    mesh, also when the scorer's cache holds a grid of the same bytes voxelized from another file (before: the hit
    replayed the warning recorded for the first file, naming a scan that was not the one scored)."""
    from cerberus_metrics import MeshQualityWarning
    from cerberus_metrics.scoring import VoxelIoUScorer

    cube, lidless, _ = _cube_lidless_big()
    scans = tmp_path / "scans"
    scans.mkdir()
    paths = [scans / "a.ply", scans / "b.ply"]
    for p in paths:
        trimesh.Trimesh(*lidless, process=False).export(p)
    assert paths[0].read_bytes() == paths[1].read_bytes()  # the same content: one cache key
    scorer = VoxelIoUScorer(gt_open_mesh="warn")

    def said(gt):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            scorer([cube], gt)
        return [str(w.message) for w in caught if issubclass(w.category, MeshQualityWarning)]

    for path in (*paths, paths[1]):  # a, b (the same bytes), b again (replayed from the cache)
        texts = said(str(path))
        assert len(texts) == 1 and "\n" not in texts[0], texts
        assert texts[0].startswith(f"gt ('{path}'): mesh is not watertight (4 boundary (open) edges)."), texts
    assert (scorer.cache.misses, scorer.cache.hits) == (2, 1)
    # in memory, without a path: the role, and the index among several ground-truth parts
    assert [t.split(":")[0] for t in said([lidless, lidless])] == ["gt[0]", "gt[1]"]
