"""Allocation diagnostics: each on a hand-built case whose answer is known, then the accumulator."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from cerberus_core.errors import ConfigError
from cerberus_core.eval.allocation import (
    Allocation,
    ImageAllocation,
    allocation_line,
    keypoint_spread,
    keypoints,
    nearest_keypoint_distances,
    part_masks,
    segment_centroids,
    silhouette_centroids,
    unique_coverage,
)
from cerberus_core.model import Cerberus
from cerberus_core.model.cerberus import ModelConfig
from cerberus_core.parts import PartSet
from cerberus_core.render.camera import Camera
from cerberus_core.render.templates import icosphere


def spheres(centres, radius: float = 0.12) -> PartSet:
    """One image of spheres at ``centres`` (world), identity rotations."""
    sphere = icosphere(2)
    p = len(centres)
    return PartSet((radius * sphere.vertices).expand(1, p, -1, -1).clone(), sphere.faces,
                   torch.eye(3).expand(1, p, 3, 3).clone(), torch.tensor([centres], dtype=torch.float32))


def test_keypoint_spread_is_the_rms_of_the_axes_std_around_the_centroid():
    # Part 0 moves with the centroid (spread 0); part 1 is at +-3 px in u and +-4 px in v around it.
    centroid = np.array([[10.0, 20.0], [30.0, 5.0], [12.0, 12.0], [40.0, 40.0]])
    offsets = np.array([[3.0, 4.0], [-3.0, -4.0], [3.0, -4.0], [-3.0, 4.0]])
    points = np.stack([centroid + [1.0, 2.0], centroid + offsets], axis=1)  # (N, 2, 2)
    spread = keypoint_spread(points, centroid)
    assert spread[0] == pytest.approx(0.0, abs=1e-12)
    assert spread[1] == pytest.approx(np.sqrt((3.0 ** 2 + 4.0 ** 2) / 2))


def test_silhouette_centroid_is_the_mean_pixel_centre():
    mask = torch.zeros(2, 8, 6, dtype=torch.bool)
    mask[0, 2:4, 1:5] = True  # rows 2-3, columns 1-4
    mask[1, 7, 5] = True
    assert silhouette_centroids(mask).tolist() == [[3.0, 3.0], [5.5, 7.5]]


def test_nearest_keypoint_distance_takes_the_closest_part():
    centroids = np.array([[[0.0, 0.0], [10.0, 10.0]]])  # (1 image, 2 segments)
    points = np.array([[[3.0, 4.0], [10.0, 12.0], [50.0, 50.0]]])  # 3 keypoints
    assert nearest_keypoint_distances(centroids, points).tolist() == [[5.0, 2.0]]


def test_unique_coverage_counts_foreground_pixels_only_one_part_holds():
    masks = torch.zeros(1, 3, 2, 4, dtype=torch.bool)
    masks[0, 0, :, 0:2] = True  # part 0: columns 0-1
    masks[0, 1, :, 1:3] = True  # part 1: columns 1-2 (column 1 shared with part 0)
    masks[0, 2, :, 1] = True  # part 2: only the shared column: adds nothing alone
    fg = torch.ones(1, 2, 4, dtype=torch.bool)
    fg[0, 1, 0] = False  # one of part 0's own pixels is background
    share = unique_coverage(masks, fg)[0].tolist()
    assert share == pytest.approx([1 / 7, 2 / 7, 0.0])


def test_keypoints_project_the_translations_and_segment_centroids_project_the_vertex_mean(renderer):
    camera = Camera.look_at(0.0, 0.0, 2.5, fov_y_deg=30.0, image_size=64)
    recon = spheres([[0.0, 0.0, 0.0], [0.3, 0.2, 0.0]])
    uv = keypoints(recon, camera)
    assert uv[0, 0].tolist() == pytest.approx([32.0, 32.0], abs=1e-4)
    assert uv[0, 1, 0] > 32 and uv[0, 1, 1] < 32  # right of centre and up (v grows downwards)
    # a segment of two vertices whose mean is the second sphere's centre lands on its keypoint
    vertices = torch.tensor([[[0.3, 0.1, 0.0], [0.3, 0.3, 0.0], [0.0, 0.0, 0.0]]])
    centres = segment_centroids(vertices, torch.tensor([1, 1, 0]), 2, camera)
    assert torch.allclose(centres[0], uv[0], atol=1e-4)
    # each part alone: two disjoint spheres, each mask is exactly its own silhouette
    masks = part_masks(renderer, recon, camera)
    assert masks.shape == (1, 2, 64, 64) and not (masks[:, 0] & masks[:, 1]).any()
    assert masks[0, 0, 32, 32] and masks[0, 1, int(uv[0, 1, 1]), int(uv[0, 1, 0])]


def test_a_cerberus_keypoint_is_its_expected_pixel_coordinate():
    """What :func:`keypoints` reads back is ``Predictions.maps.uv``, the model's own keypoint."""
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(width=8, shape_latent_dim=16, num_parts=3, depth_offset=2.5)).eval()
    images = torch.rand(2, 3, 64, 64)
    camera = Camera.look_at([0.0, 90.0], 10.0, 2.5, fov_y_deg=30.0, image_size=64)
    with torch.no_grad():
        pred = model(images)
        uv = keypoints(model.pose(pred, camera), camera)
    assert torch.allclose(uv, pred.maps.uv, atol=1e-3)


