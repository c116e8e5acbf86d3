"""Every loss term (cerberus_core.losses) and how the training objective wires them (eqs. 2-7)."""
import math

import pytest
import torch

from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.losses import (
    VIEW_PARTNER,
    background_loss,
    background_mask,
    dihedral_cosines,
    mix_shape_latents,
    reconstruction_loss,
    smoothness_loss,
    translation_loss,
    viewpoint_reconstruction,
    viewpoint_scenes,
)
from cerberus_core.model import Cerberus, ModelConfig
from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import make_renderer
from cerberus_core.render.templates import icosphere
from cerberus_core.train.data import QuadrupletBatch
from cerberus_core.train.objective import LossConfig, partner_cameras, quadruplet_mixer, quadruplet_objective


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


def test_quadruplet_mixer_shares_one_mixed_latent_per_quadruplet():
    own = torch.randn(8, 32)  # 2 quadruplets
    mixed = quadruplet_mixer(torch.Generator().manual_seed(1))(own)
    quads, mq = own.view(2, 4, 32), mixed.view(2, 4, 32)
    for b in range(2):
        assert all(torch.equal(mq[b, 0], mq[b, k]) for k in range(4))
        from_one = (mq[b, 0].unsqueeze(0) == quads[b]).any(0)
        assert from_one.all()
        assert not torch.equal(mq[b, 0], quads[b, 0])


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


def test_cross_view_warmup_keeps_the_partner_translations_first():
    cfg = LossConfig(cross_view="own", cross_view_warmup=300)
    assert [cfg.cross_view_at(s) for s in (0, 299, 300, None)] == ["partner", "partner", "own", "own"]
    assert LossConfig().cross_view_at(10_000) == "partner"  # the paper's equation 4 by default


def test_viewpoint_reconstruction_halves_own_and_cross_then_averages():
    own = torch.tensor([[1.0, 2.0, 3.0, 4.0]])
    cross = torch.tensor([[3.0, 2.0, 1.0, 0.0]])
    assert viewpoint_reconstruction(own, cross).item() == pytest.approx(2.0)
    assert viewpoint_reconstruction(own, None).item() == pytest.approx(2.5)


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


def test_loss_config_rejects_negative_weights():
    with pytest.raises(ValueError, match="losses.smoothness"):
        LossConfig(smoothness=-1).validate()


# ------------------------------------------------------------------ the objective's wiring
def _setup(pose_consistency=True, viewpoint_consistency=True):
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(num_parts=3, sphere_level=1, width=8, shape_latent_dim=8, depth_offset=2.5))
    with torch.no_grad():
        model.rotation.linear.weight.normal_(std=0.5)  # distinct rotations per image
    scene = SceneSetup(distance=2.5)
    az = torch.tensor([0.0, 80.0, 20.0, 140.0])
    cam = scene.cameras(az, 32)
    images = 0.9 * torch.rand(1, 4, 3, 32, 32)
    images[..., :8, :] = 1.0  # a band of white dataset background
    losses = LossConfig(pose_consistency=pose_consistency, viewpoint_consistency=viewpoint_consistency)
    return model, scene, QuadrupletBatch(images, cam), losses


def test_objective_cross_renders_own_rotated_mesh_with_partner_translation_from_partner_view():
    """Equation 4 end to end, with the loss's black background (background pixels of the targets
    zeroed, renderings composited over black)."""
    model, scene, batch, losses = _setup()
    assert losses.render_background == "black"
    targets = batch.images.clone()
    targets[..., :8, :] = 0.0
    renderer = make_renderer("torch")
    out = quadruplet_objective(model, renderer, batch, scene, losses, torch.Generator().manual_seed(3))
    # Recompute the reconstruction term scene by scene, from the model's own predictions.
    mixed = quadruplet_mixer(torch.Generator().manual_seed(3))
    pred = model(batch.images[0], mixed)
    rot, trans, _, _ = model.world_pose(pred, batch.camera)
    rotated = pred.local_vertices @ rot.transpose(-1, -2)
    own, cross = [], []
    for x, partner in enumerate(VIEW_PARTNER):
        def draw(verts, cam_index):
            cam = batch.camera.index([cam_index])
            return render_parts(renderer, verts.unsqueeze(0), model.faces, cam, scene.light(cam),
                                albedo=scene.albedo, background=(0.0, 0.0, 0.0)).image[0]
        own.append(reconstruction_loss(draw(rotated[x] + trans[x].unsqueeze(-2), x), targets[0, x]))
        cross.append(reconstruction_loss(draw(rotated[x] + trans[partner].unsqueeze(-2), partner),
                                         targets[0, partner]))
    expected = sum(0.5 * (o + c) for o, c in zip(own, cross, strict=False)) / 4
    assert out.terms["recon"].item() == pytest.approx(expected.item(), rel=1e-5)
    renders = out.renders[0]
    assert renders.shape == (4, 3, 32, 32)


