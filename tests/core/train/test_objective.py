"""How the training objective wires the loss terms (cerberus_core.train.objective): the quadruplet mixer,
partner cameras, the switches, the weights and their table."""
import math

import pytest
import torch

from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.losses import (
    VIEW_PARTNER,
    background_mask,
    reconstruction_loss,
)
from cerberus_core.model import Cerberus, ModelConfig
from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import make_renderer
from cerberus_core.train.data import QuadrupletBatch
from cerberus_core.train.objective import LossConfig, partner_cameras, quadruplet_mixer, quadruplet_objective
from tests.support.paths import REPO


def test_quadruplet_mixer_shares_one_mixed_latent_per_quadruplet():
    own = torch.randn(8, 32)  # 2 quadruplets
    mixed = quadruplet_mixer(torch.Generator().manual_seed(1))(own)
    quads, mq = own.view(2, 4, 32), mixed.view(2, 4, 32)
    for b in range(2):
        assert all(torch.equal(mq[b, 0], mq[b, k]) for k in range(4))
        from_one = (mq[b, 0].unsqueeze(0) == quads[b]).any(0)
        assert from_one.all()
        assert not torch.equal(mq[b, 0], quads[b, 0])


def test_partial_pose_mixing_keeps_each_images_own_elements_at_the_rest():
    own = torch.randn(8, 4000)  # 2 quadruplets
    mixed = quadruplet_mixer(torch.Generator().manual_seed(1), mixing=0.5)(own)
    quads, mq = own.view(2, 4, 4000), mixed.view(2, 4, 4000)
    for b in range(2):
        assert ((mq[b].unsqueeze(1) == quads[b].unsqueeze(0)).any(1)).all()  # every element from one of the four
        kept = (mq[b] == quads[b]).float().mean().item()
        assert kept == pytest.approx(0.5 + 0.5 * 0.25, abs=0.02)  # own when not mixed, or mixed onto itself
        assert not torch.equal(mq[b, 0], mq[b, 1])  # the four images no longer share one latent
    # mixing 1 is equation 3 and draws nothing more: a resumed run's draws do not change
    g1, g2 = torch.Generator().manual_seed(5), torch.Generator().manual_seed(5)
    torch.testing.assert_close(quadruplet_mixer(g1, mixing=1.0)(own), quadruplet_mixer(g2)(own))
    assert torch.equal(g1.get_state(), g2.get_state())


def test_partial_pose_mixing_is_a_probability_above_zero():
    for bad in (0.0, 1.5, -0.1):
        with pytest.raises(ValueError, match="losses.pose_mixing"):
            LossConfig(pose_mixing=bad).validate()
    LossConfig(pose_mixing=0.3).validate()
    with pytest.raises(ValueError, match="losses.pose_mixing.*pose_consistency=true"):
        LossConfig(pose_mixing=0.5, pose_consistency=False)


def test_cross_view_warmup_keeps_the_partner_translations_first():
    cfg = LossConfig(cross_view="own", cross_view_warmup=300)
    assert [cfg.cross_view_at(s) for s in (0, 299, 300, None)] == ["partner", "partner", "own", "own"]
    assert LossConfig().cross_view_at(10_000) == "partner"  # the paper's equation 4 by default


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


def test_objective_relocation_is_the_pull_of_the_spare_parts_of_the_own_view_render():
    """losses.relocation (issue 38): relocation_pull of the pose's agreed translations projected into each image,
    the own-view render's front parts and the image's keypoints; twelve parts at one anchor leave some spare."""
    _, scene, batch, _ = _setup()
    losses = LossConfig(recon=0, translation=0, background=0, smoothness=0, relocation=1.0)
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(num_parts=12, sphere_level=1, width=8, shape_latent_dim=8, depth_offset=2.5,
                                 anchor_spread=0.0))
    out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses, torch.Generator().manual_seed(0))
    from cerberus_core.losses import pose_consensus, relocation_pull
    images = batch.images.flatten(0, 1)
    pred = model(images)
    parts = model.pose(pred, batch.camera)  # the translations and keypoints do not see the mixed latent
    part_id = render_parts(make_renderer("torch"), out.parts.flatten(0, 1), model.faces, batch.camera).part_id
    uv, _ = batch.camera.project(pose_consensus(parts.translations.view(1, 4, -1, 3)).flatten(0, 1))
    fg = 1 - background_mask(batch.images[0], scene.background, losses.background_tolerance)
    expected = relocation_pull(uv.view(1, 4, -1, 2), part_id.view(1, 4, 32, 32), fg[None],
                               pred.maps.uv.view(1, 4, -1, 2)).mean()
    assert expected.item() > 0
    assert out.terms["relocation"].item() == pytest.approx(expected.item(), rel=1e-5)
    assert _grad_norm(model, out.total) > 0
    assert quadruplet_objective(model, make_renderer("torch"), batch, scene, LossConfig(),
                                torch.Generator().manual_seed(0)).terms["relocation"].item() == 0.0  # off: not computed


