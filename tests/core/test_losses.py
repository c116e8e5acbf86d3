"""Every loss term (cerberus_core.losses), eqs. 2-7 and the terms beyond the paper."""

import math

import pytest
import torch

from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.losses import (
    VIEW_PARTNER,
    background_loss,
    background_mask,
    dihedral_cosines,
    keep_own_elements,
    mix_shape_latents,
    reconstruction_loss,
    smoothness_loss,
    translation_loss,
    viewpoint_reconstruction,
    viewpoint_scenes,
)
from cerberus_core.render.templates import icosphere


def test_reconstruction_loss_is_mean_over_pixels_of_squared_rgb_error():
    rendered = torch.zeros(2, 4, 3, 8, 8)
    target = torch.full((2, 4, 3, 8, 8), 0.5)
    target[0, 0, :, :4] = 0.0  # half the pixels of one image are right
    loss = reconstruction_loss(rendered, target)
    assert loss.shape == (2, 4)
    assert loss[0, 0] == pytest.approx(0.375)
    assert loss[1, 3] == pytest.approx(0.75)


def test_mixing_draws_each_element_from_one_of_the_four_latents():
    g = torch.Generator().manual_seed(0)
    latents = torch.arange(4.0).view(1, 4, 1) + 10 * torch.arange(3.0).view(3, 1, 1) + torch.zeros(3, 4, 500)
    mixed, choice = mix_shape_latents(latents, g)
    assert mixed.shape == (3, 500) and choice.shape == (3, 500)
    torch.testing.assert_close(mixed, latents.gather(1, choice.unsqueeze(1)).squeeze(1))
    torch.testing.assert_close(mixed, choice.float() + 10 * torch.arange(3.0).view(3, 1))
    counts = torch.bincount(choice.flatten(), minlength=4).float() / choice.numel()
    assert torch.allclose(counts, torch.full((4,), 0.25), atol=0.04)  # uniform categorical Z


def test_keep_own_elements_sends_each_gradient_to_the_latent_it_took():
    mixed = torch.randn(2, 4, 300, requires_grad=True)
    own = torch.randn(2, 4, 300, requires_grad=True)
    out = keep_own_elements(mixed, own, 0.3, torch.Generator().manual_seed(0))
    out.sum().backward()
    took_mixed = mixed.grad == 1
    assert torch.equal(took_mixed, own.grad == 0) and torch.equal(out, torch.where(took_mixed, mixed, own))
    assert took_mixed.float().mean().item() == pytest.approx(0.3, abs=0.03)
    assert torch.equal(keep_own_elements(mixed, own, 1.0), mixed) and torch.equal(keep_own_elements(mixed, own, 0.0), own)
    with pytest.raises(ValueError, match="losses.pose_mixing"):
        keep_own_elements(mixed, own, 1.2)


def test_viewpoint_scenes_cross_uses_partner_translation_with_own_rotation():
    """Equation 4: a0 -> a1 renders R^a0 V^a0 + T^a1 (and a1 -> a0 is R^a1 V^a1 + T^a0, etc.)."""
    g = torch.Generator().manual_seed(2)
    local = torch.randn(1, 4, 2, 5, 3, generator=g)
    rot = torch.linalg.qr(torch.randn(1, 4, 2, 3, 3, generator=g))[0]
    trans = torch.randn(1, 4, 2, 3, generator=g)
    own, cross = viewpoint_scenes(local, rot, trans)
    assert VIEW_PARTNER == (1, 0, 3, 2)
    for x, partner in enumerate(VIEW_PARTNER):
        rotated = local[0, x] @ rot[0, x].transpose(-1, -2)
        torch.testing.assert_close(own[0, x], rotated + trans[0, x].unsqueeze(-2))
        torch.testing.assert_close(cross[0, x], rotated + trans[0, partner].unsqueeze(-2))


def test_viewpoint_scenes_own_cross_view_is_the_whole_model_seen_from_the_partner():
    """cross_view='own': a0 -> a1 renders R^a0 V^a0 + T^a0 (image a0's own world model), so the
    partner's image checks each part's own depth; an unknown mode is refused."""
    g = torch.Generator().manual_seed(3)
    local = torch.randn(1, 4, 2, 5, 3, generator=g)
    rot = torch.linalg.qr(torch.randn(1, 4, 2, 3, 3, generator=g))[0]
    trans = torch.randn(1, 4, 2, 3, generator=g)
    own, cross = viewpoint_scenes(local, rot, trans, "own")
    torch.testing.assert_close(cross, own)
    torch.testing.assert_close(own, viewpoint_scenes(local, rot, trans)[0])
    with pytest.raises(ValueError, match="cross_view"):
        viewpoint_scenes(local, rot, trans, "mine")