def test_partner_cameras_swap_views_within_each_pose():
    scene = SceneSetup(distance=2.5)
    cam = scene.cameras(torch.arange(8.0) * 10, 32)
    swapped = partner_cameras(cam, 2)
    expected = torch.tensor([1, 0, 3, 2, 5, 4, 7, 6])
    torch.testing.assert_close(swapped.rotation, cam.rotation[expected])


def _latents_seen(model, pose_consistency):
    seen = {}
    model.shape.to_latent.register_forward_hook(lambda m, i, o: seen.__setitem__("own", o.detach()))
    model.shape.to_displacement.register_forward_hook(lambda m, i, o: seen.__setitem__("render", i[0].detach()))
    return seen


@pytest.mark.parametrize("pose_consistency", [True, False])
def test_objective_pose_consistency_switch(pose_consistency):
    model, scene, batch, losses = _setup(pose_consistency=pose_consistency)
    seen = _latents_seen(model, pose_consistency)
    quadruplet_objective(model, make_renderer("torch"), batch, scene, losses, torch.Generator().manual_seed(0))
    own, render = seen["own"], seen["render"]
    if pose_consistency:
        assert all(torch.equal(render[0], render[k]) for k in range(4))
        assert ((render[0].unsqueeze(0) == own).any(0)).all()
        assert not torch.equal(render, own)
    else:  # Free Cerberus: every image renders its own shape latent
        torch.testing.assert_close(render, own)


def test_objective_without_viewpoint_consistency_renders_only_own_views():
    model, scene, batch, losses = _setup(viewpoint_consistency=False)
    losses.render_background = "dataset"  # the dataset's white background, as in the input images
    out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses, torch.Generator().manual_seed(0))
    assert (out.renders[0, :, :, 0, 0] == 1.0).any()  # some corner shows the white background
    own = reconstruction_loss(out.renders, batch.images).mean()
    assert out.terms["recon"].item() == pytest.approx(own.item(), rel=1e-5)
    total = sum(getattr(losses, k) * out.terms[k] for k in ("recon", "translation", "background", "smoothness"))
    assert out.total.item() == pytest.approx(total.item(), rel=1e-6)


def test_objective_reports_non_finite_geometry_without_rendering():
    model, scene, batch, losses = _setup()
    batch.images[0, 1] = float("nan")
    out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses)
    assert not out.finite and math.isnan(out.total.item()) and out.renders is None


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


def _grad_norm(model, total):
    if not total.requires_grad:
        return 0.0
    model.zero_grad(set_to_none=True)
    total.backward()
    return sum(float(p.grad.abs().sum()) for p in model.parameters() if p.grad is not None)


@pytest.mark.parametrize("antialias", [False, True])
def test_objective_silhouette_term_has_gradient_only_with_antialiasing(antialias):
    """The silhouette term alone: the paper's renderer gives its hard coverage no gradient; the
    anti-aliased renderer does (visibility gradients reach the network)."""
    model, scene, batch, _ = _setup()
    losses = LossConfig(recon=0, translation=0, background=0, smoothness=0, silhouette=1.0)
    out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses,
                               torch.Generator().manual_seed(0), antialias=antialias)
    assert out.terms["silhouette"].item() > 0
    assert out.total.item() == pytest.approx(out.terms["silhouette"].item(), rel=1e-6)
    grad = _grad_norm(model, out.total)
    assert (grad > 0) == antialias