def test_loss_config_rejects_nan_weights():
    with pytest.raises(ValueError, match="losses.silhouette"):
        LossConfig(silhouette=float("nan")).validate()


def test_each_term_is_a_written_weight_field_of_the_loss_config_and_the_docs_show_the_table():
    """Each term is declared once, as a weight field of LossConfig (a class written out, so that a type checker
    and an IDE follow `losses.coverage`): TERM_TABLE is read from those fields, with the paper's weights as
    defaults and the range >= 0; docs/training.md shows terms_table()."""
    import ast
    import inspect
    import typing

    from cerberus_core.train import objective
    from cerberus_core.train.objective import TERM_TABLE, terms_table

    written = {node.name: node for node in ast.parse(inspect.getsource(objective)).body if isinstance(node, ast.ClassDef)}
    annotated = [n.target.id for n in written["LossConfig"].body if isinstance(n, ast.AnnAssign)]
    assert annotated[:len(TERM_TABLE)] == [t.name for t in TERM_TABLE]  # the terms, in logging order, then the switches
    assert typing.get_type_hints(LossConfig)["coverage"] is float and "make_dataclass" not in inspect.getsource(objective)

    assert LossConfig().weights == {t.name: t.weight for t in TERM_TABLE}
    assert [t.name for t in TERM_TABLE if t.paper] == ["recon", "translation", "background", "smoothness"]
    assert all(t.weight == 0 for t in TERM_TABLE if not t.paper)  # beyond the paper: off in its settings
    assert all(t.function.__module__ == "cerberus_core.losses" for t in TERM_TABLE)
    docs = (REPO / "docs" / "training.md").read_text()
    assert terms_table() in docs, "docs/training.md: paste cerberus_core.train.objective.terms_table() over its table"
    with pytest.raises(ValueError, match=r"losses.hidden = nan: must be a number >= 0"):
        LossConfig(hidden=float("nan")).validate()


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


def test_the_first_step_equals_the_one_before_the_speed_rewrites():
    """Issue 33 held to its reference formulas on a fixed batch, with the ``cpu`` preset's losses and
    anti-aliasing: the translation head's up-sampling as matrix products (against
    ``interpolate(mode="bilinear")``), the batched nearest-neighbour search of the pulls (against the
    per-image ``cdist`` loop) and the trimmed render glue give the same first-step loss to 1e-6 and
    the same gradient up to rounding."""
    import copy

    from cerberus_core.train.settings import load_config
    from tests.support.reference_ops import ReferenceTranslationHead, loop_search

    cfg = load_config(preset="cpu")
    _, scene, batch, _ = _setup()
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(num_parts=4, sphere_level=1, width=8, shape_latent_dim=8, depth_offset=2.5))
    reference = copy.deepcopy(model)
    head = model.translation
    reference.translation = ReferenceTranslationHead(head.logits.in_channels, 4, head.depth_offset)
    reference.translation.load_state_dict(head.state_dict())

    class LoopSearchRenderer(type(make_renderer("torch"))):
        def nearest_indices(self, points, targets, counts, both=True):
            return loop_search(points, targets, counts, both)

    out = []
    for net, renderer in ((model, make_renderer("torch")), (reference, LoopSearchRenderer())):
        res = quadruplet_objective(net, renderer, batch, scene, cfg.losses, torch.Generator().manual_seed(0),
                                   smoothness_once=True, antialias=cfg.render.antialias, step=0)
        grads = torch.autograd.grad(res.total, list(net.parameters()), allow_unused=True)
        out.append((res, torch.cat([g.flatten() for g in grads if g is not None])))
    (new, new_grad), (ref, ref_grad) = out
    assert new.terms["chamfer"] > 0 and new.terms["silhouette"] > 0
    assert abs(float(new.total.detach()) - float(ref.total.detach())) < 1e-6
    assert float((new_grad - ref_grad).norm() / ref_grad.norm()) < 1e-4