def test_accumulator_summary_and_line():
    acc = Allocation(segments=["head", "shin"], num_parts=2)
    centroid = np.array([[32.0, 32.0], [30.0, 34.0]])
    acc.add(ImageAllocation(keypoints=np.array([[[32.0, 20.0], [32.0, 50.0]]]), centroid=centroid[:1],
                            segments=np.array([[[32.0, 18.0], [32.0, 56.0]]]), unique=np.array([[0.3, 0.01]])))
    acc.add(ImageAllocation(keypoints=np.array([[[30.0, 22.0], [34.0, 50.0]]]), centroid=centroid[1:],
                            segments=np.array([[[30.0, 20.0], [34.0, 60.0]]]), unique=np.array([[0.5, 0.03]])))
    s = acc.summary()
    assert s["images"] == 2
    assert s["segment_to_keypoint"] == {"head": pytest.approx(2.0), "shin": pytest.approx(8.0)}  # median of 6, 10
    assert s["unique_coverage"] == pytest.approx([0.4, 0.02])
    assert s["low_coverage_parts"] == [1]  # 0.02 is at the threshold
    # part 0 sits 12 px above the centroid in both images; part 1 at (0, 18) then (4, 16)
    assert s["keypoint_spread"] == [pytest.approx(0.0), pytest.approx(np.sqrt((2.0 ** 2 + 1.0 ** 2) / 2), abs=1e-4)]
    line = allocation_line(s)
    assert line.startswith("keypoints: spread ") and "shin 8.0 px" in line and "1 of 2" in line
    assert Allocation(segments=["head"], num_parts=1).summary() is None  # nothing added: nothing measured


def test_allocation_takes_a_batch_of_bodies_with_different_vertex_layouts(tmp_path, renderer):
    """Issue 38: animals of different species have different meshes (the tiny set: 5,002 and 5,004 vertices) in one
    batch; the allocation diagnostic measured a batch as one stack of vertices and refused them, so a training on
    the animal data stopped at its first allocation probe. Each layout is now measured alone, in the batch's order:
    the same numbers as one image at a time."""
    from cerberus_core.cli import main
    from cerberus_core.datasets.dataset import Dataset
    from cerberus_core.eval.runner import evaluate_dataset

    assert main(["data", "generate", "--dataset", "animal", "--size", "tiny", "--out", str(tmp_path / "a"),
                 "--quiet"]) == 0
    views = Dataset.open(tmp_path / "a").views("test")
    assert len({len(views.gt_mesh(i).vertices) for i in range(len(views))}) > 1
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(num_parts=3, width=4, shape_latent_dim=8, depth_offset=float(views.scene.distance)))
    model.eval()
    skip = ("hard", "part_quality", "visibility", "depth", "segments")
    together = evaluate_dataset(views, model.reconstruct, renderer=renderer, skip=skip, batch_size=8, progress=False)
    alone = evaluate_dataset(views, model.reconstruct, renderer=renderer, skip=skip, batch_size=1, progress=False)
    assert [r["keypoints"] for r in together.records] == [r["keypoints"] for r in alone.records]
    assert [r["unique_coverage"] for r in together.records] == [r["unique_coverage"] for r in alone.records]
    assert together.diagnostics["allocation"] == alone.diagnostics["allocation"] is not None


def test_adding_by_hand_needs_the_vocabulary():
    batch = ImageAllocation(keypoints=np.zeros((1, 2, 2)), centroid=np.zeros((1, 2)), segments=np.zeros((1, 1, 2)),
                            unique=np.zeros((1, 2)))
    with pytest.raises(ConfigError, match=r"segments: Allocation.add needs .*`Allocation\(segments=\[...\], num_parts=P\)`"):
        Allocation().add(batch)
    acc = Allocation(segments=["body"], num_parts=2)
    acc.add(batch)
    assert acc.summary()["segment_to_keypoint"] == {"body": 0.0}  # no segment labels: the whole body's centroid


def test_an_image_whose_body_is_out_of_view_is_left_out_of_every_figure(renderer):
    """Review of issue 43: the unique coverage counted an image with an empty ground-truth foreground as 0 while the
    keypoint spread left it out (no centroid); one rule now: such an image is in no allocation figure, and the
    summary counts it apart. Two images of the same two parts, the second one's body (rendered by the renderer)
    wholly out of its camera: the summary is the first image's alone."""
    from dataclasses import fields

    from cerberus_core.eval.allocation import measure_allocation
    from cerberus_core.eval.masks import coverage_masks

    camera = Camera.look_at(torch.tensor([0.0, 0.0]), 0.0, 3.0, image_size=32)
    recon = PartSet.cat([spheres([[0.0, 0.15, 0.0], [0.0, -0.15, 0.0]])] * 2)
    bodies = PartSet.cat([spheres([[0.0, 0.0, 0.0]], 0.3), spheres([[9.0, 0.0, 0.0]], 0.3)])  # the second: off-camera
    foreground = coverage_masks(renderer, bodies.posed(), bodies.faces, camera)
    assert foreground[0].any() and not foreground[1].any()
    vertices = bodies.posed()[:, 0]  # (2, V, 3)
    measured = measure_allocation(renderer, recon, camera, foreground,
                                  (vertices, torch.zeros(vertices.shape[1], dtype=torch.long), 1))
    assert np.isfinite(measured.unique[0]).all() and np.isnan(measured.unique[1]).all()  # no share to measure
    both, first = Allocation(segments=["body"], num_parts=2), Allocation(segments=["body"], num_parts=2)
    both.add(measured)
    first.add(ImageAllocation(*(getattr(measured, f.name)[:1] for f in fields(ImageAllocation))))
    s, alone = both.summary(), first.summary()
    assert s["images"] == 1 and s["empty_foreground_images"] == 1 and alone["empty_foreground_images"] == 0
    assert {k: v for k, v in s.items() if k != "empty_foreground_images"} == \
        {k: v for k, v in alone.items() if k != "empty_foreground_images"}
    assert 0 < sum(s["unique_coverage"]) <= 1