def test_objective_silhouette_term_is_the_coverage_error_of_each_view():
    model, scene, batch, _ = _setup(viewpoint_consistency=False)
    losses = LossConfig(silhouette=1.0, viewpoint_consistency=False)
    out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses, torch.Generator().manual_seed(0))
    fg = 1 - background_mask(batch.images, scene.background, losses.background_tolerance)  # (1, 4, 1, H, W)
    alpha = (out.renders.sum(2, keepdim=True) > 0).float()  # over black, every covered pixel is lit
    assert 0 < alpha.mean() < 1
    from cerberus_core.losses import silhouette_loss
    expected = silhouette_loss(alpha, fg).mean()
    assert out.terms["silhouette"].item() == pytest.approx(expected.item(), rel=1e-6)


def test_objective_pulls_are_zero_when_unweighted():
    """The chamfer and hidden-part pulls are Python loops over images: not computed at weight 0."""
    model, scene, batch, _ = _setup()
    off = quadruplet_objective(model, make_renderer("torch"), batch, scene, LossConfig(),
                               torch.Generator().manual_seed(0))
    assert off.terms["chamfer"].item() == 0.0 and off.terms["hidden"].item() == 0.0


def test_objective_chamfer_term_is_the_chamfer_of_the_projected_parts_and_pulls_every_vertex():
    model, scene, batch, _ = _setup()
    losses = LossConfig(recon=0, translation=0, background=0, smoothness=0, chamfer=1.0)
    out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses, torch.Generator().manual_seed(0))
    from cerberus_core.losses import silhouette_chamfer
    uv, _ = batch.camera.project(out.parts.flatten(0, 1).flatten(1, 2))
    fg = 1 - background_mask(batch.images[0], scene.background, losses.background_tolerance)
    assert out.terms["chamfer"].item() == pytest.approx(silhouette_chamfer(uv, fg).mean().item(), rel=1e-5)
    assert _grad_norm(model, out.total) > 0  # no renderer in the path: a gradient with the paper's renderer too


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


def test_objective_hidden_term_is_the_pull_of_the_hidden_parts():
    _, scene, batch, _ = _setup()
    losses = LossConfig(recon=0, translation=0, background=0, smoothness=0, hidden=1.0)
    torch.manual_seed(0)  # twelve parts at one anchor crowd the middle of the image: some hide behind others
    model = Cerberus(ModelConfig(num_parts=12, sphere_level=1, width=8, shape_latent_dim=8, depth_offset=2.5,
                                 anchor_spread=0.0))
    out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses, torch.Generator().manual_seed(0))
    # Recompute it from the objective's own parts: render each own view, count each part's pixels.
    from cerberus_core.losses import hidden_part_pull
    from cerberus_core.render.api import render_parts
    bsz, n, v = out.parts.shape[0], out.parts.shape[2], out.parts.shape[3]
    model_faces = model.faces
    part_id = render_parts(make_renderer("torch"), out.parts.flatten(0, 1), model_faces, batch.camera).part_id
    shown = torch.stack([(part_id == k).flatten(1).any(1) for k in range(n)], 1)
    fg = 1 - background_mask(batch.images[0], scene.background, losses.background_tolerance)
    uv, _ = batch.camera.project(out.parts.flatten(0, 1).flatten(1, 2))
    expected = hidden_part_pull(uv.view(4 * bsz, n, v, 2), shown, fg[:, 0] * (part_id < 0)).mean()
    assert not shown.all() and expected.item() > 0
    assert out.terms["hidden"].item() == pytest.approx(expected.item(), rel=1e-5)
    assert _grad_norm(model, out.total) > 0  # no renderer in the path: a gradient with the paper's renderer too


def test_loss_config_rejects_nan_weights():
    with pytest.raises(ValueError, match="losses.silhouette"):
        LossConfig(silhouette=float("nan")).validate()


def test_the_term_table_makes_the_config_weights_and_the_docs_show_it():
    """Each term is declared once (TERM_TABLE): LossConfig's weight fields are made from it, with the
    paper's weights as defaults and the range >= 0; docs/training.md shows terms_table()."""
    from pathlib import Path

    from cerberus_core.train.objective import TERM_TABLE, terms_table

    assert LossConfig().weights == {t.name: t.weight for t in TERM_TABLE}
    assert [t.name for t in TERM_TABLE if t.paper] == ["recon", "translation", "background", "smoothness"]
    assert all(t.weight == 0 for t in TERM_TABLE if not t.paper)  # beyond the paper: off in its settings
    assert all(t.function.__module__ == "cerberus_core.losses" for t in TERM_TABLE)
    docs = (Path(__file__).resolve().parents[2] / "docs" / "training.md").read_text()
    assert terms_table() in docs, "docs/training.md: paste cerberus_core.train.objective.terms_table() over its table"
    with pytest.raises(ValueError, match=r"losses.hidden = nan: must be a number >= 0"):
        LossConfig(hidden=float("nan")).validate()


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


