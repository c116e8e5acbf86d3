"""The shape, rotation and translation heads; equation 1 (translation = unprojected expectation)."""
import math

import pytest
import torch

from cerberus_core.errors import ShapeError
from cerberus_core.model.heads import (
    RotationHead,
    ShapeHead,
    TranslationHead,
    anchor_grid,
    expectation,
    unproject_expectation,
)
from cerberus_core.render.camera import Camera
from cerberus_core.render.templates import icosphere
from tests.support.reference_ops import reference_keypoint_maps


def test_shape_head_shapes_and_initial_sphere():
    t = icosphere(2)
    head = ShapeHead(512, 64, 9, t.vertices, init_scale=0.12)
    s = head.latent(torch.randn(3, 512))
    assert s.shape == (3, 64)
    verts = head.deform(s)
    assert verts.shape == (3, 9, 162, 3)
    radius = verts.norm(dim=-1)
    assert torch.allclose(radius, torch.full_like(radius, 0.12), atol=0.01)


def test_bounded_shape_head_starts_at_the_template_and_never_leaves_the_box():
    t = icosphere(2)
    head = ShapeHead(16, 8, 1, t.vertices, init_scale=0.3, displacement_scale=0.05, vertex_bound=0.5)
    torch.nn.init.zeros_(head.to_displacement.weight)
    s = head.latent(torch.randn(2, 16))
    assert torch.allclose(head.deform(s), 0.3 * t.vertices.expand(2, 1, -1, -1), atol=1e-6)
    torch.nn.init.normal_(head.to_displacement.weight, std=1e3)  # displacements of hundreds of units
    s = head.latent(torch.randn(2, 16))
    v = head.deform(s)
    assert v.abs().max() <= 0.5 and torch.isfinite(v).all()  # tanh may round to 1 in float32
    v.sum().backward()
    assert torch.isfinite(head.to_displacement.weight.grad).all()
    # Small displacements pass almost unchanged (slope 1 - (t/b)^2 of tanh at the template).
    torch.manual_seed(0)  # the draw below must not depend on which tests ran before
    unbounded = ShapeHead(16, 8, 1, t.vertices, init_scale=0.3, displacement_scale=0.05)
    bounded = ShapeHead(16, 8, 1, t.vertices, init_scale=0.3, displacement_scale=0.05, vertex_bound=0.5)
    bounded.load_state_dict(unbounded.state_dict())
    with torch.no_grad():
        z = unbounded.latent(torch.randn(1, 16))
        d_unb = unbounded.deform(z) - unbounded.template
        d_b = bounded.deform(z) - bounded.template
    slope = 1 - (unbounded.template / 0.5) ** 2
    assert 0 < d_unb.abs().max() < 1e-3
    assert torch.allclose(d_b, d_unb * slope, rtol=0.02, atol=1e-3 * float(d_unb.abs().max()))
    with pytest.raises(ValueError, match="must exceed init_scale"):
        ShapeHead(16, 8, 1, t.vertices, init_scale=0.3, vertex_bound=0.3)


def test_recentred_shape_head_keeps_each_part_on_its_translation():
    """model.recentre (issue 38): a displacement that shifts a whole part is taken back out, so the part's
    vertex mean stays at its local origin (where its translation puts it), while its shape still deforms."""
    t = icosphere(2)
    torch.manual_seed(0)
    free = ShapeHead(16, 8, 3, t.vertices, init_scale=0.12, displacement_scale=0.05)
    centred = ShapeHead(16, 8, 3, t.vertices, init_scale=0.12, displacement_scale=0.05, recentre=True)
    centred.load_state_dict(free.state_dict())
    with torch.no_grad():
        free.to_displacement.bias.view(3, -1, 3)[:, :, 0] += 1.0  # every vertex of every part 0.05 to the right
        centred.to_displacement.bias.copy_(free.to_displacement.bias)
        s = free.latent(torch.randn(2, 16))
        v_free, v_centred = free.deform(s), centred.deform(s)
    assert float(v_free.mean(-2)[..., 0].min()) > 0.04  # the free head shifts the parts
    assert float(v_centred.mean(-2).abs().max()) < 1e-6  # the recentred one keeps them on their origin
    torch.testing.assert_close(v_centred, v_free - v_free.mean(-2, keepdim=True))  # same shape, recentred
    bounded = ShapeHead(16, 8, 3, t.vertices, init_scale=0.12, vertex_bound=0.2, recentre=True)
    with torch.no_grad():
        assert float(bounded.deform(s).mean(-2).abs().max()) < 1e-6