def _triangulated_by_hand(maps, camera, partner, triangulate, loss):
    """The triangulated-depth term of one quadruplet, image by image: each view's keypoint rays and its partner's."""
    depth, target, weight = maps.depth.view(1, 4, -1), torch.zeros(1, 4, maps.depth.shape[-1]), torch.zeros(1, 4)
    for k in range(4):
        pair = [k, partner[k]]
        cams = camera.index(pair)
        ends = cams.unproject(maps.uv[pair].detach(), torch.ones(2, maps.uv.shape[1]))
        rays = torch.nn.functional.normalize(ends - cams.center.unsqueeze(1), dim=-1)  # (2, N, 3)
        target[0, k] = camera.index([k]).project(triangulate(cams.center, rays).unsqueeze(0))[1][0]
        weight[0, k] = (1 - (rays[0] * rays[1]).sum(-1).square()).mean()
    return loss(depth, target, weight)


def test_objective_limb_terms_are_their_functions_of_the_objective_parts_and_off_when_unweighted():
    """Issue 30's terms: each is its function of the objective's own parts, keypoints and rotations,
    has a gradient without a renderer in the path, and is not computed at weight 0."""
    from cerberus_core.losses import (
        VIEW_PARTNER,
        body_translation_loss,
        part_overlap,
        part_separation,
        pose_consensus,
        rotation_loss,
        silhouette_coverage,
        triangulated_body_depth_loss,
    )
    from cerberus_core.render.camera import triangulate

    model, scene, batch, _ = _setup()
    with torch.no_grad():
        model.translation.coords.weight.zero_()  # every part starts at the image centre: stacked, so separation acts
    names = ("coverage", "keypoint_coverage", "overlap", "rotation", "consensus_coverage", "separation",
             "body_translation", "triangulated_depth")
    off = quadruplet_objective(model, make_renderer("torch"), batch, scene, LossConfig(), torch.Generator().manual_seed(0))
    assert all(off.terms[k].item() == 0.0 for k in names)
    fg = 1 - background_mask(batch.images[0], scene.background, LossConfig().background_tolerance)
    images = batch.images.flatten(0, 1)
    parts = model.pose(model(images), batch.camera)  # rotations and keypoints do not see the mixed latent
    uv, _ = batch.camera.project(off.parts.flatten(0, 1).flatten(1, 2))  # the rendered (mixed) parts
    expected = {"coverage": silhouette_coverage(uv, fg),
                "keypoint_coverage": silhouette_coverage(model(images).maps.uv, fg),
                "overlap": part_overlap(off.parts.flatten(0, 1)),
                "rotation": rotation_loss(parts.rotations.view(1, 4, *parts.rotations.shape[1:])),
                "consensus_coverage": silhouette_coverage(batch.camera.project(pose_consensus(
                    parts.translations.view(1, 4, -1, 3)).flatten(0, 1))[0], fg),
                "separation": part_separation(parts.translations),
                "body_translation": body_translation_loss(parts.translations.view(1, 4, -1, 3)),
                "triangulated_depth": _triangulated_by_hand(model(images).maps, batch.camera, VIEW_PARTNER,
                                                            triangulate, triangulated_body_depth_loss)}
    for name in names:
        losses = LossConfig(recon=0, translation=0, background=0, smoothness=0, **{name: 1.0})
        out = quadruplet_objective(model, make_renderer("torch"), batch, scene, losses, torch.Generator().manual_seed(0))
        assert out.terms[name].item() == pytest.approx(expected[name].mean().item(), rel=1e-5), name
        assert out.terms[name].item() > 0 and _grad_norm(model, out.total) > 0, name