def _depth_setup(cross_view="partner", **weights):
    """Two views 90 degrees apart of one pose; the objective's gradient on the predicted depths."""
    model, scene, batch, _ = _setup()
    losses = LossConfig(**{"recon": 0, "translation": 0, "background": 0, "smoothness": 0, **weights},
                        cross_view=cross_view)
    return model, scene, batch, losses


def test_objective_reprojection_is_the_translations_seen_by_the_partner_camera():
    model, scene, batch, losses = _depth_setup(reprojection=1.0)
    out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses, torch.Generator().manual_seed(0))
    pred = model(batch.images[0], quadruplet_mixer(torch.Generator().manual_seed(0)))
    _, trans, _, _ = model.world_pose(pred, batch.camera)
    uv, _ = partner_cameras(batch.camera, 1).project(trans)
    kp = pred.maps.uv[list(VIEW_PARTNER)]
    expected = ((uv - kp) / 32).square().sum(-1).mean()
    assert out.terms["reprojection"].item() == pytest.approx(expected.item(), rel=1e-4)
    assert expected.item() > 0 and _grad_norm(model, out.total) > 0


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


def test_cross_pulls_average_the_partner_view_pull_with_the_input_view_pull():
    model, scene, batch, _ = _setup()
    renderer, gen = make_renderer("torch"), torch.Generator
    kw = dict(recon=0, translation=0, background=0, smoothness=0, chamfer=1.0, cross_view="own")
    own_only = quadruplet_objective(model, renderer, batch, scene, LossConfig(**kw), gen().manual_seed(0))
    both = quadruplet_objective(model, renderer, batch, scene, LossConfig(**kw, cross_pulls=True), gen().manual_seed(0))
    from cerberus_core.losses import silhouette_chamfer
    parts = own_only.parts.flatten(0, 1).flatten(1, 2)  # own cross view: the same world parts
    uv_cross, _ = partner_cameras(batch.camera, 1).project(parts)
    fg = 1 - background_mask(batch.images[0], scene.background, 0.02)
    cross = silhouette_chamfer(uv_cross, fg[list(VIEW_PARTNER)]).mean()
    expected = 0.5 * (own_only.terms["chamfer"] + cross)
    assert both.terms["chamfer"].item() == pytest.approx(expected.item(), rel=1e-5)
    assert cross.item() != pytest.approx(own_only.terms["chamfer"].item(), rel=1e-3)


def test_objective_own_cross_view_renders_each_model_whole_from_the_partner_camera():
    model, scene, batch, _ = _setup()
    renderer = make_renderer("torch")
    losses = LossConfig(cross_view="own", cross_view_warmup=5)
    warm = quadruplet_objective(model, renderer, batch, scene, losses, torch.Generator().manual_seed(3), step=4)
    paper = quadruplet_objective(model, renderer, batch, scene, LossConfig(), torch.Generator().manual_seed(3))
    assert warm.terms["recon"].item() == paper.terms["recon"].item()  # partner translations in the warm-up
    after = quadruplet_objective(model, renderer, batch, scene, losses, torch.Generator().manual_seed(3), step=5)
    parts = after.parts[0]  # (4, N, V, 3) world parts, the same ones seen from the partner camera
    targets = batch.images.clone()
    targets[..., :8, :] = 0.0
    cams = partner_cameras(batch.camera, 1)
    cross = render_parts(renderer, parts, model.faces, cams, scene.light(cams), albedo=scene.albedo,
                         background=(0.0, 0.0, 0.0)).image
    own = reconstruction_loss(after.renders[0], targets[0])
    expected = 0.5 * (own + reconstruction_loss(cross, targets[0, list(VIEW_PARTNER)]))
    assert after.terms["recon"].item() == pytest.approx(expected.mean().item(), rel=1e-5)
    assert after.terms["recon"].item() != pytest.approx(paper.terms["recon"].item(), rel=1e-4)


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