def test_viewpoint_reconstruction_halves_own_and_cross_then_averages():
    own = torch.tensor([[1.0, 2.0, 3.0, 4.0]])
    cross = torch.tensor([[3.0, 2.0, 1.0, 0.0]])
    assert viewpoint_reconstruction(own, cross).item() == pytest.approx(2.0)
    assert viewpoint_reconstruction(own, None).item() == pytest.approx(2.5)


def test_body_translation_loss_is_the_mean_part_of_equation_5_blind_to_which_part_is_which():
    from cerberus_core.losses import body_translation_loss

    g = torch.Generator().manual_seed(0)
    t = torch.randn(2, 4, 5, 3, generator=g)
    # equation 5's decomposition: 1/N sum ||d_i||^2 = ||mean d||^2 + 1/N sum ||d_i - mean d||^2
    d_a, d_b = t[:, 0] - t[:, 1], t[:, 2] - t[:, 3]
    rest = 0.5 * sum((d - d.mean(1, keepdim=True)).square().sum(-1).mean(-1) for d in (d_a, d_b))
    torch.testing.assert_close(translation_loss(t), body_translation_loss(t) + rest)
    # the parts of one view in another order: equation 5 changes, the body's translation does not
    swapped = t.clone()
    swapped[:, 1] = t[:, 1, torch.tensor([4, 3, 2, 1, 0])]
    torch.testing.assert_close(body_translation_loss(swapped), body_translation_loss(t))
    assert (translation_loss(swapped) != translation_loss(t)).all()
    # one view's whole body 0.1 farther along z, every part: the loss is that shift squared, halved over two poses
    t = torch.zeros(1, 4, 3, 3)
    t[0, 1, :, 2] = 0.1
    assert body_translation_loss(t).item() == pytest.approx(0.5 * 0.01)


def test_body_translation_loss_gradient_moves_each_view_toward_the_other_and_keeps_the_parts_apart():
    from cerberus_core.losses import body_translation_loss

    t = torch.zeros(1, 4, 2, 3)
    t[0, :, 1, 0] = 0.5  # two parts 0.5 apart in every view
    t[0, 1, :, 2] = 0.2  # a1's whole body 0.2 farther in z than a0's
    t.requires_grad_(True)
    body_translation_loss(t).backward()
    grad = t.grad[0]
    assert (grad[0, :, 2] < 0).all() and (grad[1, :, 2] > 0).all()  # descent: a0 goes +z, a1 goes -z
    torch.testing.assert_close(grad[0, 0], grad[0, 1])  # every part of a view moves alike: the parts stay apart
    assert grad[2:].abs().max() == 0  # pose b agrees already


def test_triangulated_body_depth_loss_moves_each_views_whole_body_toward_its_target_alike_for_every_part():
    from cerberus_core.losses import triangulated_body_depth_loss

    depth = torch.full((2, 4, 3), 2.0)
    depth[0, 1] += torch.tensor([0.1, -0.1, 0.3])  # a1 of the first quadruplet: its body 0.1 too far on average
    target = torch.full((2, 4, 3), 2.0)
    weight = torch.ones(2, 4)
    weight[1] = 0.0  # the second quadruplet's views fix no depth
    depth.requires_grad_(True)
    loss = triangulated_body_depth_loss(depth, target, weight)
    assert loss[0].item() == pytest.approx(0.01 / 4, rel=1e-5) and loss[1].item() == 0.0
    loss.sum().backward()
    grad = depth.grad
    assert (grad[0, 1] > 0).all()  # descent brings a1's body nearer, every part by the same amount
    torch.testing.assert_close(grad[0, 1], grad[0, 1, :1].expand(3))
    assert grad[0, [0, 2, 3]].abs().max() == 0 and grad[1].abs().max() == 0


def test_translation_loss_equations_5_and_6():
    t = torch.zeros(1, 4, 3, 3)
    t[0, 0, :, 0] = 1.0  # a0 differs from a1 by 1 in x for every part; b0 == b1
    t[0, 2] = t[0, 3] = 5.0
    assert translation_loss(t).item() == pytest.approx(0.5)
    t[0, 3, 0, 1] = 7.0  # one of 3 parts of pose b off by 2 in y: L_t^b = 4 / 3
    assert translation_loss(t).item() == pytest.approx(0.5 * (1 + 4 / 3))


