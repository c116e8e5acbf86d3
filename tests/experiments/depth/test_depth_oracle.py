"""experiments/depth/depth_oracle.py: the oracle that triangulates each part's rays."""
from __future__ import annotations

import pytest
import torch

from tests.support.paths import load_script


def test_along_rays_keeps_each_keypoint_in_view_and_reaches_the_new_depth():
    from cerberus_core.parts import PartSet
    from cerberus_core.render.camera import Camera

    module = load_script("experiments/depth/depth_oracle.py")
    camera = Camera.look_at(30.0, 15.0, 2.0, fov_y_deg=30.0, image_size=64)
    translations = torch.tensor([[[0.1, 0.0, 0.0], [-0.2, 0.3, 0.1]]])  # (1, 2, 3)
    local = torch.randn(1, 2, 5, 3) * 0.05
    parts = PartSet(local, torch.zeros(1, 3, dtype=torch.long), torch.eye(3).expand(1, 2, 3, 3), translations)
    uv, depth = camera.project(translations)
    new_depth = depth[0] + torch.tensor([0.05, -0.03])
    moved = module.along_rays(parts, camera.center[0], depth[0], new_depth)
    uv2, depth2 = camera.project(moved.translations)
    torch.testing.assert_close(uv2, uv, atol=1e-4, rtol=0)
    torch.testing.assert_close(depth2[0], new_depth, atol=1e-5, rtol=0)
    torch.testing.assert_close(moved.local_vertices, parts.local_vertices)


def test_shift_search_finds_the_depth_a_sphere_was_pushed_away_by_from_each_signal():
    import trimesh

    from cerberus_core.eval.masks import coverage_masks
    from cerberus_core.eval.standard import VoxelScorer
    from cerberus_core.parts import PartSet
    from cerberus_core.render.backends import make_renderer
    from cerberus_core.render.camera import Camera

    module = load_script("experiments/depth/depth_oracle.py")
    sphere = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    verts = torch.as_tensor(sphere.vertices, dtype=torch.float32)
    faces = torch.as_tensor(sphere.faces, dtype=torch.long)
    camera = Camera.look_at(0.0, 15.0, 2.0, fov_y_deg=30.0, image_size=64)
    other = Camera.look_at(90.0, 15.0, 2.0, fov_y_deg=30.0, image_size=64)
    centre = camera.center[0]
    at_origin = PartSet(verts[None, None], faces, torch.eye(3)[None, None], torch.zeros(1, 1, 3))
    _, depth = camera.project(at_origin.translations)
    pushed = module.along_rays(at_origin, centre, depth[0], depth[0] + 0.03)  # 0.03 too far from the camera
    renderer = make_renderer("torch")
    truth = coverage_masks(renderer, verts[None, None], faces, other)[0]
    ious, picks = module.shift_search(VoxelScorer(), renderer, pushed, camera, depth[0] + 0.03,
                                      (sphere.vertices, sphere.faces), [other], [truth])
    assert module.GRID[int(torch.tensor(ious).argmax())] == -0.03
    assert picks["partner_silhouette"][0] == -0.03 and picks["partner_centroid"][0] == -0.03
    assert abs(picks["box_centre"][0] + 0.03) < 2e-3
    assert min(iou for _, iou in picks.values()) > ious[list(module.GRID).index(0.0)] + 0.1


def test_ridge_readout_finds_a_linear_signal_and_reports_none_in_noise():
    import numpy as np

    module = load_script("experiments/depth/depth_oracle.py")
    rng = np.random.default_rng(0)
    x, test_x = rng.normal(size=(600, 20)), rng.normal(size=(200, 20))
    w = rng.normal(size=20)
    signal = module.ridge_readout(x, x @ w + 0.1 * rng.normal(size=600), test_x, test_x @ w)
    assert signal["test_r2"] > 0.95 and signal["test_correlation"] > 0.95
    assert signal["mean_abs_residual"] < 0.2 * signal["mean_abs_shift"]
    noise = module.ridge_readout(x, rng.normal(size=600), test_x, rng.normal(size=200))
    assert noise["test_r2"] < 0.05 and abs(noise["test_correlation"]) < 0.2