def test_axis_scales_start_as_the_spheres_and_their_gradient_stretches_the_axis_a_loss_asks_for():
    """model.axis_scales (issue 38): zero at the start (the head without them, bit for bit, every other weight drawn
    as without the switch from one seed), a loss that wants the parts longer along their first local axis gives
    the first axis' scale a descent direction that grows it and none to the other two; one step of gradient
    descent stretches every vertex alike (an ellipsoid, not a spike), and the scales stay within a quarter and
    four times however far the latent pushes them."""
    t = icosphere(2)
    torch.manual_seed(0)
    plain = ShapeHead(16, 8, 3, t.vertices, init_scale=0.12, displacement_scale=0.05)
    torch.manual_seed(0)
    head = ShapeHead(16, 8, 3, t.vertices, init_scale=0.12, displacement_scale=0.05, axis_scales=True)
    assert all(torch.equal(v, plain.state_dict()[k]) for k, v in head.state_dict().items() if k in plain.state_dict())
    s = plain.latent(torch.randn(2, 16)).detach()
    assert torch.equal(head.deform(s), plain.deform(s))
    v = head.deform(s)
    loss = -(v[..., 0] ** 2).mean()  # longer along x
    loss.backward()
    g = head.to_axes.bias.grad.view(3, 3)
    assert bool((g[:, 0] < 0).all())  # descent grows the first axis of every part
    assert float(g[:, 1:].abs().max()) == 0.0
    with torch.no_grad():
        head.to_axes.bias -= 2.0 * head.to_axes.bias.grad.sign()  # a sign step, as Adam takes
    v1 = head.deform(s).detach()
    ratio = v1[..., 0] / v.detach()[..., 0]
    big = v.detach()[..., 0].abs() > 0.05  # away from x = 0, where the tiny displacements dominate the ratio
    assert float(ratio[big].min()) > 1.05 and float(ratio[big].max() - ratio[big].min()) < 0.01  # every vertex alike
    with torch.no_grad():
        head.to_axes.bias.fill_(1e6)
        bounded = ShapeHead(16, 8, 3, t.vertices, init_scale=0.12, vertex_bound=0.3, axis_scales=True)
        bounded.to_axes.bias.fill_(1e6)
    assert torch.allclose(head.axes(s), torch.full((2, 3, 3), 4.0))
    w = bounded.deform(s)
    assert torch.isfinite(w).all() and float(w.detach().abs().max()) <= 0.3  # the bound holds the ellipsoid too
    assert torch.allclose(head.axes(s, gain=0.0), torch.ones(2, 3, 3))  # a deformation hold holds the axes too


def test_deformation_warmup_keeps_the_template_spheres_then_deforms():
    """model.deformation_warmup (issue 38): before step S the parts are the template spheres and the displacement map
    gets no gradient (a part can cover the body only by moving); from step S on, and for a trained model (step
    None), the deformation is the full one, bit for bit, as without a hold."""
    from cerberus_core.model.cerberus import Cerberus, ModelConfig
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(num_parts=2, width=4, shape_latent_dim=8, depth_offset=2.0, deformation_warmup=100))
    with torch.no_grad():
        model.shape.to_displacement.bias.normal_(std=1.0)  # a visible deformation
    images = torch.rand(2, 3, 32, 32)
    full, held = model(images).local_vertices, model(images, step=99).local_vertices
    torch.testing.assert_close(held, model.shape.template.expand_as(full))
    assert not torch.allclose(full, held)
    assert torch.equal(model(images, step=100).local_vertices, full)
    held.sum().backward()
    assert float(model.shape.to_displacement.weight.grad.abs().max()) == 0.0
    paper = Cerberus(ModelConfig(num_parts=2, width=4, shape_latent_dim=8, depth_offset=2.0))
    paper.load_state_dict(model.state_dict())
    assert torch.equal(paper(images, step=0).local_vertices, full)  # no hold: every step deforms fully


