"""Voxel IoU (cerberus_metrics.voxelize, through voxel_iou / voxelize / grid_iou): protocol geometry, union
semantics, agreement with independent solid tests, parts clamped into the kato grid, the grid-level API."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from cerberus_metrics import (
    Frame,
    MeshInputError,
    grid_iou,
    voxel_iou,
    voxelize,
)
from cerberus_metrics.protocols import PROTOCOLS
from cerberus_metrics.voxelize import center_occupancy, fill_exterior, kato_surface

#: Identity frame: lattice coordinates == mesh coordinates, grid [0, 16)^3, kato rule.
LATTICE16 = Frame(1.0, (0.0, 0.0, 0.0), 16, True)


def kato_box_count(lo_p, hi_p) -> int:
    """Kato rule on a box whose faces are off the lattice planes: every voxel the box touches."""
    return int(np.prod(np.floor(hi_p) - np.floor(lo_p) + 1))


@pytest.mark.parametrize("protocol", list(PROTOCOLS))
def test_mesh_against_itself_is_exactly_one(helpers, protocol):
    for mesh in (helpers.box((-0.3, -0.2, -0.1), (0.25, 0.3, 0.2)), helpers.blob(1)):
        assert voxel_iou(mesh, mesh, protocol=protocol) == 1.0
    parts = [helpers.blob(2, 0.15, (-0.1, 0, 0)), helpers.blob(3, 0.15, (0.12, 0.05, 0))]
    assert voxel_iou(parts, parts, protocol=protocol, resolution=48) == 1.0


@pytest.mark.parametrize(
    "lo,hi",
    [((-0.25, -0.2, -0.15), (0.25, 0.2, 0.15)), ((-0.41, 0.03, -0.33), (0.1, 0.37, 0.44)), ((-0.1,) * 3, (0.1,) * 3)],
)
def test_kato_box_marks_every_touched_voxel(helpers, lo, hi):
    # kato frame: p = 31 v + 16; the solid is every voxel the box touches (larger than its volume).
    g = voxelize(helpers.box(lo, hi))
    lo_p, hi_p = 31 * np.asarray(lo) + 16, 31 * np.asarray(hi) + 16
    assert g.occupancy.shape == (32, 32, 32)
    assert g.count == kato_box_count(lo_p, hi_p)
    assert g.count * g.frame.pitch**3 > np.prod(np.subtract(hi, lo))  # runs larger than the analytic volume


def test_kato_box_on_lattice_planes_follows_floor_rule(helpers):
    # Faces exactly on the planes 4 and 10: a face at height c marks index floor(c) = c (the upper face marks
    # voxel 10, outside [4, 10)), and the rays on the box's edge lines (4 and 10) mark the voxels on both sides.
    a, b = 4, 10
    g = voxelize(helpers.box((a,) * 3, (b,) * 3), frame=LATTICE16)
    idx = np.indices((16, 16, 16))
    in_block = ((idx >= a) & (idx <= b)).all(axis=0)
    slabs = np.zeros((16, 16, 16), bool)
    for ax in range(3):
        others = [i for i in range(3) if i != ax]
        on_plane = (idx[ax] == a) | (idx[ax] == b)
        slabs |= on_plane & ((idx[others] >= a - 1) & (idx[others] <= b)).all(axis=0)
    expected = in_block | slabs
    assert np.array_equal(g.occupancy, expected)
    assert g.count > (b - a) ** 3  # the analytic volume, in voxels


def test_sphere_volume_center_protocol_64(helpers):
    r = 1.0
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=r)
    g = voxelize(sphere, protocol="gt_bbox_center", resolution=64)
    analytic = 4 / 3 * math.pi * r**3
    assert abs(g.volume - analytic) / analytic < 0.03


def test_disjoint_shapes_give_zero(helpers):
    a = helpers.box((-0.45, -0.45, -0.45), (-0.1, -0.1, -0.1))
    b = helpers.box((0.1, 0.1, 0.1), (0.45, 0.45, 0.45))
    for protocol in PROTOCOLS:
        assert voxel_iou(a, b, protocol=protocol) == 0.0


def test_shift_by_one_voxel(helpers):
    # Box of 8 x 8 x 8 touched voxels (lattice faces at .3/.6 fractions), shifted by one voxel along x.
    lo, hi = np.array([3.3, 2.6, 5.3]), np.array([10.6, 9.3, 12.6])
    n = np.floor(hi) - np.floor(lo) + 1
    expected = (n[0] - 1) / (n[0] + 1)
    a = helpers.box(lo, hi)
    b = helpers.box(lo + [1, 0, 0], hi + [1, 0, 0])
    ga, gb = voxelize(a, frame=LATTICE16), voxelize(b, frame=LATTICE16)
    assert grid_iou(gb, ga) == pytest.approx(expected, abs=1e-12)
    # Same through the public kato frame: one voxel = 1/31 mesh units.
    shift = np.array([1.0, 0.0, 0.0])
    wa = helpers.box((lo - 16) / 31, (hi - 16) / 31)
    wb = helpers.box((lo + shift - 16) / 31, (hi + shift - 16) / 31)
    assert voxel_iou(wb, wa) == pytest.approx(expected, abs=1e-12)


def test_union_of_overlapping_parts(helpers):
    a = helpers.box((2.3, 2.3, 2.3), (8.6, 6.6, 7.6))
    b = helpers.box((5.3, 4.3, 3.3), (12.6, 11.6, 9.6))
    ga, gb = voxelize(a, frame=LATTICE16), voxelize(b, frame=LATTICE16)
    gu = voxelize([a, b], frame=LATTICE16)
    assert np.array_equal(gu.occupancy, ga.occupancy | gb.occupancy)
    ia, ib = np.floor(a.bounds).astype(int), np.floor(b.bounds).astype(int)
    inter = np.prod(np.clip(np.minimum(ia[1], ib[1]) - np.maximum(ia[0], ib[0]) + 1, 0, None))
    assert gu.count == np.prod(ia[1] - ia[0] + 1) + np.prod(ib[1] - ib[0] + 1) - inter
    # voxel_iou accepts parts as (vertices, faces) pairs too
    pairs = [(np.asarray(m.vertices), np.asarray(m.faces)) for m in (a, b)]
    assert np.array_equal(voxelize(pairs, frame=LATTICE16).occupancy, gu.occupancy)
    # center rule: overlapping closed parts give their union (non-zero winding)
    c = voxelize([a, b], protocol="gt_bbox_center", frame=Frame(1.0, (0, 0, 0), 16, False))
    ca = voxelize(a, protocol="gt_bbox_center", frame=c.frame)
    cb = voxelize(b, protocol="gt_bbox_center", frame=c.frame)
    assert grid_iou(c, ca) < 1 and np.array_equal(c.dense(), ca.dense() | cb.dense())


def _closed_meshes(helpers):
    rot = trimesh.transformations.rotation_matrix(0.7, [1, 2, 3])
    box = helpers.box((-0.3, -0.2, -0.25), (0.3, 0.2, 0.25))
    box.apply_transform(rot)
    torus = trimesh.creation.torus(major_radius=0.3, minor_radius=0.1, major_sections=16, minor_sections=8)
    return [helpers.blob(5), helpers.blob(6, 0.35), box, torus]


def _inside(helpers, mesh, centres, skip=None):
    """Winding-number inside test of (N, 3) points; points outside the mesh's bounding box are outside.

    skip: (N,) bool of points not to evaluate (reported as outside).
    """
    lo, hi = mesh.bounds
    todo = ((centres >= lo) & (centres <= hi)).all(axis=1)
    if skip is not None:
        todo &= ~skip
    inside = np.zeros(len(centres), bool)
    inside[todo] = np.abs(helpers.winding(centres[todo], mesh.vertices[mesh.faces])) > 0.5
    return inside


def test_kato_agrees_with_winding_number_up_to_surface_voxels(helpers):
    centres = (np.argwhere(np.ones((32,) * 3, bool)) + 0.5 - 16) / 31
    for mesh in _closed_meshes(helpers):
        g = voxelize(mesh)
        surf = voxelize(mesh, fill=False).occupancy
        # Off the surface voxels both must agree exactly; on them kato is solid by definition.
        inside = _inside(helpers, mesh, centres, skip=surf.ravel()).reshape((32,) * 3)
        off_surface = ~surf
        assert np.array_equal(g.occupancy[off_surface], inside[off_surface])
        assert surf.sum() > 0 and inside.sum() > 0


def test_center_rule_matches_winding_number(helpers):
    for mesh in _closed_meshes(helpers):
        g = voxelize(mesh, protocol="gt_bbox_center", resolution=20)
        centres = g.frame.to_mesh(np.argwhere(np.ones(g.occupancy.shape)) + g.origin + 0.5)
        assert np.array_equal(g.occupancy.ravel(), _inside(helpers, mesh, centres))


def test_vectorised_kato_surface_equals_literal_loops(helpers):
    rng = np.random.default_rng(0)
    meshes = [helpers.blob(s, 5.0, (8, 8, 8)) for s in range(3)]
    meshes.append(helpers.box((4, 4.5, 3), (11, 12, 9.25)))  # on-lattice faces and edges
    meshes.append(trimesh.Trimesh(rng.uniform(1, 15, (30, 3)), rng.integers(0, 30, (40, 3)), process=False))
    for m in meshes:
        tri = np.asarray(m.vertices)[np.asarray(m.faces)]
        assert np.array_equal(kato_surface(tri, np.zeros(3, int), (16, 16, 16)), helpers.kato_loops(tri, 16))


def test_fill_exterior_equals_bfs(helpers):
    rng = np.random.default_rng(1)
    for density in (0.2, 0.35, 0.5):
        surface = rng.random((14, 15, 16)) < density
        assert np.array_equal(fill_exterior(surface), helpers.bfs_fill(surface))
    # a hollow shell with a spiral corridor: needs many direction changes
    shell = np.ones((12, 12, 12), bool)
    shell[1:-1, 1:-1, 1:-1] = False
    shell[3:9, 3:9, 3:9] = True
    shell[4:8, 4:8, 4:8] = False
    assert np.array_equal(fill_exterior(shell), helpers.bfs_fill(shell))


def test_center_occupancy_of_box_counts_centres(helpers):
    m = helpers.box((2.3, 2.7, 3.1), (9.2, 6.4, 11.8))
    tri = np.asarray(m.vertices)[m.faces]
    occ = center_occupancy(tri, np.zeros(3, int), (16, 16, 16))
    # centres k + 0.5 inside [lo, hi]: k from ceil(lo - .5) to floor(hi - .5)
    n = np.floor(np.array([9.2, 6.4, 11.8]) - 0.5) - np.ceil(np.array([2.3, 2.7, 3.1]) - 0.5) + 1
    assert occ.sum() == np.prod(n)


def test_gt_bbox_grows_the_lattice_for_a_larger_prediction(helpers):
    gt = helpers.box((-0.5,) * 3, (0.5,) * 3)
    pred = helpers.box((-0.99,) * 3, (0.99,) * 3)  # about twice the GT: lattice [-14.69, 46.69]
    g = voxelize(gt, protocol="gt_bbox")
    p = voxelize(pred, protocol="gt_bbox", frame=g.frame)
    assert g.origin == (0, 0, 0) and g.occupancy.shape == (32, 32, 32)
    assert g.count == 32**3 and p.count == 62**3 and p.origin == (-16, -16, -16)
    assert voxel_iou(pred, gt, protocol="gt_bbox") == pytest.approx(32**3 / 62**3, abs=1e-15)


@pytest.mark.parametrize("resolution", [32, 64, 128])
def test_resolutions(helpers, resolution):
    a, b = helpers.blob(7), helpers.blob(8)
    iou = voxel_iou(a, b, protocol="gt_bbox", resolution=resolution)
    assert 0 < iou < 1
    g = voxelize(b, protocol="gt_bbox", resolution=resolution)
    assert g.occupancy.shape == (resolution,) * 3 and g.frame.resolution == resolution


def test_part_boxes_equal_whole_grid_voxelization(helpers):
    # voxelize() works per part in a small box (bounding voxels + 1 margin); the whole-grid rule must agree,
    # also for a part touching the grid border (faces at |v| = 0.5, lattice 0.5 and 31.5).
    parts = [helpers.blob(1, 0.2, (-0.2, 0, 0)), helpers.box((-0.5, -0.5, -0.5), (-0.2, 0.5, 0.1)), helpers.blob(2)]
    whole = np.zeros((32, 32, 32), bool)
    for m in parts:
        tri = 31 * np.asarray(m.vertices)[np.asarray(m.faces)] + 16
        whole |= fill_exterior(kato_surface(tri, np.zeros(3, int), (32, 32, 32)))
    assert np.array_equal(voxelize(parts).occupancy, whole)


DIRECTIONS = [(1, 0, 0), (0, -1, 0), (1, 1, 0), (-1, 0, -1), (1, 1, 1), (-1, -1, -1)]


@pytest.mark.parametrize("direction", DIRECTIONS, ids=["face+x", "face-y", "edge+x+y", "edge-x-z", "corner+", "corner-"])
def test_a_part_outside_the_kato_grid_is_clamped_by_one_rule_in_every_direction(helpers, direction):
    """A part straddling a face, an edge or a corner of the kato grid keeps exactly its voxels inside
    the grid (oracle: the part voxelized whole on a grown lattice of the same pitch, then cropped)."""
    d = np.asarray(direction, float)
    part = helpers.box(0.5 * d - 0.2, 0.5 * d + 0.2)  # half (or a quarter, an eighth) inside the grid
    clamped = voxelize(part, outside="clamp")
    grown = voxelize(part, frame=Frame(31.0, (16.0, 16.0, 16.0), 32, False))  # same map, grid may grow
    assert clamped.clamped == 1 and clamped.origin == (0, 0, 0) and clamped.occupancy.shape == (32,) * 3
    assert np.array_equal(clamped.occupancy, grown.dense())
    # The same box counted by hand: lattice extent [31 * (0.5 d - 0.2) + 16, ...], cut to [0, 32) per axis.
    lo_p, hi_p = 31 * (0.5 * d - 0.2) + 16, 31 * (0.5 * d + 0.2) + 16
    expected = np.prod(np.minimum(np.floor(hi_p), 31) - np.maximum(np.floor(lo_p), 0) + 1)
    assert clamped.count == expected
    with pytest.raises(Exception, match="outside the kato grid"):
        voxelize(part)  # the default stays the reference's strictness



def test_grid_level_api(box, helpers):
    from cerberus_metrics import grid_iou

    small = helpers.blob(4, radius=0.1)
    g = voxelize(box, protocol="gt_bbox", resolution=64)
    p = voxelize(small, protocol="gt_bbox", frame=g.frame)
    assert p.origin == (0, 0, 0) and p.occupancy.shape == (64, 64, 64)
    assert grid_iou(p, g) == voxel_iou(small, box, protocol="gt_bbox", resolution=64)
    assert grid_iou(p.dense(), g.dense()) == grid_iou(p, g)
    other = voxelize(box, protocol="gt_bbox", resolution=32)
    with pytest.raises(MeshInputError, match="different frames"):
        grid_iou(p, other)
    with pytest.raises(MeshInputError, match="both grids are empty"):
        grid_iou(np.zeros((4, 4, 4), bool), np.zeros((4, 4, 4), bool))
    centres = g.centers()
    assert centres.shape == (g.count, 3)
    assert (centres.min(axis=0) > box.bounds[0] - g.frame.pitch).all()



def test_grid_iou_refuses_a_float_grid():
    from cerberus_metrics import grid_iou
    from cerberus_metrics.io import MeshInputError

    occupied = np.zeros((4, 4, 4), bool)
    occupied[:2] = True
    assert grid_iou(occupied, occupied.astype(np.uint8)) == 1.0  # 0/1 integers are occupancy
    with pytest.raises(MeshInputError, match="float64 grid, not occupancy"):
        grid_iou(np.full((4, 4, 4), 0.5), occupied)


@pytest.mark.parametrize("option", [None, "gt_open_mesh"])
def test_quality_warnings_name_the_open_mesh_option_the_caller_set(option):
    """voxelize_parts names the option that set the parts' open-mesh policy (open_mesh_option, default
    "open_mesh"): a ground truth under the scorer's gt_open_mesh is not told to set open_mesh, which it has not."""
    from cerberus_metrics.io import MeshQualityWarning, load_parts
    from cerberus_metrics.protocols import get_protocol, make_frame
    from cerberus_metrics.voxelize import voxelize_parts

    box = trimesh.creation.box(extents=(0.5, 0.5, 0.5))
    lidless = (np.asarray(box.vertices), np.asarray(box.faces)[2:])  # a cube without one side: open
    kato = get_protocol("kato")
    frame = make_frame(kato, 32, np.asarray(box.vertices))
    name = option or "open_mesh"
    kwargs = {} if option is None else {"open_mesh_option": option}
    for policy, words in (("close", f"closed holes with pymeshlab ({name}='close'), adding 2 faces"),
                          ("warn", f"Use {name}='close' to fill holes with pymeshlab, or {name}='error' to reject")):
        parts = load_parts(lidless, "gt", check_self_intersections=False, open_mesh=policy)
        with pytest.warns(MeshQualityWarning) as caught:
            voxelize_parts(parts, kato, frame, **kwargs)
        assert [words in str(w.message) for w in caught] == [True], [str(w.message) for w in caught]