def test_triangulated_depths_are_each_view_s_depth_of_the_point_its_rays_meet_at():
    from cerberus_core.render.camera import Camera

    module = load_script("experiments/depth/depth_oracle.py")
    points = torch.tensor([[[0.1, 0.2, -0.1], [-0.2, -0.1, 0.15]]])  # (1, N=2, 3) world
    cams = {i: Camera.look_at(az, 15.0, 2.0, fov_y_deg=30.0, image_size=64) for i, az in ((3, 0.0), (7, 70.0))}
    uv = {i: cam.project(points)[0][0] for i, cam in cams.items()}
    depths = module.triangulated_depths([3, 7], uv, cams)
    for i, cam in cams.items():
        torch.testing.assert_close(depths[i], cam.project(points)[1][0], atol=1e-4, rtol=0)
    shifts = module.body_shifts([[3, 7]], uv, {i: d - 0.05 for i, d in depths.items()}, cams)
    assert shifts == {3: pytest.approx(0.05, abs=1e-4), 7: pytest.approx(0.05, abs=1e-4)}



def test_flip_search_mirrors_back_the_part_that_points_the_wrong_way_in_depth():
    """--flip: two rods tilted toward the camera; the prediction has the second tilted away (the same pixels,
    mirrored in depth about its translation). The mirror keeps every vertex's pixel and is its own inverse; the
    greedy search mirrors the second rod back, leaves the first alone, and scores the truth's IoU."""
    import numpy as np
    import trimesh

    from cerberus_core.eval.standard import VoxelScorer
    from cerberus_core.parts import PartSet
    from cerberus_core.render.camera import Camera

    module = load_script("experiments/depth/depth_oracle.py")
    camera = Camera.look_at(0.0, 0.0, 2.0, fov_y_deg=30.0, image_size=64)
    rod = trimesh.creation.capsule(height=0.4, radius=0.06, count=[8, 8])
    tilt = trimesh.transformations.rotation_matrix(0.7, [1.0, 0.0, 0.0])[:3, :3]  # its ends at different depths
    local = torch.as_tensor(rod.vertices @ tilt.T, dtype=torch.float32)
    faces = torch.as_tensor(rod.faces, dtype=torch.long)
    place = torch.tensor([[[-0.25, 0.0, 0.0], [0.25, 0.0, 0.0]]])
    truth = PartSet(local.expand(1, 2, -1, -1), faces, torch.eye(3).expand(1, 2, 3, 3), place)
    gt = trimesh.util.concatenate([trimesh.Trimesh(v, f) for v, f in truth.part_meshes(0)])
    gt = (np.asarray(gt.vertices), np.asarray(gt.faces))
    second = truth.posed()[:, 1]  # (1, V, 3) world
    _, t_depth = camera.project(place[:, 1:])
    about = t_depth.expand(1, second.shape[1])
    wrong = module.mirrored_in_depth(second, camera, about)
    torch.testing.assert_close(camera.project(wrong)[0], camera.project(second)[0], atol=1e-4, rtol=0)
    assert float((camera.project(wrong)[1] - camera.project(second)[1]).abs().max()) > 0.1  # reversed in depth
    torch.testing.assert_close(module.mirrored_in_depth(wrong, camera, about), second, atol=1e-5, rtol=0)
    predicted = PartSet(torch.stack([local, wrong[0] - place[0, 1]])[None], faces, torch.eye(3).expand(1, 2, 3, 3),
                        place)
    scorer = VoxelScorer()
    before = scorer(predicted.part_meshes(0), gt).iou
    greedy, mirror, chosen = module.flip_search(scorer, predicted, camera, gt)
    assert chosen == [1] and greedy > 0.9 and greedy > before + 0.2
    assert mirror < greedy  # mirroring everything reverses the first rod as well
    right, _, none = module.flip_search(scorer, truth, camera, gt)
    assert none == [] and right > 0.9