def test_rotation_head_unit_quaternions_identity_init_and_valid_rotations():
    head = RotationHead(32, 5)
    q, r = head(torch.randn(4, 32))
    assert q.shape == (4, 5, 4) and r.shape == (4, 5, 3, 3)
    assert torch.allclose(q.norm(dim=-1), torch.ones(4, 5), atol=1e-6)
    assert torch.allclose(r, torch.eye(3).expand_as(r), atol=0.05)  # starts near the identity
    with torch.no_grad():
        head.linear.weight.normal_()
    _, r = head(torch.randn(4, 32))
    eye = torch.eye(3).expand_as(r)
    assert torch.allclose(r @ r.transpose(-1, -2), eye, atol=1e-5)
    assert torch.allclose(torch.linalg.det(r), torch.ones(4, 5), atol=1e-5)


def test_local_rotation_starts_as_the_paper_and_reads_only_what_lies_under_its_own_map():
    """model.local_rotation (issue 38): the model starts as without it, bit for bit (the new map is zeros and draws
    nothing from the random stream); a loss on one part's quaternion gives its own map a descent direction that
    lowers the loss, none to the other parts' maps, and reaches only the feature cells under the part's keypoint
    map; the keypoint maps are read, not moved (no gradient to the translation head from the rotation)."""
    from cerberus_core.model.cerberus import Cerberus, ModelConfig
    from cerberus_core.model.heads import cell_shares, features_under
    torch.manual_seed(0)
    paper = Cerberus(ModelConfig(num_parts=3, width=4, shape_latent_dim=8, depth_offset=2.0))
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(num_parts=3, width=4, shape_latent_dim=8, depth_offset=2.0, local_rotation=True))
    assert set(model.state_dict()) - set(paper.state_dict()) == {"rotation.local"}
    assert all(torch.equal(v, model.state_dict()[k]) for k, v in paper.state_dict().items())
    images = torch.rand(2, 3, 32, 32)
    assert torch.equal(model(images).rotations, paper(images).rotations)

    head = RotationHead(6, 2, local_dim=4)
    prob = torch.zeros(1, 2, 16, 16)
    prob[0, 0, 2:4, 2:4] = 0.25  # part 0 in the top-left corner, part 1 in the bottom-right
    prob[0, 1, 12:14, 12:14] = 0.25
    features = torch.randn(1, 4, 8, 8, requires_grad=True)
    target = torch.tensor([0.0, 1.0, 0.0, 0.0])  # half a turn about x
    latent = torch.randn(1, 6)
    q, _ = head(latent, features_under(prob, features))
    loss = (q[0, 0] - target).square().sum()
    loss.backward()
    g = head.local.grad
    assert float(g[0].abs().sum()) > 0 and float(g[1].abs().max()) == 0.0  # part 0's map only
    with torch.no_grad():
        head.local -= 0.01 * g
        q1, _ = head(latent, features_under(prob, features))
        assert float((q1[0, 0] - target).square().sum()) < float(loss)  # a descent direction
        head.local.normal_()
        head.local.normal_()
    q, _ = head(torch.zeros(1, 6), features_under(prob, features))
    features.grad = None
    (q[0, 0] - target).square().sum().backward()
    under = cell_shares(prob, (8, 8))[0, 0] > 0
    reached = features.grad[0].abs().sum(0) > 0
    assert bool(reached.any()) and torch.equal(reached, under)  # the cells under part 0's map, and no other
    with pytest.raises(ShapeError, match="features_under"):
        head(torch.randn(1, 6))

    with torch.no_grad():
        model.rotation.local.normal_()
    model(images).quaternions[:, 0].sum().backward()
    assert model.rotation.local.grad.abs().sum() > 0
    assert model.translation.logits.weight.grad is None or float(model.translation.logits.weight.grad.abs().max()) == 0


def test_quaternions_are_real_part_first():
    """(w, x, y, z) = (cos 45, 0, 0, sin 45) is +90 degrees about +z: x maps to y (kornia's convention)."""
    head = RotationHead(1, 1)
    with torch.no_grad():
        head.linear.weight.zero_()
        head.linear.bias.copy_(torch.tensor([math.cos(math.pi / 4), 0, 0, math.sin(math.pi / 4)]) * 3.0)
    _, r = head(torch.zeros(1, 1))
    assert torch.allclose(r[0, 0] @ torch.tensor([1.0, 0, 0]), torch.tensor([0.0, 1, 0]), atol=1e-6)


def test_anchor_grid_starts_central_and_spreads():
    torch.testing.assert_close(anchor_grid(1, 0.4), torch.zeros(1, 2))
    g = anchor_grid(9, 0.4)
    assert g.shape == (9, 2) and torch.equal(g[0], torch.zeros(2))
    assert len({tuple(p) for p in g.tolist()}) == 9 and g.abs().max() == pytest.approx(0.4)