def test_allocation_pulls_fade_over_allocation_steps_and_the_image_terms_do_not():
    """losses.allocation_steps (issue 38): the allocation pulls place the parts early, then leave training to the
    image terms; with 0 every weight is constant; the objective uses the step's weights."""
    losses = LossConfig(consensus_coverage=3.0, keypoint_coverage=1.0, separation=2.0, chamfer=0.1,
                        allocation_steps=1000)
    from cerberus_core.train.objective import TERM_TABLE

    assert {t.name for t in TERM_TABLE if t.allocation} == {"rigid_coverage", "keypoint_coverage", "consensus_coverage",
                                                             "separation", "relocation"}
    assert losses.weights_at(0) == losses.weights
    half = losses.weights_at(500)
    assert (half["consensus_coverage"], half["keypoint_coverage"], half["separation"]) == (1.5, 0.5, 1.0)
    assert half["chamfer"] == 0.1 and half["recon"] == 1.0
    assert losses.weights_at(5000)["consensus_coverage"] == 0.0 == losses.weights_at(None)["separation"]
    assert LossConfig(consensus_coverage=3.0).weights_at(10**6)["consensus_coverage"] == 3.0
    model, scene, batch, _ = _setup()
    with torch.no_grad():
        model.translation.coords.weight.zero_()
    cfg = LossConfig(recon=0, translation=0, background=0, smoothness=0, separation=1.0, allocation_steps=10)
    early = quadruplet_objective(model, make_renderer("torch"), batch, scene, cfg, torch.Generator().manual_seed(0),
                                 step=0)
    late = quadruplet_objective(model, make_renderer("torch"), batch, scene, cfg, torch.Generator().manual_seed(0),
                                step=10)
    assert early.terms["separation"] > 0 and float(early.total.detach()) > 0
    assert float(late.total) == 0.0


def test_the_network_sees_the_inputs_and_the_losses_compare_against_the_images():
    """``QuadrupletBatch.inputs`` (``data.input_look``) is what the model is given; the reconstruction targets and
    the background mask stay the stored images."""
    model, scene, batch, losses = _setup()
    looked = batch.images.flip(-2)  # another picture: its white background band at the bottom
    renderer, gen = make_renderer("torch"), lambda: torch.Generator().manual_seed(3)
    seeing = quadruplet_objective(model, renderer, QuadrupletBatch(batch.images, batch.camera, looked), scene, losses,
                                  gen())
    stored = quadruplet_objective(model, renderer, QuadrupletBatch(looked, batch.camera), scene, losses, gen())
    own = quadruplet_objective(model, renderer, batch, scene, losses, gen())
    torch.testing.assert_close(seeing.renders, stored.renders)  # the same input: the same parts
    assert not torch.allclose(seeing.renders, own.renders)
    assert seeing.terms["recon"] != stored.terms["recon"]  # ... compared against other targets
    assert seeing.terms["background"] != stored.terms["background"]  # ... and another background mask


def test_consensus_tips_join_the_consensus_pull_and_need_it():
    """``losses.consensus_tips`` changes only ``consensus_coverage`` (the k-means over keypoints and tips; the other
    terms as without it) and refuses to run without that pull."""
    from cerberus_core.errors import ConfigError

    model, scene, batch, _ = _setup(pose_consistency=False)

    def terms(**switches):
        losses = LossConfig(pose_consistency=False, consensus_coverage=1.0, **switches)
        return quadruplet_objective(model, make_renderer("torch"), batch, scene, losses).terms

    plain, tips = terms(), terms(consensus_tips=True)
    assert float(tips["consensus_coverage"]) != float(plain["consensus_coverage"])
    assert all(torch.equal(tips[k], plain[k]) for k in plain if k not in ("consensus_coverage", "total"))
    with pytest.raises(ConfigError, match=r"losses.consensus_tips = True: .*set losses.consensus_coverage=1.0"):
        LossConfig(consensus_tips=True).check()