def test_background_loss_is_probability_mass_on_background():
    prob = torch.full((2, 3, 4, 4), 1 / 16)
    images = torch.ones(2, 3, 4, 4)
    images[:, :, :2] = 0.3  # top half is body, bottom half is white background
    mask = background_mask(images, (1.0, 1.0, 1.0), 0.02)
    assert mask.shape == (2, 1, 4, 4)
    torch.testing.assert_close(background_loss(prob, mask), torch.full((2,), 0.5))
    prob = torch.zeros(2, 3, 4, 4)
    prob[..., 0, 0] = 1.0  # all mass on a body pixel
    torch.testing.assert_close(background_loss(prob, mask), torch.zeros(2))


def _hinge(phi: float) -> torch.Tensor:
    """Two triangles sharing edge (0,0,0)-(1,0,0); the second wing at angle ``phi`` from the first."""
    return torch.tensor([[0.0, 0, 0], [1, 0, 0], [0.5, 1, 0], [0.5, math.cos(phi), math.sin(phi)]])


@pytest.mark.parametrize("phi, expected", [(math.pi, 0.0), (math.pi / 2, 1.0), (2 * math.pi / 3, 0.25),
                                           (1e-3, 4.0)])
def test_smoothness_of_a_hinge_is_cos_plus_one_squared(phi, expected):
    quad = torch.tensor([[0, 1, 2, 3]])
    v = _hinge(phi).view(1, 1, 4, 3)
    assert dihedral_cosines(v, quad).item() == pytest.approx(math.cos(phi), abs=1e-5)
    assert smoothness_loss(v, quad).item() == pytest.approx(expected, abs=1e-4)


def test_smoothness_of_spheres_is_small_and_summed_over_parts():
    t = icosphere(2)
    parts = t.vertices.expand(2, 3, -1, -1) * 0.1
    loss = smoothness_loss(parts, t.dihedral)
    assert loss.shape == (2,)
    per_part = smoothness_loss(parts[:, :1], t.dihedral)
    torch.testing.assert_close(loss, 3 * per_part)
    assert 0 < per_part[0] < 0.01 * len(t.dihedral)
    bumpy = parts.clone()
    bumpy[..., ::7, :] *= 1.5
    assert (smoothness_loss(bumpy, t.dihedral) > 10 * loss).all()


def test_silhouette_chamfer_pulls_toward_uncovered_foreground_and_vanishes_on_a_fit():
    from cerberus_core.losses import silhouette_chamfer

    fg = torch.zeros(1, 1, 16, 16)
    fg[..., 4:12, 2:4] = 1  # a thin vertical limb
    rows, cols = torch.nonzero(fg[0, 0], as_tuple=True)
    exact = (torch.stack([cols, rows], -1).float() + 0.5)[None]
    assert float(silhouette_chamfer(exact, fg)) == 0.0
    far = torch.tensor([[[13.0, 8.0], [14.0, 9.0]]], requires_grad=True)  # two vertices off to the right
    loss = silhouette_chamfer(far, fg)
    loss.backward()
    assert float(loss.detach()) > 0 and (far.grad[0, :, 0] > 0).all()  # descending moves both left, to the limb
    assert float(silhouette_chamfer(far.detach(), torch.zeros(1, 16, 16))) == 0.0


def test_silhouette_loss_is_the_mean_squared_coverage_error():
    from cerberus_core.losses import silhouette_loss

    alpha = torch.tensor([[[[1.0, 0.5], [0.0, 0.0]]]])
    fg = torch.tensor([[[[1.0, 1.0], [1.0, 0.0]]]])
    torch.testing.assert_close(silhouette_loss(alpha, fg), torch.tensor([(0.25 + 1.0) / 4]))


def test_hidden_part_pull_moves_only_hidden_parts_toward_uncovered_foreground():
    from cerberus_core.losses import hidden_part_pull

    uncovered = torch.zeros(1, 1, 16, 16)
    uncovered[..., 4:12, 2:4] = 1  # a limb nobody covers, columns 2-3
    pts = torch.tensor([[[[13.0, 8.0], [14.0, 9.0]],   # part 0: hidden, off to the right
                         [[8.0, 8.0], [9.0, 8.0]]]],   # part 1: visible
                       requires_grad=True)
    visible = torch.tensor([[False, True]])
    loss = hidden_part_pull(pts, visible, uncovered)
    # part 0's vertices (13, 8) and (14, 9): the nearest uncovered pixel centres lie in column 3.5,
    # half a pixel above or below, so the distances are |(9.5, 0.5)| and |(10.5, 0.5)|, in image heights
    expected = (torch.tensor([9.5, 0.5]).norm() + torch.tensor([10.5, 0.5]).norm()) / 2 / 16
    torch.testing.assert_close(loss, expected.reshape(1).float())
    loss.sum().backward()
    assert (pts.grad[0, 0, :, 0] > 0).all()  # descending moves the hidden part left, to the limb
    assert (pts.grad[0, 1] == 0).all()  # the visible part is left alone
    assert float(hidden_part_pull(pts.detach(), torch.tensor([[True, True]]), uncovered)) == 0.0
    assert float(hidden_part_pull(pts.detach(), visible, torch.zeros(1, 16, 16))) == 0.0
    with pytest.raises(ValueError, match="hidden_part_pull"):
        hidden_part_pull(pts.detach()[0], visible, uncovered)


