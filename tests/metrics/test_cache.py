"""The grid cache (cerberus_metrics.cache): hits skip work, replay warnings, and survive the process."""
from __future__ import annotations

import pytest
import trimesh

from cerberus_metrics import (
    GridCache,
    MeshQualityWarning,
    voxel_iou,
)


def test_cache_hits_skip_work_and_replay_warnings(tmp_path, box, helpers):
    cache = GridCache(tmp_path / "grids")
    gt = tmp_path / "gt.ply"
    box.export(gt)
    pred = helpers.blob(3)
    first = voxel_iou(pred, str(gt), cache=cache)
    assert (cache.hits, cache.misses) == (0, 1)
    assert voxel_iou(pred, str(gt), cache=cache) == first
    assert cache.hits == 1
    fresh = GridCache(tmp_path / "grids")  # another process: read from disk
    assert voxel_iou(pred, str(gt), cache=fresh) == first and fresh.hits == 1
    voxel_iou(pred, str(gt), protocol="gt_bbox", cache=fresh)
    assert fresh.misses == 1  # another protocol is another key
    open_box = trimesh.Trimesh(box.vertices, box.faces[1:], process=False)
    mem = GridCache()
    with pytest.warns(MeshQualityWarning):
        voxel_iou(box, open_box, cache=mem)
    with pytest.warns(MeshQualityWarning, match="not watertight"):
        voxel_iou(box, open_box, cache=mem)
    assert mem.hits == 1


def test_a_damaged_cache_entry_is_a_miss_recomputed(tmp_path, box, helpers):
    """Issue 34 campaign: a cache file overwritten with junk failed every pair that hit it (numpy's 'pickled data'
    ValueError); it is a miss, and the grid is recomputed and rewritten."""
    cache = GridCache(tmp_path / "grids")
    pred = helpers.blob(3)
    first = voxel_iou(pred, box, cache=cache)
    entries = list((tmp_path / "grids").glob("*.npz"))
    assert entries
    for entry in entries:
        entry.write_text("junk")
    fresh = GridCache(tmp_path / "grids")
    assert voxel_iou(pred, box, cache=fresh) == first and fresh.misses >= 1


def test_a_failed_write_leaves_no_temporary_file(tmp_path, box):
    """Before: the cache wrote `<key>.<pid>.tmp.npz` and renamed it, with no clean-up, so an error (here the
    target name taken by a folder) left the temporary file behind; now the package's one atomic writer removes
    it (and syncs the file before the rename)."""
    from cerberus_metrics import voxelize
    from cerberus_metrics.cache import CachedGrid

    folder = tmp_path / "grids"
    cache = GridCache(folder)
    grid = voxelize(box)
    (folder / "k.npz").mkdir()  # the entry's name is taken: os.replace fails
    with pytest.raises(OSError):
        cache.put("k", CachedGrid(grid, ()))
    assert sorted(p.name for p in folder.iterdir()) == ["k.npz"]
    cache.put("j", CachedGrid(grid, ("a note",)))  # a good write: the entry alone, readable by another process
    assert sorted(p.name for p in folder.iterdir()) == ["j.npz", "k.npz"]
    again = GridCache(folder).get("j")
    assert again is not None and again.messages == ("a note",) and again.grid.count == grid.count


def test_a_hit_replays_warnings_only_for_the_file_they_name(tmp_path, box):
    """The key is the content, the warnings name the file: a scan moved (or copied) after its grid was cached is
    voxelized again, so its warning names where it is now rather than where it was; a grid cached before its
    warnings' names were recorded (``labels`` None) still replays them."""
    from cerberus_metrics.cache import CachedGrid

    open_box = trimesh.Trimesh(box.vertices, box.faces[1:], process=False)
    old, new = tmp_path / "old.ply", tmp_path / "new.ply"
    open_box.export(old)
    with pytest.warns(MeshQualityWarning, match=r"^gt \('.*old\.ply'\): mesh is not watertight"):
        voxel_iou(box, str(old), cache=GridCache(tmp_path / "grids"))
    old.rename(new)
    fresh = GridCache(tmp_path / "grids")  # another process, reading the grid of the same bytes from disk
    with pytest.warns(MeshQualityWarning, match=r"^gt \('.*new\.ply'\): mesh is not watertight") as caught:
        voxel_iou(box, str(new), cache=fresh)
    assert not [w for w in caught if "old.ply" in str(w.message)] and (fresh.misses, fresh.hits) == (1, 0)
    with pytest.warns(MeshQualityWarning, match=r"new\.ply"):
        voxel_iou(box, str(new), cache=GridCache(tmp_path / "grids"))  # rewritten under its new name: a hit
    cache = GridCache(tmp_path / "unlabelled")
    cache.put("k", CachedGrid(fresh.get(next(iter(fresh._mem))).grid, ("an old note",)))
    hit = GridCache(tmp_path / "unlabelled").get("k", ("gt ('elsewhere.ply')",))
    assert hit is not None and hit.labels is None and hit.messages == ("an old note",)


def test_a_cleaned_mesh_not_tested_for_self_intersections_caches_the_fresh_warning(helpers):
    """Before: voxelize(mesh, cache=c) of a Mesh cleaned with check_self_intersections=False stored a grid without
    the self-intersection warning under the key of the test asked for, and a later voxelize((v, f), cache=c) of the
    same content hit it and skipped the warning a fresh load gives. Now the Mesh is tested, so both warn."""
    from cerberus_metrics import load_parts, voxelize

    merged = trimesh.util.concatenate([helpers.box((-0.3, -0.3, -0.3), (0.1, 0.1, 0.1)),
                                       helpers.box((-0.1, -0.1, -0.1), (0.3, 0.3, 0.3))])
    (cleaned,) = load_parts(merged, check_self_intersections=False)  # named "mesh", as voxelize names a pair
    words = r"^mesh: mesh is self-intersecting \(\d+ faces\)"
    for check in (True, "pymeshlab"):
        cache = GridCache()
        with pytest.warns(MeshQualityWarning, match=words):
            first = voxelize(cleaned, cache=cache, check_self_intersections=check)
        with pytest.warns(MeshQualityWarning, match=words):
            second = voxelize((cleaned.vertices, cleaned.faces), cache=cache, check_self_intersections=check)
        assert (cache.misses, cache.hits) == (1, 1) and second is first
