"""Part quality on constructed cases with real capsule-figure meshes."""
from __future__ import annotations

import numpy as np
import pytest
import trimesh

from cerberus_core.errors import ConfigError
from cerberus_core.eval.part_quality import (
    PartQuality,
    assign_to_parts,
    image_overlap,
    merge_sides,
    overlap_matrix,
    side_free,
    surface_samples,
    vertex_areas,
)


def _parts(body):
    k = len(body.part_names)
    return body.vertices.reshape(k, -1, 3), body.faces[: len(body.faces) // k]


def _summary(bodies, predict, weighting="area"):
    acc = PartQuality(num_parts=len(bodies[0].part_names), gt_part_names=bodies[0].part_names)
    for body in bodies:
        pv, f = predict(body)
        acc.add(image_overlap(pv, f, body.vertices, body.faces, body.vertex_parts, len(body.part_names),
                              weighting=weighting), body.subject)
    return acc.summary()


@pytest.mark.parametrize("weighting", ["area", "count"])
def test_perfect_segmentation_scores_one(primitive_bodies, weighting):
    s = _summary(primitive_bodies, _parts, weighting)
    assert s["consistency"] == 1.0
    assert s["mean_entropy_bits"] == 0.0
    assert s["mean_segmentation_iou"] == pytest.approx(1.0)
    assert [p["label"] for p in s["parts"]] == primitive_bodies[0].part_names
    assert all(set(p["agreement_by_group"].values()) == {1.0} for p in s["parts"])


def test_permuted_parts_still_score_one_after_matching(primitive_bodies):
    perm = np.random.default_rng(0).permutation(len(primitive_bodies[0].part_names))

    def permuted(body):
        pv, f = _parts(body)
        return pv[perm], f

    s = _summary(primitive_bodies, permuted)
    names = primitive_bodies[0].part_names
    assert [p["label"] for p in s["parts"]] == [names[k] for k in perm]
    assert s["consistency"] == 1.0 and s["mean_segmentation_iou"] == pytest.approx(1.0)


def test_random_parts_score_low(primitive_bodies):
    rng = np.random.default_rng(1)
    sphere = trimesh.creation.icosphere(1)

    def random_blobs(body):
        centres = rng.uniform(-0.4, 0.4, size=(len(body.part_names), 1, 3))
        return np.asarray(sphere.vertices)[None] * 0.08 + centres, np.asarray(sphere.faces)

    s = _summary(primitive_bodies, random_blobs)
    assert s["mean_segmentation_iou"] < 0.35
    assert s["consistency"] < 0.6
    assert s["mean_entropy_bits"] > 0.5


def test_overlap_matrix_counts_and_weights():
    m = overlap_matrix(np.array([0, 0, 1, 2]), np.array([1, 1, 0, 1]), 3, 2, np.array([1.0, 2.0, 3.0, 4.0]))
    np.testing.assert_array_equal(m, [[0, 3], [3, 0], [0, 4]])
    with pytest.raises(ValueError, match="ground-truth labels"):
        overlap_matrix(np.array([0]), np.array([5]), 1, 2)


def test_assignment_matches_exact_nearest_surface():
    # Overlapping deformed icospheres (what a model predicts) and points near their surfaces.
    rng = np.random.default_rng(0)
    sphere = trimesh.creation.icosphere(2)
    f = np.asarray(sphere.faces)
    pv = np.asarray(sphere.vertices)[None] * rng.uniform(0.04, 0.15, (9, 1, 3)) + rng.uniform(-0.2, 0.2, (9, 1, 3))
    pts = pv.reshape(-1, 3)[rng.choice(pv.shape[0] * pv.shape[1], 1000)] + rng.normal(0, 0.02, (1000, 3))
    got = assign_to_parts(pts, pv, f, density=4)
    exact = np.stack([trimesh.proximity.closest_point_naive(trimesh.Trimesh(v, f, process=False), pts)[1]
                      for v in pv], axis=1)  # (N, P) exact distances
    slack = exact[np.arange(len(pts)), got] - exact.min(1)
    longest_edge = max(np.linalg.norm(v[f][:, [1, 2, 0]] - v[f], axis=-1).max() for v in pv)
    assert slack.max() <= longest_edge / (4 * np.sqrt(3))  # the documented error bound
    assert np.mean(got == exact.argmin(1)) > 0.98  # other choices only between almost equally near parts


def test_vertex_areas_sum_to_surface_area(primitive_bodies):
    body = primitive_bodies[0]
    mesh = trimesh.Trimesh(body.vertices, body.faces, process=False)
    assert vertex_areas(body.vertices, body.faces).sum() == pytest.approx(mesh.area, rel=1e-5)
    pts, part = surface_samples(*_parts(body), density=2)
    assert pts.shape[0] == part.shape[0] == len(body.faces) * 6


def test_summary_marks_unused_parts():
    acc = PartQuality(num_parts=3, gt_part_names=["a", "b"])
    acc.add(np.array([[2.0, 0.0], [0.0, 1.0], [0.0, 0.0]]), "s")
    s = acc.summary()
    assert s["unused_parts"] == [2] and s["parts"][2]["label"] is None
    with pytest.raises(ValueError, match=r"PartQuality.add: overlap must be \(3, 2\)"):
        acc.add(np.zeros((2, 2)))


def test_data_without_part_labels_says_so_instead_of_scoring_one(primitive_bodies, tmp_path):
    """A mesh folder without parts.npy has one ground-truth part ('body'): every learned part's
    majority is that part, so consistency and segmentation IoU used to come out 1.0 for any model."""
    from cerberus_core.bodies.folder import FolderSource
    from cerberus_core.eval.report import markdown_report

    for i, body in enumerate(primitive_bodies[:3]):  # real meshes, no part labels
        (tmp_path / "meshes" / "subject").mkdir(parents=True, exist_ok=True)
        trimesh.Trimesh(body.vertices, body.faces, process=False).export(tmp_path / "meshes" / "subject" / f"p{i}.ply")
    source = FolderSource(tmp_path / "meshes", test_fraction=0.0)
    bodies = source.bodies(source.subjects("train", None, 0)[0], [0, 1, 2])
    assert bodies[0].part_names == ["body"]
    rng = np.random.default_rng(1)
    sphere = trimesh.creation.icosphere(1)
    acc = PartQuality(num_parts=4, gt_part_names=bodies[0].part_names)
    for body in bodies:  # a nonsense prediction: four random blobs
        pv = np.asarray(sphere.vertices)[None] * 0.1 + rng.uniform(-0.4, 0.4, size=(4, 1, 3))
        acc.add(image_overlap(pv, np.asarray(sphere.faces), body.vertices, body.faces, body.vertex_parts, 1),
                body.subject)
    s = acc.summary()
    assert s["part_labels"] is False and "no part labels" in s["note"]
    assert s["consistency"] is None and s["mean_segmentation_iou"] is None and s["mean_entropy_bits"] is None
    assert s["parts"] == [] and s["segmentation_iou"] == {} and s["images"] == 3
    report = markdown_report({"protocol": "kato", "resolution": 32, "seconds": 0.0,
                              "standard": {"mean": 0.5, "count": 3, "per_group": {}}, "hard": None,
                              "canonical": {}, "part_quality": s, "part_visibility": None, "records": []})
    assert "Not scored: no part labels" in report and "Consistency" not in report
    labelled = _summary(primitive_bodies, _parts)  # with labels nothing changes
    assert labelled["part_labels"] is True and labelled["note"] is None and labelled["consistency"] == 1.0


def test_side_free_names_of_every_body_source():
    from cerberus_core.bodies.animal import ANIMAL_PART_NAMES
    from cerberus_core.bodies.human import PART_NAMES

    assert [side_free(n) for n in ("shin.L", "shin.R", "upper_arm.L", "head", "arm_r", "left_hand", "left")] == [
        "shin", "shin", "upper_arm", "head", "arm", "hand", "left"]
    merged, index = merge_sides(PART_NAMES)
    assert merged == ["head", "neck", "torso", "pelvis", "upper_arm", "lower_arm", "thigh", "shin"]
    assert [merged[i] for i in index] == [side_free(n) for n in PART_NAMES]
    assert merge_sides(ANIMAL_PART_NAMES)[0] == ["head", "neck", "torso", "tail", "front_leg", "back_leg"]
    assert merge_sides(["body"]) == (["body"], np.array([0]))


def test_merged_sides_score_a_model_that_follows_the_image_not_the_body(primitive_bodies):
    """A model whose left and right parts swap with the view (as a grey body seen from the front or the
    back allows) scores 0.5 per side and 1 with the sides merged."""
    names = primitive_bodies[0].part_names
    swap = np.array([names.index(n.replace(".L", ".X").replace(".R", ".L").replace(".X", ".R")) for n in names])

    def half_swapped(body):
        pv, f = _parts(body)
        return (pv[swap], f) if body.pose_id % 2 else (pv, f)

    bodies = [b for b in primitive_bodies if b.pose_id in (0, 1)]  # 2 subjects x (as is, swapped)
    s = _summary(bodies, half_swapped)
    sided = [p for p in s["parts"] if p["label"] != side_free(p["label"])]
    assert sided and all(p["agreement"] == 0.5 for p in sided)
    merged = s["sides_merged"]
    assert merged["gt_parts"] == ["head", "torso", "upper_arm", "lower_arm", "thigh", "shin"]
    assert merged["consistency"] == 1.0 and merged["mean_segmentation_iou"] == pytest.approx(1.0)
    assert [p["label"] for p in merged["parts"]] == [side_free(n) for n in names]
    assert merged["sides_merged"] is None
    acc = PartQuality(num_parts=2, gt_part_names=["a", "b"])
    acc.add(np.eye(2))
    assert acc.merged_sides() is None and acc.summary()["sides_merged"] is None


def test_adding_by_hand_needs_the_vocabulary():
    with pytest.raises(ConfigError, match=r"gt_part_names: PartQuality.add needs .*`PartQuality\(gt_part_names=\[...\], "
                                          r"num_parts=P\)`"):
        PartQuality().add(np.ones((2, 3)))
    acc = PartQuality(num_parts=2, gt_part_names=["a", "b", "c"])
    acc.add(np.ones((2, 3)))
    assert len(acc.overlaps) == 1