def test_reprojection_loss_pulls_the_projection_toward_the_partner_keypoint_only():
    from cerberus_core.losses import reprojection_loss

    projected = torch.zeros(1, 4, 2, 2, requires_grad=True)
    keypoints = torch.zeros(1, 4, 2, 2, requires_grad=True)
    with torch.no_grad():
        keypoints[0, 0, 1] = torch.tensor([8.0, 0.0])  # one of 8 (image, part) pairs off by 8 px of 16
    loss = reprojection_loss(projected, keypoints, 16)
    torch.testing.assert_close(loss, torch.tensor([0.25 / 8]))
    loss.sum().backward()
    assert projected.grad[0, 0, 1, 0] < 0  # descending moves the projection right, onto the keypoint
    assert keypoints.grad is None  # the partner's keypoint is a target, not pulled
    with pytest.raises(ValueError, match="reprojection_loss"):
        reprojection_loss(projected[0], keypoints, 16)


def test_reprojection_gradient_moves_a_part_along_its_ray_toward_the_triangulated_depth():
    """A part seen at the right pixel of view 0 but at the wrong depth: the partner view (90 degrees
    around) sees it off its keypoint, and descending the term moves view 0's depth to the truth."""
    from cerberus_core.losses import reprojection_loss

    scene = SceneSetup(distance=2.5)
    cam = scene.cameras(torch.tensor([0.0, 90.0]), 32)
    truth = torch.tensor([[[0.2, 0.1, 0.0]]])  # (1, 1, 3) world point
    uv0, d0 = cam.index([0]).project(truth)
    uv1, _ = cam.index([1]).project(truth)
    def loss_at(depth):
        point = cam.index([0]).unproject(uv0, depth)  # stays on view 0's ray: view 0 unchanged
        projected, _ = cam.index([1]).project(point)
        return reprojection_loss(projected.reshape(1, 1, 1, 2).expand(1, 4, 1, 2),
                                 uv1.reshape(1, 1, 1, 2).expand(1, 4, 1, 2), 32).sum()

    for offset in (0.4, -0.4):  # too far, then too near, along view 0's ray
        depth = (d0 + offset).clone().requires_grad_(True)
        (grad,) = torch.autograd.grad(loss_at(depth), depth)
        assert float(grad.sign()) == (1.0 if offset > 0 else -1.0)  # descending moves it toward the truth
        opt = torch.optim.Adam([depth], lr=0.01)
        for _ in range(150):
            opt.zero_grad()
            loss_at(depth).backward()
            opt.step()
        assert abs(float(depth.detach() - d0)) < 0.01
    assert float(loss_at(d0)) < 1e-10


def test_cross_view_chamfer_pulls_a_part_along_its_own_ray_toward_the_partner_silhouette():
    """losses.cross_pulls: a part at the wrong depth sits exactly on its own view's silhouette, so the
    input-view chamfer gives its depth no gradient; projected into the partner view it misses the body by
    more than a limb's width, and the chamfer there pulls its depth toward the truth."""
    from cerberus_core.losses import silhouette_chamfer

    scene = SceneSetup(distance=2.5)
    cam = scene.cameras(torch.tensor([0.0, 90.0]), 32)
    truth = torch.tensor([[[0.1, 0.0, 0.0]]])
    blob = 0.05 * icosphere(1).vertices  # the part: a small sphere of points around its centre
    masks = []
    for k in range(2):  # each view's silhouette of the true part
        uv, _ = cam.index([k]).project(truth + blob[None])
        m = torch.zeros(1, 32, 32)
        cols, rows = uv[0, :, 0].long().clamp(0, 31), uv[0, :, 1].long().clamp(0, 31)
        m[0, rows, cols] = 1
        masks.append(m)
    uv0, d0 = cam.index([0]).project(truth)

    def pulls(depth):
        centre = cam.index([0]).unproject(uv0, depth)  # on view 0's ray through the true centre
        pts = centre + blob[None]
        own = silhouette_chamfer(cam.index([0]).project(pts)[0], masks[0])
        cross = silhouette_chamfer(cam.index([1]).project(pts)[0], masks[1])
        return own.sum(), cross.sum()

    depth = (d0 + 0.5).clone().requires_grad_(True)  # 0.5 too far: a limb's width is about 0.1
    own, cross = pulls(depth)
    (g_own,) = torch.autograd.grad(own, depth, retain_graph=True)
    (g_cross,) = torch.autograd.grad(cross, depth)
    assert abs(float(g_own)) < 0.1 * abs(float(g_cross))  # the input view barely sees the depth error
    assert float(g_cross) > 0  # descending the partner-view pull brings the part nearer, toward the truth