def test_translation_head_starts_each_part_at_its_anchor():
    head = TranslationHead(16, 4, depth_offset=2.5, anchor_spread=0.4)
    with torch.no_grad():
        head.logits.weight.zero_()
    maps = head(torch.randn(1, 16, 16, 16), (64, 64))
    anchors_px = (anchor_grid(4, 0.4) + 1) * 32  # normalised -> pixels
    # a broad Gaussian bump inside a bounded image: the expectation lies between centre and anchor
    direction = (maps.uv[0] - 32) / (anchors_px - 32)
    assert ((direction > 0.3) & (direction < 1.0)).all()
    flat = TranslationHead(16, 4, depth_offset=2.5, anchor_spread=0.0)
    with torch.no_grad():
        flat.logits.weight.zero_()
    torch.testing.assert_close(flat(torch.randn(1, 16, 16, 16), (64, 64)).uv, torch.full((1, 4, 2), 32.0))


def test_translation_head_maps_shapes_and_depth_init():
    head = TranslationHead(16, 9, depth_offset=2.5)
    maps = head(torch.randn(2, 16, 8, 8), (32, 32))
    assert maps.prob.shape == (2, 9, 32, 32)
    assert maps.depth_map.shape == (2, 9, 32, 32)
    assert maps.uv.shape == (2, 9, 2) and maps.depth.shape == (2, 9)
    assert torch.allclose(maps.prob.sum(dim=(-2, -1)), torch.ones(2, 9), atol=1e-5)
    assert torch.allclose(maps.depth, torch.full((2, 9), 2.5))
    assert ((maps.uv >= 0) & (maps.uv <= 32)).all()


def test_translation_head_body_depth_shifts_every_part_alike_and_starts_at_zero():
    """model.body_depth (issue 38): one depth shift per image from its global latent, the same for every part;
    zero at the start, so a new model predicts what the paper's head does; a loss on one part's depth teaches it."""
    torch.manual_seed(0)
    plain = TranslationHead(16, 5, depth_offset=2.5)
    head = TranslationHead(16, 5, depth_offset=2.5, body_depth_from=12)
    head.load_state_dict(plain.state_dict(), strict=False)
    features, latent = torch.randn(3, 16, 8, 8), torch.randn(3, 12)
    torch.testing.assert_close(head(features, (32, 32), latent).depth, plain(features, (32, 32)).depth)
    head(features, (32, 32), latent).depth[:, 0].sum().backward()  # a pull on part 0's depth alone
    assert head.body_depth.bias.grad.item() == pytest.approx(3.0)  # d(sum of 3 images' depth)/d(shift)
    with torch.no_grad():
        head.body_depth.bias.fill_(0.1)
        head.body_depth.weight.copy_(torch.linspace(-1, 1, 12))
    shifted = head(features, (32, 32), latent).depth - plain(features, (32, 32)).depth  # (3, 5)
    expected = (0.1 + latent @ torch.linspace(-1, 1, 12)).unsqueeze(1).expand(3, 5)
    torch.testing.assert_close(shifted, expected, atol=1e-5, rtol=0)
    with pytest.raises(ShapeError, match="global latent"):
        head(features, (32, 32))


def _camera(batch=2, size=(24, 32)):
    return Camera.look_at(torch.tensor([20.0, -65.0])[:batch], 15.0, 2.7, fov_y_deg=35.0, image_size=size)


def test_equation1_translation_is_unprojection_of_expected_pixel_and_depth():
    """T_k = pi^{-1}(sum x p, sum y p, sum d p), with x, y the pixel centres (j + 0.5, i + 0.5)."""
    g = torch.Generator().manual_seed(0)
    h, w = 24, 32
    prob = torch.softmax(torch.randn(2, 3, h * w, generator=g), -1).view(2, 3, h, w)
    depth = 2.0 + torch.rand(2, 3, h, w, generator=g)
    cam = _camera(2, (h, w))
    maps = expectation(prob, depth)
    rows, cols = torch.meshgrid(torch.arange(h) + 0.5, torch.arange(w) + 0.5, indexing="ij")
    u = (prob * cols).sum(dim=(-2, -1))
    v = (prob * rows).sum(dim=(-2, -1))
    d = (prob * depth).sum(dim=(-2, -1))
    expected_cam = cam.unproject(torch.stack([u, v], -1), d, to_world=False)
    expected_world = cam.unproject(torch.stack([u, v], -1), d, to_world=True)
    torch.testing.assert_close(unproject_expectation(maps, cam, to_world=False), expected_cam)
    torch.testing.assert_close(unproject_expectation(maps, cam, to_world=True), expected_world)