def test_rigid_coverage_turns_and_moves_a_part_toward_a_missed_limb_and_leaves_its_shape_alone():
    """``losses.rigid_coverage`` (issue 38): a long part on the trunk below a raised arm that it misses. The coverage
    pull on its vertices with the shape held turns it toward the arm (about the camera-facing axis, +: toward +x) and
    moves it toward +x, and gives its vertices no gradient: the part swings instead of stretching."""
    import types

    from cerberus_core.datasets.scene import SceneSetup
    from cerberus_core.losses import nearest_indices
    from cerberus_core.parts import PartSet
    from cerberus_core.render.templates import icosphere
    from cerberus_core.train.objective import ObjectiveInputs, _rigid_coverage

    cam = SceneSetup(distance=2.5).cameras(torch.tensor([0.0, 40.0, 0.0, 40.0]), 32)
    body = [torch.tensor([0.0, y, 0.0]) for y in torch.linspace(-0.3, 0.3, 25)]  # the trunk, up to the shoulder
    body += [torch.tensor([x, 0.3, 0.0]) for x in torch.linspace(0.0, 0.4, 17)]  # the raised arm, along +x
    uv, _ = cam.project(torch.stack(body).expand(4, -1, 3))
    fg = torch.zeros(4, 32, 32)
    fg[torch.arange(4)[:, None], uv[..., 1].long(), uv[..., 0].long()] = 1
    template = icosphere(1)
    local = (template.vertices * torch.tensor([0.05, 0.3, 0.05])).expand(4, 1, -1, 3).clone().requires_grad_(True)
    angle = torch.zeros((), requires_grad=True)
    c, s, o = torch.cos(angle), torch.sin(angle), torch.zeros(())
    rot = torch.stack([torch.stack([c, s, o]), torch.stack([-s, c, o]), torch.stack([o, o, o + 1])]).expand(4, 1, 3, 3)
    t = torch.tensor([0.0, 0.1, 0.0]).expand(4, 1, 3).clone().requires_grad_(True)
    x = ObjectiveInputs(types.SimpleNamespace(camera=cam, num_quadruplets=1), None, PartSet(local, template.faces, rot, t),
                        1 - fg.view(4, 1, 32, 32), None, None, None, False, nearest_indices)  # no cross view
    loss = _rigid_coverage(x)
    assert loss.shape == (1,) and float(loss.detach()) > 0
    loss.sum().backward()
    assert float(angle.grad) < 0  # descending turns the part toward the arm
    assert t.grad[:, 0, 0].lt(0).all()  # ... and moves it toward +x in every view
    assert local.grad is None  # the shape is held: no stretching


def test_rigid_coverage_is_the_coverage_pull_whose_gradient_skips_the_shape_head():
    """The same value as ``losses.coverage`` (the same vertices, the same pull, in the input view and with
    ``losses.cross_pulls`` the cross view too), but the shape head gets no gradient from it, while the rotation and
    translation heads do; off (weight 0) it is not computed."""
    model, scene, batch, _ = _setup(pose_consistency=False)
    base = dict(pose_consistency=False, recon=0, translation=0, background=0, smoothness=0)
    values = []

    def run(**weights):
        out = quadruplet_objective(model, make_renderer("torch"), batch, scene, LossConfig(**base, **weights))
        model.zero_grad(set_to_none=True)
        out.total.backward()
        return out.terms, {name: sum(float(p.grad.abs().sum()) for p in head.parameters() if p.grad is not None)
                           for name, head in (("shape", model.shape), ("rotation", model.rotation),
                                              ("translation", model.translation))}

    for cross_pulls in (False, True):  # with cross_pulls both pulls also act on the cross view, averaged like eq. 4
        base.update(cross_pulls=cross_pulls, cross_view="own")
        rigid, rigid_grads = run(rigid_coverage=1.0)
        plain, plain_grads = run(coverage=1.0)
        assert float(rigid["rigid_coverage"]) == pytest.approx(float(plain["coverage"]), rel=1e-6)
        assert rigid_grads["shape"] == 0 and plain_grads["shape"] > 0
        assert rigid_grads["rotation"] > 0 and rigid_grads["translation"] > 0
        assert float(plain["rigid_coverage"]) == 0.0
        values.append(float(rigid["rigid_coverage"]))
    assert values[0] != pytest.approx(values[1], rel=1e-3)  # the cross view's pull joins in