# ------------------------------------------------------------------ toward parts on the limbs (issue 30)
def _trunk_and_limb():
    """A 10-pixel-wide trunk (columns 10-19) and a 2-pixel-wide limb (columns 2-3), rows 4-27."""
    fg = torch.zeros(1, 1, 32, 32)
    fg[..., 4:28, 10:20] = 1
    fg[..., 4:28, 2:4] = 1
    return fg


def test_thinness_weights_are_one_over_the_squared_depth_inside_the_silhouette():
    from cerberus_core.losses import thinness_weights

    w = thinness_weights(_trunk_and_limb())
    assert w.shape == (1, 32, 32)
    torch.testing.assert_close(w[0, 15, 2:4], torch.ones(2))  # the limb: every pixel on the edge
    torch.testing.assert_close(w[0, 15, 10:20], torch.tensor([1.0, 2, 3, 4, 5, 5, 4, 3, 2, 1]) ** -2)
    assert float(w[0, 15].sum()) == pytest.approx(2 + 2 * (1 + 1 / 4 + 1 / 9 + 1 / 16 + 1 / 25))  # limb 2, trunk 2.9
    assert (w[0, 15, 4:10] == 0).all() and (w[0, :4] == 0).all()  # background
    edge = torch.zeros(1, 8, 8)
    edge[0, :, :3] = 1  # touching the image's border: the outside counts as background
    torch.testing.assert_close(thinness_weights(edge)[0, 4, :3], torch.tensor([1.0, 0.25, 1.0]))


def test_silhouette_coverage_pulls_the_nearest_vertex_onto_an_uncovered_thin_limb():
    from cerberus_core.losses import silhouette_coverage, thinness_weights

    fg = _trunk_and_limb()
    rows, cols = torch.nonzero(fg[0, 0], as_tuple=True)
    exact = (torch.stack([cols, rows], -1).float() + 0.5)[None]
    assert float(silhouette_coverage(exact, fg)) == 0.0  # every pixel has a point on it
    # Points cover the trunk only; the vertex at column 10 is the limb's nearest.
    grid = torch.stack(torch.meshgrid(torch.arange(10.5, 20), torch.arange(4.5, 28), indexing="xy"), -1).reshape(-1, 2)
    pts = grid[None].clone().requires_grad_(True)
    loss = silhouette_coverage(pts, fg)
    loss.backward()
    pulled = pts.grad[0].norm(dim=-1) > 0
    assert pulled.any() and (pts.grad[0, pulled, 0] > 0).all()  # descending moves them left, toward the limb
    assert (pts[0, pulled, 0] == 10.5).all()  # only the trunk's leftmost column, the limb's nearest
    # All the loss is the limb's, each pixel 7 or 8 pixels from the nearest vertex, weighted 1 (its depth
    # is 1) against the trunk's 1/d^2: the limb holds over a third of the weight and a sixth of the pixels.
    w = thinness_weights(fg)
    assert float(loss.detach()) == pytest.approx(24 * (8 + 7) / float(w.sum()) / 32, rel=1e-5)
    assert float(w[0, :, 2:4].sum() / w.sum()) > 1 / 3 > 48 / 288
    assert float(silhouette_coverage(pts.detach(), torch.zeros(1, 32, 32))) == 0.0
    with pytest.raises(ValueError, match="silhouette_coverage"):
        silhouette_coverage(pts.detach()[0], fg)


def test_silhouette_coverage_of_keypoints_spreads_stacked_parts_onto_the_limb():
    """With one point per part (its keypoint) the coverage is a weighted k-means: of two parts stacked
    on the trunk, the one nearer the uncovered limb is pulled onto it."""
    from cerberus_core.losses import silhouette_coverage

    keypoints = torch.tensor([[[14.0, 16.0], [16.0, 16.0]]], requires_grad=True)
    silhouette_coverage(keypoints, _trunk_and_limb()).backward()
    assert keypoints.grad[0, 0, 0] > 0  # part 0, nearer the limb: descending moves it left, toward it
    assert keypoints.grad[0, 0, 0] > keypoints.grad[0, 1, 0].abs()  # far more than part 1 moves sideways