def test_equation1_one_hot_map_projects_back_to_its_pixel():
    h, w = 24, 32
    prob = torch.zeros(2, 1, h, w)
    prob[0, 0, 5, 7] = 1.0
    prob[1, 0, 20, 30] = 1.0
    depth = torch.full((2, 1, h, w), 2.4)
    cam = _camera(2, (h, w))
    t = unproject_expectation(expectation(prob, depth), cam, to_world=True)
    uv, d = cam.project(t)
    torch.testing.assert_close(uv, torch.tensor([[[7.5, 5.5]], [[30.5, 20.5]]]), atol=1e-4, rtol=0)
    torch.testing.assert_close(d, torch.full((2, 1), 2.4), atol=1e-5, rtol=0)


def test_unproject_expectation_checks_camera_size():
    maps = expectation(torch.full((1, 1, 8, 8), 1 / 64), torch.ones(1, 1, 8, 8))
    with pytest.raises(ValueError, match="does not match"):
        unproject_expectation(maps, _camera(1, (16, 16)), to_world=True)


@pytest.mark.parametrize("dtype", [torch.float64, torch.float32])
def test_translation_head_upsamples_by_matrices_exactly_as_bilinear_interpolation(dtype):
    """The up-sampling as two products with fixed matrices, and the expected depth on the cells, equal
    the reference formula (values and gradients, up to rounding: float64 to 1e-12, float32 keypoints
    to 1e-4 px)."""
    torch.manual_seed(0)
    head = TranslationHead(8, 5, depth_offset=2.5).to(dtype)
    torch.nn.init.normal_(head.depth.weight, std=0.2)  # a depth map that varies
    features = torch.randn(3, 8, 16, 16, dtype=dtype, requires_grad=True)
    maps = head(features, (64, 64))
    prob, depth_map, uv, depth = reference_keypoint_maps(head, features, (64, 64))
    tol = {"atol": 1e-12, "rtol": 0} if dtype == torch.float64 else {"atol": 1e-5, "rtol": 1e-5}
    torch.testing.assert_close(maps.prob, prob, **tol)
    torch.testing.assert_close(maps.depth_map, depth_map, **tol)
    torch.testing.assert_close(maps.depth, depth, **tol)
    torch.testing.assert_close(maps.uv, uv, atol=1e-12 if dtype == torch.float64 else 1e-4, rtol=0)
    g = torch.Generator().manual_seed(1)
    weights = [torch.randn(t.shape, generator=g, dtype=dtype) for t in (prob, uv, depth)]
    inputs = [features, head.logits.weight, head.coords.weight, head.depth.weight, head.depth.bias]

    def grads(*outs):
        return torch.autograd.grad(sum((o * wt).sum() for o, wt in zip(outs, weights, strict=True)), inputs)

    for new, ref in zip(grads(maps.prob, maps.uv, maps.depth), grads(prob, uv, depth), strict=True):
        torch.testing.assert_close(new, ref, atol=1e-10 if dtype == torch.float64 else 1e-4, rtol=1e-5)


def test_upsample_bilinear_is_interpolate_for_any_sizes():
    from cerberus_core.model.heads import upsample_bilinear

    x = torch.randn(2, 3, 7, 5, dtype=torch.float64)
    for size in ((28, 20), (13, 9), (7, 5)):
        expected = torch.nn.functional.interpolate(x, size=size, mode="bilinear", align_corners=False)
        torch.testing.assert_close(upsample_bilinear(x, size), expected, atol=1e-12, rtol=0)


def test_a_narrow_anchor_width_starts_each_part_on_its_anchor_and_spreads_them():
    """The default bump (as wide as the grid) starts the outer parts at ~0.35 of the half-image for a
    grid of 0.4 or 0.7 alike; with `anchor_width` narrower, a part starts on its anchor."""
    def start(spread, width):
        head = TranslationHead(16, 9, depth_offset=2.5, anchor_spread=spread, anchor_width=width)
        with torch.no_grad():
            head.logits.weight.zero_()
        return head(torch.randn(1, 16, 16, 16), (64, 64)).uv[0] / 32 - 1  # normalised
    wide, narrow = start(0.7, None), start(0.7, 0.15)
    torch.testing.assert_close(narrow, anchor_grid(9, 0.7), atol=0.02, rtol=0)
    assert wide.abs().max() < 0.4 < 0.65 < narrow.abs().max()
    torch.testing.assert_close(start(0.4, None), start(0.4, 0.4))  # None: as wide as the grid, as before


