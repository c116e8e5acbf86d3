"""Mesh input (cerberus_metrics.io): input forms, cleaning reports, bad input errors, open and
self-intersecting meshes."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest
import trimesh

from cerberus_metrics import (
    MeshInputError,
    MeshQualityWarning,
    inspect_mesh,
    load_parts,
    voxel_iou,
    voxelize,
)


def test_input_forms_agree(tmp_path, box):
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    ref = voxelize(box).occupancy
    for ext in ("obj", "ply", "stl", "off", "glb"):
        path = tmp_path / f"box.{ext}"
        box.export(path)
        assert np.array_equal(voxelize(str(path)).occupancy, ref), ext
        assert np.array_equal(voxelize(path).occupancy, ref), ext
    assert np.array_equal(voxelize((v, f)).occupancy, ref)
    assert np.array_equal(voxelize([v.tolist(), f.tolist()]).occupancy, ref)  # a 2-list of arrays is one mesh
    assert np.array_equal(voxelize({"vertices": v, "faces": f}).occupancy, ref)
    assert np.array_equal(voxelize(trimesh.Scene([box])).occupancy, ref)


def test_multi_mesh_glb_is_parts(tmp_path, helpers):
    a = helpers.box((-0.4, -0.4, -0.4), (0.0, 0.0, 0.0))
    b = helpers.box((0.1, 0.1, 0.1), (0.4, 0.4, 0.4))
    path = tmp_path / "scene.glb"
    trimesh.Scene([a, b]).export(path)
    parts = load_parts(str(path), "pred")
    assert len(parts) == 2
    assert voxel_iou(str(path), [a, b]) == 1.0


def test_cleaning_report(box):
    v, f = np.asarray(box.vertices), np.asarray(box.faces)
    # split vertices per face (as STL does), add a duplicate face, a zero-area face and an unused vertex
    tri = v[f].reshape(-1, 3)
    faces = np.arange(len(tri)).reshape(-1, 3)
    faces = np.vstack([faces, faces[:1], [[0, 1, 1]]])
    verts = np.vstack([tri, [[9.0, 9.0, 9.0]]])
    (rep,) = inspect_mesh((verts, faces), "pred")
    assert rep.faces == 12 and rep.vertices == 8 and rep.watertight
    assert rep.removed_duplicate_vertices == len(tri) - 8
    assert rep.removed_unreferenced_vertices == 1
    assert rep.removed_duplicate_faces + rep.removed_null_faces == 2
    assert rep.self_intersecting_faces == 0
    assert rep.volume == pytest.approx(0.55 * 0.5 * 0.3)
    assert voxel_iou((verts, faces), box) == 1.0


@pytest.mark.parametrize(
    "make,words",
    [
        (lambda v, f: (np.zeros((0, 3)), np.zeros((0, 3), int)), ["gt", "empty mesh"]),
        (lambda v, f: (np.where(np.arange(8)[:, None] == 3, np.nan, v), f), ["gt", "NaN", "vertex 3"]),
        (lambda v, f: (v, np.where(f == 7, 8, f)), ["gt", "vertex index 8", "0..7"]),
        (lambda v, f: (v, -np.ones_like(f)), ["gt", "vertex index -1"]),
        (lambda v, f: (v[:, :2], f), ["gt", "shape (V, 3)"]),
        (lambda v, f: (v, f[:, :2]), ["gt", "(F, 3)", "triangulate"]),
        (lambda v, f: (v + 2.0, f), ["gt", "outside the kato grid", "gt_bbox"]),
    ],
)
def test_bad_arrays_raise_clear_errors(box, make, words):
    v, f = make(np.asarray(box.vertices), np.asarray(box.faces))
    with pytest.raises(MeshInputError) as exc:
        voxel_iou(box, (v, f))
    for w in words:
        assert w in str(exc.value)


def test_inf_vertex_in_part_names_the_part(box, helpers):
    v = np.asarray(box.vertices).copy()
    v[2, 1] = np.inf
    with pytest.raises(MeshInputError, match=r"pred\[1\].*infinite"):
        voxel_iou([box, (v, box.faces)], box)


def test_part_outside_grid_names_the_part_file(tmp_path, box, helpers):
    far = tmp_path / "far.obj"
    helpers.box((0.3, 0.3, 0.3), (0.6, 0.6, 0.6)).export(far)
    with pytest.raises(MeshInputError, match=r"pred\[1\] \('.*far\.obj'\): mesh lies \(partly\) outside.*0\.5161"):
        voxel_iou([box, str(far)], box)


def test_bad_files_name_the_file(tmp_path, box):
    missing = tmp_path / "missing.obj"
    with pytest.raises(MeshInputError, match=r"pred.*missing\.obj.*does not exist"):
        voxel_iou(str(missing), box)
    garbage = tmp_path / "garbage.obj"
    garbage.write_text("v 1 2\nf 1 2 3\n")
    with pytest.raises(MeshInputError, match=r"gt.*garbage\.obj.*cannot read mesh file"):
        voxel_iou(box, str(garbage))
    points = tmp_path / "points.ply"
    trimesh.PointCloud(np.random.default_rng(0).random((10, 3)) - 0.5).export(points)
    with pytest.raises(MeshInputError, match=r"points\.ply.*empty mesh"):
        voxel_iou(str(points), box)
    with pytest.raises(MeshInputError, match="unknown protocol 'foo'.*kato"):
        voxel_iou(box, box, protocol="foo")
    with pytest.raises(MeshInputError, match="resolution"):
        voxel_iou(box, box, resolution=0)


def test_open_mesh_policies(box):
    open_box = trimesh.Trimesh(box.vertices, box.faces[1:], process=False)
    with pytest.warns(MeshQualityWarning, match=r"gt: mesh is not watertight \(3 boundary .*Treatment"):
        iou = voxel_iou(box, open_box)
    assert 0 < iou <= 1
    with pytest.raises(MeshInputError, match="not watertight.*open_mesh='error'"):
        voxel_iou(box, open_box, open_mesh="error")
    with pytest.warns(MeshQualityWarning, match="closed holes"):
        assert voxel_iou(box, open_box, open_mesh="close") == 1.0


def test_a_cleaned_mesh_passed_again_answers_to_open_mesh_error(box):
    """A Mesh load_parts cleaned (one with a report) is taken as it is, but open_mesh="error" still holds for it:
    before, one cleaned under "warn" and open was accepted under "error", where the same mesh from arrays raised.
    Now it raises the same OpenMeshError, naming the option that set the policy; a watertight one passes as it is."""
    from cerberus_metrics import OpenMeshError
    from cerberus_metrics.io import mesh_labels

    lidless = (np.asarray(box.vertices), np.asarray(box.faces)[2:])  # a cube without one side: 4 boundary edges
    (cleaned,) = load_parts(lidless, "gt", check_self_intersections=False, open_mesh="warn")
    assert not cleaned.report.watertight
    words = r"^gt: mesh is not watertight \(4 boundary \(open\) edges\) and {0}='error'; repair the mesh, or use {0}='warn'"
    for kwargs, option in (({}, "open_mesh"), ({"open_mesh_option": "gt_open_mesh"}, "gt_open_mesh")):
        with pytest.raises(OpenMeshError, match=words.format(option)) as fresh:
            load_parts(lidless, "gt", check_self_intersections=False, open_mesh="error", **kwargs)
        with pytest.raises(OpenMeshError, match=words.format(option)) as again:
            load_parts(cleaned, "gt", check_self_intersections=False, open_mesh="error", **kwargs)
        assert str(again.value) == str(fresh.value) and again.value.report is cleaned.report
        with pytest.raises(OpenMeshError, match=r"^gt: mesh is not watertight"):
            load_parts([cleaned], "pred", open_mesh="error", **kwargs)  # a taken-as-is part keeps its own name
    with pytest.raises(OpenMeshError, match="open_mesh='error'"):
        voxelize(cleaned, open_mesh="error")
    assert load_parts(cleaned, "gt", check_self_intersections=False, open_mesh="warn")[0] is cleaned  # as it is
    (closed,) = load_parts(cleaned, "gt", open_mesh="close")  # "close" still cleans it again, closing its holes
    assert closed.report.watertight and closed.report.holes_closed == 2
    assert mesh_labels(cleaned, "x", "error") == mesh_labels(cleaned, "x", "warn") == ("gt",)

    (whole,) = load_parts(box, "gt", open_mesh="error")  # cleaned once under "error": watertight
    for kwargs in ({}, {"open_mesh_option": "gt_open_mesh"}):
        (same,) = load_parts(whole, "pred", open_mesh="error", **kwargs)
        assert same is whole
    assert load_parts(closed, "gt", open_mesh="error")[0] is closed  # closed under "close": watertight too


def test_large_hole_leaks_and_is_reported(helpers):
    # A sphere with a cap removed: the kato fill enters through the hole, only surface voxels stay.
    s = trimesh.creation.icosphere(subdivisions=3, radius=0.4)
    keep = s.triangles_center[:, 2] < 0.3
    cut = trimesh.Trimesh(s.vertices, s.faces[keep], process=False)
    with pytest.warns(MeshQualityWarning, match="not watertight"):
        g = voxelize(cut)
    assert g.count < 0.5 * voxelize(s).count


def test_self_intersecting_mesh_warns_and_gives_union(helpers):
    a = helpers.box((-0.3, -0.3, -0.3), (0.1, 0.1, 0.1))
    b = helpers.box((-0.1, -0.1, -0.1), (0.3, 0.3, 0.3))
    merged = trimesh.util.concatenate([a, b])  # one mesh whose surfaces cross
    for protocol in ("kato", "gt_bbox_center"):
        with pytest.warns(MeshQualityWarning, match="self-intersecting.*union"):
            one = voxelize(merged, protocol=protocol)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            two = voxelize([a, b], protocol=protocol, frame=one.frame)  # parts: no warning
        assert np.array_equal(one.occupancy, two.occupancy)


def crossing_boxes(helpers, duplicate_face: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """(vertices, faces) of one closed mesh made of two boxes whose surfaces cross (self-intersecting, not
    star-shaped: pymeshlab's test answers it); duplicate_face: with its first face twice (one for cleaning)."""
    merged = trimesh.util.concatenate([helpers.box((-0.3, -0.3, -0.3), (0.1, 0.1, 0.1)),
                                       helpers.box((-0.1, -0.1, -0.1), (0.3, 0.3, 0.3))])
    f = np.asarray(merged.faces)
    return np.asarray(merged.vertices), np.concatenate([f, f[:1]]) if duplicate_face else f


def test_a_cleaned_mesh_not_tested_for_self_intersections_is_tested_when_asked(helpers):
    """Before: a Mesh cleaned with check_self_intersections=False was taken as it is when passed again with the test
    asked for (True or "pymeshlab"): its report still said "skipped" and the self-intersection warning a fresh load
    raises was missing. Now that test alone runs on it: the report says which answered, keeps what the first cleaning
    removed, and the warning is the fresh load's, naming the Mesh by its own name."""
    from dataclasses import replace

    from cerberus_metrics.io import mesh_labels

    v, f = crossing_boxes(helpers, duplicate_face=True)
    (cleaned,) = load_parts((v, f), "gt", check_self_intersections=False)
    assert cleaned.report.self_intersection_check == "skipped" and cleaned.report.removed_duplicate_faces == 1
    (fresh,) = load_parts((v, f), "gt")
    assert fresh.report.self_intersection_check == "pymeshlab" and fresh.report.self_intersecting_faces > 0
    for check in (True, "pymeshlab"):
        for policy in ("warn", "error"):  # closed: "error" takes it too
            (again,) = load_parts(cleaned, "pred", check_self_intersections=check, open_mesh=policy)
            assert again.report == fresh.report  # the count and the test of a fresh load, the first cleaning's counts
            assert again.name == "gt" and again.vertices is cleaned.vertices and again.faces is cleaned.faces
            assert replace(again.report, self_intersecting_faces=None, self_intersection_check="skipped") == \
                cleaned.report
        with pytest.warns(MeshQualityWarning) as caught:
            voxelize(cleaned, check_self_intersections=check)
        with pytest.warns(MeshQualityWarning) as expected:
            voxelize((v, f), name="gt", check_self_intersections=check)
        assert [str(w.message) for w in caught] == [str(w.message) for w in expected]
        assert str(caught[0].message).startswith(f"gt: mesh is self-intersecting ({fresh.report.self_intersecting_faces} faces)")
    assert cleaned.report.self_intersection_check == "skipped"  # the Mesh passed is not changed
    assert mesh_labels(cleaned, "x") == ("gt",)
    assert load_parts(cleaned, "gt", check_self_intersections=False)[0] is cleaned  # nothing asked: as it is


def test_a_cleaned_mesh_already_tested_is_taken_as_it_is(helpers):
    """A Mesh whose report answers the test asked for is returned as the same object (no second test): one tested by
    pymeshlab for either request, one certified star-shaped for True; "pymeshlab" (always pymeshlab's test) runs
    that test on a certified one, as a fresh load under "pymeshlab" does. A tested Mesh keeps its answer when the
    test is not asked for."""
    (tested,) = load_parts(crossing_boxes(helpers), "gt")
    assert tested.report.self_intersection_check == "pymeshlab"
    for check in (True, "pymeshlab", False):
        assert load_parts(tested, "gt", check_self_intersections=check)[0] is tested
    blob = helpers.blob(1)
    (certified,) = load_parts(blob, "gt")
    assert certified.report.self_intersection_check == "star-shaped certificate"
    assert load_parts(certified, "gt")[0] is certified
    assert load_parts(certified, "gt", check_self_intersections=False)[0] is certified
    (again,) = load_parts(certified, "gt", check_self_intersections="pymeshlab")
    (fresh,) = load_parts(blob, "gt", check_self_intersections="pymeshlab")
    assert again is not certified and again.report == fresh.report
    assert (again.report.self_intersection_check, again.report.self_intersecting_faces) == ("pymeshlab", 0)


def test_star_shaped_certificate_agrees_with_pymeshlab(helpers):
    from cerberus_metrics.io import star_shaped

    torus = trimesh.creation.torus(major_radius=0.3, minor_radius=0.1)
    a = helpers.box((-0.3, -0.3, -0.3), (0.1, 0.1, 0.1))
    b = helpers.box((-0.1, -0.1, -0.1), (0.3, 0.3, 0.3))
    crossing = trimesh.util.concatenate([a, b])
    cases = [(helpers.blob(s), True) for s in range(4)] + [(torus, False), (crossing, False)]
    for mesh, certified in cases:
        (auto,) = inspect_mesh(mesh)
        (full,) = inspect_mesh(mesh, check_self_intersections="pymeshlab")
        assert star_shaped(np.asarray(mesh.vertices), np.asarray(mesh.faces)) is certified
        assert auto.self_intersection_check == ("star-shaped certificate" if certified else "pymeshlab")
        assert full.self_intersection_check == "pymeshlab"
        assert auto.self_intersecting_faces == full.self_intersecting_faces
    flipped = helpers.blob(1)
    flipped.invert()
    assert star_shaped(np.asarray(flipped.vertices), np.asarray(flipped.faces))
    (skipped,) = inspect_mesh(helpers.blob(1), check_self_intersections=False)
    assert skipped.self_intersecting_faces is None and skipped.self_intersection_check == "skipped"


def test_a_face_count_beyond_the_bound_is_refused_before_any_copy():
    """Issue 34: a (V, 3) / (F, 3) pair with more than MAX_FACES faces is one MeshInputError (a broadcast view:
    nothing of that size is ever allocated)."""
    import numpy as np
    import pytest

    from cerberus_metrics import MeshInputError, load_parts
    from cerberus_metrics.filecheck import MAX_FACES

    vertices = np.eye(3)
    faces = np.broadcast_to(np.array([[0, 1, 2]]), (MAX_FACES + 1, 3))
    with pytest.raises(MeshInputError, match=f"{MAX_FACES + 1} faces: a mesh may have 0..{MAX_FACES}"):
        load_parts((vertices, faces), "pred")


def test_a_header_claiming_a_huge_face_count_is_refused(tmp_path):
    import pytest

    from cerberus_metrics import MeshInputError, load_parts

    (tmp_path / "huge.ply").write_text("ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
                                       "property float z\nelement face 1000000000000000000\n"
                                       "property list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n")
    with pytest.raises(MeshInputError, match="1000000000000000000 faces: a mesh may have"):
        load_parts(str(tmp_path / "huge.ply"), "gt")


def test_what_stands_where_a_mesh_file_should_be_is_named(tmp_path):
    """Issue 34 campaign: a FIFO, a device and a symlink loop were each said to "not exist"."""
    import os

    from cerberus_metrics.io import not_a_file

    os.mkfifo(tmp_path / "pipe.obj")
    (tmp_path / "loop.obj").symlink_to(tmp_path / "loop.obj")
    (tmp_path / "dangling.obj").symlink_to(tmp_path / "gone.obj")
    (tmp_path / "ok.obj").write_text("v 0 0 0\n")
    assert not_a_file(tmp_path / "pipe.obj") == "is not a regular file (a FIFO, device or socket)"
    assert not_a_file(Path("/dev/zero")) == "is not a regular file (a FIFO, device or socket)"
    assert not_a_file(tmp_path / "loop.obj") == "is a symlink loop"
    assert not_a_file(tmp_path / "dangling.obj") == "is a broken symlink"
    assert not_a_file(tmp_path / "nope.obj") == "does not exist" and not_a_file(tmp_path) == "is a directory"
    assert not_a_file(tmp_path / "ok.obj") is None