def test_part_overlap_pushes_overlapping_parts_apart_and_ignores_separate_ones():
    from cerberus_core.losses import part_overlap

    sphere = icosphere(2).vertices.float() * 0.12
    def pair(dx):
        return torch.stack([sphere, sphere + torch.tensor([dx, 0.0, 0.0])])
    assert float(part_overlap(pair(0.0))) == pytest.approx(2 ** -1.5, rel=1e-4)  # equal parts, one centre
    assert float(part_overlap(pair(0.24))) < 0.03  # touching spheres pay little
    assert float(part_overlap(pair(1.0))) < 1e-6
    assert float(part_overlap(torch.stack([0.2 * sphere, sphere]))) == pytest.approx(0.95 / 2, abs=0.01)
    assert float(part_overlap(sphere[None])) == 0.0  # one part: nothing to overlap
    parts = pair(0.1).requires_grad_(True)
    part_overlap(parts).backward()
    step = -parts.grad.mean(1)  # descending moves each part's vertices on average ...
    assert step[0, 0] < 0 < step[1, 0]  # ... part 0 to the left, part 1 to the right: apart
    assert part_overlap(torch.stack([pair(0.0), pair(0.5)])).shape == (2,)


def test_rotation_loss_is_equation_6_for_rotations_and_turns_the_views_toward_each_other():
    from kornia.geometry.conversions import axis_angle_to_rotation_matrix

    from cerberus_core.losses import rotation_loss

    angles = torch.tensor([0.0, 0.5, 0.2, 0.2], requires_grad=True)  # pose a disagrees, pose b agrees
    axis = torch.tensor([0.0, 0.0, 1.0])
    rot = axis_angle_to_rotation_matrix(angles[:, None] * axis).view(1, 4, 1, 3, 3)
    loss = rotation_loss(rot)
    assert float(loss.detach()) == pytest.approx(0.5 * 4 * (1 - math.cos(0.5)), rel=1e-5)  # ||R - R'||^2 = 4 (1 - cos)
    loss.backward()
    assert angles.grad[0] < 0 < angles.grad[1]  # descending turns a0 and a1 toward each other
    assert angles.grad[2] == 0 and angles.grad[3] == 0
    assert (rotation_loss(torch.eye(3).expand(2, 4, 3, 3, 3)) == 0).all()


# ------------------------------------------------------------------ parts that move (issue 38)
def test_pose_consensus_is_the_mean_of_the_two_viewpoints_and_leaves_the_poses_apart():
    from cerberus_core.losses import pose_consensus

    t = torch.randn(2, 4, 3, 3)
    c = pose_consensus(t)
    torch.testing.assert_close(c[:, 0], 0.5 * (t[:, 0] + t[:, 1]))
    torch.testing.assert_close(c[:, 2], 0.5 * (t[:, 2] + t[:, 3]))
    assert torch.equal(c[:, 0], c[:, 1]) and torch.equal(c[:, 2], c[:, 3])
    with pytest.raises(ValueError, match="pose_consensus"):
        pose_consensus(t[:, :2])


def test_consensus_coverage_pulls_both_views_toward_the_limb_the_two_images_share():
    """A part that one view puts on the body's limb and the other on the trunk: projected from the pose's
    agreed point, the pulls of both images move *both* views' translations toward the limb (the per-image
    k-means would leave the view that sits on the trunk where it is)."""
    from cerberus_core.losses import pose_consensus, silhouette_coverage

    scene = SceneSetup(distance=2.5)
    cam = scene.cameras(torch.tensor([0.0, 60.0]), 32)
    limb = torch.tensor([0.35, 0.0, 0.0])  # a thin limb at x = 0.35, the trunk at the origin
    masks = []
    for k in range(2):
        fg = torch.zeros(1, 32, 32)
        for point in (limb, torch.zeros(3)):
            uv, _ = cam.index([k]).project(point.view(1, 1, 3))
            col, row = int(uv[0, 0, 0]), int(uv[0, 0, 1])
            fg[0, row - 6:row + 6, col - (1 if point is limb else 4):col + (1 if point is limb else 4)] = 1
        masks.append(fg)
    # Part 0 sits on the trunk in both views; part 1 on the limb in view 0 and on the trunk in view 1.
    t = torch.tensor([[[0.0, 0.0, 0.0], [0.35, 0.0, 0.0]], [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]])
    t = torch.cat([t, t]).unsqueeze(0).requires_grad_(True)  # (1, 4, 2, 3): poses a and b alike
    consensus = pose_consensus(t)
    loss = sum(silhouette_coverage(cam.index([k % 2]).project(consensus[:, k])[0], masks[k % 2]).sum()
               for k in range(4))
    loss.backward()
    assert t.grad[0, 1, 1, 0] < 0  # descending moves view 1's part 1 (on the trunk) toward the limb (+x)
    assert t.grad[0, 0, 1, 0] < 0  # and view 0's part 1 the same way: one 3D point, pulled by both images
    torch.testing.assert_close(t.grad[0, 0, 1], t.grad[0, 1, 1])