def test_root_part_is_the_single_mesh_in_the_world_frame_and_the_other_parts_are_unchanged():
    """model.root_part (issue 38): part 0 starts as NMRr's sphere (radius 0.3, bounded by 0.5) and keeps the identity
    world rotation in every view, while the other parts are the model's without the switch, bit for bit (same
    tensors, no draw from the random stream); a loss on the root's world vertices gives the rotation head nothing
    and the shape head a descent direction; one part alone is refused."""
    from cerberus_core.errors import ConfigError
    from cerberus_core.model.cerberus import Cerberus, ModelConfig
    from cerberus_core.model.heads import ROOT_INIT_SCALE, ROOT_VERTEX_BOUND
    torch.manual_seed(0)
    paper = Cerberus(ModelConfig(num_parts=3, width=4, shape_latent_dim=8, depth_offset=2.83))
    torch.manual_seed(0)
    model = Cerberus(ModelConfig(num_parts=3, width=4, shape_latent_dim=8, depth_offset=2.83, root_part=True))
    assert all(torch.equal(v, model.state_dict()[k]) for k, v in paper.state_dict().items())
    assert set(model.state_dict()) == set(paper.state_dict())
    images = torch.rand(2, 3, 32, 32)
    camera = Camera.look_at(torch.tensor([30.0, 120.0]), torch.tensor([15.0, 5.0]), 2.83, image_size=32)
    with torch.no_grad():
        model.rotation.linear.weight.normal_()  # turned parts, so a world rotation shows
        paper.rotation.linear.weight.copy_(model.rotation.linear.weight)
    pred, ref = model(images), paper(images)
    radius = pred.local_vertices.norm(dim=-1)
    assert torch.allclose(radius[:, 0], torch.full_like(radius[:, 0], ROOT_INIT_SCALE), atol=0.01)
    assert torch.equal(pred.local_vertices[:, 1:], ref.local_vertices[:, 1:])
    r_world, t_world, r_cam, _ = model.world_pose(pred, camera)
    p_world, p_t, p_cam, _ = paper.world_pose(ref, camera)
    assert torch.equal(r_world[:, 0], torch.eye(3).expand(2, 3, 3)) and torch.equal(r_cam[:, 0], camera.rotation)
    assert torch.equal(r_world[:, 1:], p_world[:, 1:]) and torch.equal(r_cam[:, 1:], p_cam[:, 1:])
    assert not torch.allclose(p_world[:, 0], torch.eye(3).expand(2, 3, 3), atol=1e-3)  # the paper's part 0 turns
    assert torch.equal(t_world, p_t)

    with torch.no_grad():  # the root stays inside NMRr's bound, however far the map pushes it; the others do not
        model.shape.to_displacement.bias.fill_(50.0)
        far = model(images).local_vertices
        model.shape.to_displacement.bias.zero_()
    assert float(far[:, 0].abs().max()) < ROOT_VERTEX_BOUND and float(far[:, 1:].abs().max()) > 1.0

    target = 1.3 * model(images).local_vertices[:, 0].detach()  # a larger root, in the world (its frame)
    model.zero_grad()
    pred = model(images)
    parts = model.pose(pred, camera)
    loss = (parts.posed()[:, 0] - (target + parts.translations[:, :1, None].detach())).square().mean()
    loss.backward()
    g = model.rotation.linear.weight.grad.view(3, 4, -1)
    assert float(g[0].abs().max()) == 0.0  # the root's quaternion is not used
    with torch.no_grad():
        w = model.shape.to_displacement.weight
        w -= 1e-2 * w.grad / w.grad.abs().max()
        parts = model.pose(model(images), camera)
        after = (parts.posed()[:, 0] - (target + parts.translations[:, :1, None])).square().mean()
    assert float(after) < float(loss.detach())

    with pytest.raises(ConfigError, match="model.root_part .* needs model.num_parts >= 2"):
        ModelConfig(num_parts=1, root_part=True).check()
