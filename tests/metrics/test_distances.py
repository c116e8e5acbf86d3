"""Chamfer-L2 and F-score on sampled surfaces (distances by pymeshlab)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from cerberus_metrics import chamfer_l2, evaluate_pair, fscore
from cerberus_metrics.distances import nearest_distances


def sphere(r, subdivisions=4):
    return trimesh.creation.icosphere(subdivisions=subdivisions, radius=r)


def test_nearest_distances_match_brute_force():
    rng = np.random.default_rng(0)
    a, b = rng.random((300, 3)), rng.random((500, 3)) + 0.2
    brute = np.sqrt(((a[:, None] - b[None]) ** 2).sum(-1)).min(axis=1)
    assert np.allclose(np.sort(nearest_distances(a, b)), np.sort(brute), rtol=0, atol=1e-12)


def test_concentric_spheres():
    inner, outer = sphere(0.30), sphere(0.35)
    cd = chamfer_l2(inner, outer, n_samples=20_000)
    assert cd == pytest.approx(2 * 0.05**2, rel=0.1)
    assert fscore(inner, outer, threshold=0.01, n_samples=20_000) == 0.0
    assert fscore(inner, outer, threshold=0.06, n_samples=20_000) == 1.0


def test_same_shape_and_seeds():
    s = sphere(0.3)
    # independent uniform samplings: E[d^2] to the nearest of n points on area A is A / (pi n) (Poisson)
    assert chamfer_l2(s, s, n_samples=20_000) == pytest.approx(2 * s.area / (np.pi * 20_000), rel=0.15)
    assert fscore(s, s, threshold=0.01, n_samples=20_000) > 0.99
    a = chamfer_l2(s, sphere(0.32), n_samples=5_000, seed=3)
    assert a == chamfer_l2(s, sphere(0.32), n_samples=5_000, seed=3)
    assert a != chamfer_l2(s, sphere(0.32), n_samples=5_000, seed=4)


def test_normalize_makes_metrics_scale_free():
    a, b = sphere(0.3), sphere(0.33)
    big_a, big_b = a.copy(), b.copy()
    big_a.apply_scale(10)
    big_b.apply_scale(10)
    kw = dict(n_samples=5_000, normalize=True)
    assert chamfer_l2(a, b, **kw) == pytest.approx(chamfer_l2(big_a, big_b, **kw), rel=1e-9)
    assert fscore(a, b, threshold=0.05, **kw) == fscore(big_a, big_b, threshold=0.05, **kw)


def test_evaluate_pair_parts_and_precision_recall(helpers):
    gt = sphere(0.3)
    parts = [sphere(0.3), helpers.box((0.5, 0.5, 0.5), (0.6, 0.6, 0.6))]  # an extra part far away
    r = evaluate_pair(parts, gt, ["voxel_iou", "chamfer_l2", "fscore"], n_samples=10_000, threshold=0.02,
                      protocol="gt_bbox")
    assert r["recall"] > 0.99 and r["precision"] < 0.99
    assert set(r) == {"voxel_iou", "clamped_parts", "chamfer_l2", "fscore", "precision", "recall"}
    assert r["clamped_parts"] == 0  # the gt_bbox grid spans both meshes: nothing to clamp


@pytest.mark.parametrize("n", [0, -1, 10_000_001, 10**12, 2.5, True])
def test_sample_counts_are_bounded_before_the_meshes_are_read(n):
    """Issue 34: ``n_samples`` outside [1, MAX_SAMPLES] is a MeshInputError, not an allocation (the paths
    do not even exist: the count is checked first)."""
    from cerberus_metrics import MeshInputError
    from cerberus_metrics.distances import MAX_SAMPLES

    assert MAX_SAMPLES == 10_000_000
    with pytest.raises(MeshInputError, match=r"n_samples must be an integer in \[1, 10000000\]"):
        chamfer_l2("missing_pred.obj", "missing_gt.obj", n_samples=n)


def test_surface_buried_inside_another_part_counts_against_precision(helpers):
    """The documented behaviour (distances.sample_surface, docs/metrics.md "Parts that overlap"): every part's
    whole surface is sampled, also where it lies inside another part. Two boxes overlapping in [-0.1, 0.1] along x
    make exactly the ground-truth box (voxel IoU 1), but their two faces buried in the overlap (1/6 of the
    prediction's area) lie up to 0.2 from the ground truth's surface: at a threshold of 0.02, precision about
    1 - 1/6 * (0.36/0.4)^2 = 0.865 (the share of the buried faces farther than 0.02 from their edges)."""
    gt = helpers.box((-0.3, -0.2, -0.2), (0.3, 0.2, 0.2))
    parts = [helpers.box((-0.3, -0.2, -0.2), (0.1, 0.2, 0.2)), helpers.box((-0.1, -0.2, -0.2), (0.3, 0.2, 0.2))]
    r = evaluate_pair(parts, gt, ["voxel_iou", "fscore"], n_samples=20_000, threshold=0.02)
    assert r["voxel_iou"] == 1.0 and r["recall"] > 0.99
    assert r["precision"] == pytest.approx(1 - (0.36 / 0.4) ** 2 / 6, abs=0.015)