def test_part_separation_pushes_stacked_parts_apart_and_ignores_distant_ones():
    from cerberus_core.losses import part_separation

    t = torch.tensor([[0.0, 0.0, 0.0], [0.03, 0.0, 0.0], [0.5, 0.0, 0.0]], requires_grad=True)
    loss = part_separation(t)
    assert float(loss.detach()) == pytest.approx(2 * (0.01 - 0.03**2) / 6)
    loss.backward()
    assert t.grad[0, 0] > 0 > t.grad[1, 0]  # descending: part 0 to the left, part 1 to the right
    assert float(t.grad[2].abs().sum()) == 0.0  # the distant part feels nothing
    assert float(part_separation(t.detach()[:1])) == 0.0  # one part
    assert part_separation(torch.zeros(2, 4, 3, 3)).shape == (2, 4)
    assert float(part_separation(torch.zeros(3, 3))) == pytest.approx(0.01)  # all stacked: the maximum delta^2


def _trunk_and_arm(cam, views):
    """Per view: a trunk (12 x 8 px) that part 0 covers at the origin and a thin arm along +x to x = 0.45 that no part
    covers; returns the foreground, the part_id map (2 parts) and each view's arm end (the free pixel farthest from
    the origin's projection)."""
    fgs, ids, ends = [], [], []
    for k in views:
        fg, part_id = torch.zeros(32, 32), torch.full((32, 32), -1)
        (u0, v0), (u1, _) = (cam.index([k]).project(torch.tensor([[[x, 0.0, 0.0]]]))[0][0, 0].tolist()
                             for x in (0.0, 0.45))
        col, row, end = int(u0), int(v0), int(u1)
        fg[row - 6:row + 6, col - 4:col + 4] = 1
        part_id[row - 6:row + 6, col - 4:col + 4] = 0
        lo, hi = (col + 4, end + 1) if end > col else (end, col - 4)
        fg[row:row + 2, lo:hi] = 1  # the arm, two rows
        free = (fg > 0) & (part_id < 0)
        rr, cc = torch.nonzero(free, as_tuple=True)
        centres = torch.stack([cc, rr], -1).float() + 0.5
        ends.append(centres[(centres - torch.tensor([u0, v0])).norm(dim=-1).argmax()])
        fgs.append(fg), ids.append(part_id)
    return torch.stack(fgs)[None], torch.stack(ids)[None], torch.stack(ends)[None]


def test_relocation_pulls_a_spare_part_through_the_pose_to_the_farthest_uncovered_pixel():
    """Part 1 covers nothing: its pose-agreed translation, projected into each view, is pulled to that view's free
    pixel farthest from part 0's keypoint (the arm's end); both views pull it along +x, one step brings it closer in
    each image, and part 0 (holding the trunk) feels nothing."""
    from cerberus_core.losses import pose_consensus, relocation_pull

    cam = SceneSetup(distance=2.5).cameras(torch.tensor([0.0, 60.0, 0.0, 60.0]), 32)
    fg, part_id, ends = _trunk_and_arm(cam, range(4))
    t = torch.zeros(1, 4, 2, 3, requires_grad=True)  # both parts at the origin in every view

    def pulled(t):
        return cam.project(pose_consensus(t).flatten(0, 1))[0].view(1, 4, 2, 2)

    points = pulled(t)
    loss = relocation_pull(points, part_id, fg, points)
    expected = ((points[0, :, 1].detach() - ends[0]) / 32).square().sum(-1)
    torch.testing.assert_close(loss.detach()[0], expected)
    loss.sum().backward()
    assert (t.grad[0, :, 1, 0] < 0).all()  # descending moves the spare part toward the arm (+x) in every view
    assert float(t.grad[0, :, 0].abs().sum()) == 0.0  # the part that holds the trunk: no gradient
    stepped = pulled(t.detach() - 0.5 * t.grad)
    before = (points[0, :, 1].detach() - ends[0]).norm(dim=-1)
    assert ((stepped[0, :, 1] - ends[0]).norm(dim=-1) < before).all()
    reached = part_id.clone()  # part 1 holds the arm's end pixel, too little to be placed: the end stays its target
    for k in range(4):
        reached[0, k, int(ends[0, k, 1]), int(ends[0, k, 0])] = 1
    torch.testing.assert_close(relocation_pull(points.detach(), reached, fg, points.detach()), loss.detach())


def test_relocation_is_zero_without_a_spare_part_and_decides_spare_over_the_pose():
    """No spare part (each holds more than 2 % of the pose's foreground), no foreground, or a part hidden behind
    another in one view but holding the arm in its partner: 0, and no gradient. Spare is the eval's spare share."""
    import inspect

    from cerberus_core.eval.allocation import SPARE_COVERAGE
    from cerberus_core.losses import relocation_pull

    assert inspect.signature(relocation_pull).parameters["spare_share"].default == SPARE_COVERAGE
    cam = SceneSetup(distance=2.5).cameras(torch.tensor([0.0, 60.0, 0.0, 60.0]), 32)
    fg, part_id, _ = _trunk_and_arm(cam, range(4))
    points = torch.full((1, 4, 2, 2), 16.0, requires_grad=True)
    held = torch.where((fg > 0) & (part_id < 0), 1, part_id)  # part 1 holds the arm in every view
    loss = relocation_pull(points, held, fg, points.detach())
    assert loss.shape == (1, 4) and float(loss.detach().abs().sum()) == 0.0
    loss.sum().backward()
    assert float(points.grad.abs().sum()) == 0.0
    assert float(relocation_pull(points.detach(), part_id, torch.zeros_like(fg), points.detach()).abs().sum()) == 0
    hidden_in_one = held.clone()
    hidden_in_one[0, 0][hidden_in_one[0, 0] == 1] = 0  # view a0: part 0 in front of the arm too
    assert float(relocation_pull(points.detach(), hidden_in_one, fg, points.detach()).abs().sum()) == 0.0
    assert relocation_pull(points.detach(), part_id, fg, points.detach()).gt(0).all()  # part 1 holds nothing: spare


def test_consensus_tips_swing_a_part_toward_the_limb_its_far_end_is_nearest_instead_of_stretching_it():
    """``losses.consensus_tips``: a part on the trunk whose far end points up at the start of a raised arm. The
    keypoint-only k-means has no use for the part's turn; with the tips the arm's pixels pull the pose's agreed tip,
    and descending turns the part toward the arm in both views, while its vertices get no gradient (detached)."""
    from cerberus_core.losses import part_tips, pose_consensus, silhouette_coverage

    scene = SceneSetup(distance=2.5)
    cam = scene.cameras(torch.tensor([0.0, 40.0]), 32)
    body = [torch.tensor([0.0, y, 0.0]) for y in torch.linspace(-0.3, 0.3, 25)]  # the trunk, up to the shoulder
    body += [torch.tensor([x, 0.3, 0.0]) for x in torch.linspace(0.0, 0.4, 17)]  # the raised arm, along +x
    masks = []
    for k in range(2):
        uv, _ = cam.index([k]).project(torch.stack(body).view(1, -1, 3))
        fg = torch.zeros(1, 32, 32)
        fg[0, uv[0, :, 1].long(), uv[0, :, 0].long()] = 1
        masks.append(fg)
    vertices = torch.tensor([[0.0, 0.3, 0.0], [0.05, 0.0, 0.0], [0.0, -0.1, 0.0]]).expand(1, 4, 1, 3, 3).clone()
    vertices.requires_grad_(True)
    angle = torch.zeros((), requires_grad=True)  # the part's turn about the camera-facing axis z (+: toward +x)
    c, s = torch.cos(angle), torch.sin(angle)
    rot = torch.stack([torch.stack([c, s, 0 * c]), torch.stack([-s, c, 0 * c]),
                       torch.stack([0 * c, 0 * c, 1 + 0 * c])]).expand(1, 4, 1, 3, 3)
    t = torch.zeros(1, 4, 1, 3)

    def pull(points):  # (1, 4, M, 3) world points -> the pose's k-means over both images
        agreed = pose_consensus(points)
        return sum(silhouette_coverage(cam.index([k % 2]).project(agreed[:, k])[0], masks[k % 2]).sum()
                   for k in range(4))

    tips = part_tips(vertices, rot, t)
    torch.testing.assert_close(tips[0, :, 0], torch.tensor([0.0, 0.3, 0.0]).expand(4, 3))  # vertex 0, every view
    loss = pull(torch.cat([t, tips], dim=2))
    loss.backward()
    assert float(angle.grad) < 0  # descending turns the far end toward the arm (+x)
    assert vertices.grad is None  # the shape is left alone: the part swings, it does not stretch
