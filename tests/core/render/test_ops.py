"""The rendering ops as free functions (cerberus_core.render.ops): composed, they are render(); each
runs on every installed backend; interpolate is perspective-correct and differentiable."""
import pytest
import torch

from cerberus_core import Camera, Light, icosphere, make_renderer
from cerberus_core.render import ops, render
from cerberus_core.render.backends import available_renderers


@pytest.mark.parametrize("backend", available_renderers())
def test_the_ops_composed_are_render(backend):
    ctx = make_renderer(backend)
    cam = Camera.look_at(torch.tensor([20.0, 140.0]), 10.0, 2.5, image_size=32)
    sphere = icosphere(2)
    v = (0.4 * sphere.vertices + torch.tensor([0.05, 0.0, 0.0])).expand(2, -1, -1).contiguous()
    light = Light.following(cam)
    clip = cam.world_to_clip(v)
    face_id = ops.rasterize(ctx, clip, sphere.faces, (32, 32), cam.near)
    rgb, depth = ops.shade(ctx, clip, sphere.faces, face_id, ops.vertex_normals(ctx, v, sphere.faces),
                           torch.full_like(v, 0.8), light)
    alpha = (face_id >= 0).float()[..., None]
    rgba = ops.antialias(ctx, torch.cat([rgb, alpha], -1), clip, sphere.faces, face_id)
    out = render(ctx, v, sphere.faces, cam, light, antialias=True)
    assert torch.equal(out.face_id, face_id)
    torch.testing.assert_close(out.image.permute(0, 2, 3, 1), rgba[..., :3])
    torch.testing.assert_close(out.alpha.permute(0, 2, 3, 1), rgba[..., 3:])
    torch.testing.assert_close(out.depth[:, 0], depth)


def test_interpolate_gives_the_surface_point_under_each_pixel_and_its_gradient():
    ctx = make_renderer("torch")
    cam = Camera.look_at(30.0, 10.0, 2.5, image_size=24)
    sphere = icosphere(2)
    v = (0.4 * sphere.vertices[None]).requires_grad_()
    clip = cam.world_to_clip(v)
    face_id = ops.rasterize(ctx, clip, sphere.faces, (24, 24), cam.near)
    xyz = ops.interpolate(v, clip, sphere.faces, face_id)  # (1, H, W, 3) world points
    covered = face_id >= 0
    assert xyz.shape == (1, 24, 24, 3) and covered.sum() > 100
    assert (xyz[~covered] == 0).all()
    # each covered pixel's point lies on the (faceted) sphere, at the depth the shading reports
    radius = xyz[covered].norm(dim=-1)
    assert ((radius > 0.37) & (radius <= 0.4 + 1e-5)).all()
    _, depth = ops.shade(ctx, clip, sphere.faces, face_id, ops.vertex_normals(ctx, v, sphere.faces),
                         torch.full_like(v, 0.8), Light.following(cam))
    view_depth = -(cam.world_to_camera(xyz.view(1, -1, 3)).view(1, 24, 24, 3)[..., 2])
    torch.testing.assert_close(view_depth[covered], depth[covered], atol=1e-4, rtol=0)
    xyz[covered].sum().backward()
    assert v.grad.abs().sum() > 0


def _scene():
    ctx = make_renderer("torch")
    cam = Camera.look_at(30.0, 10.0, 2.5, image_size=16)
    sphere = icosphere(1)
    v = 0.4 * sphere.vertices[None]
    return ctx, cam, sphere.faces, v, cam.world_to_clip(v)


@pytest.mark.parametrize(("call", "error", "words"), [
    (lambda ctx, c, f, v: ops.rasterize(ctx, c * float("inf"), f, (16, 16), 0.05), "MeshError",
     "42 clip-space vertices are NaN or inf"),
    (lambda ctx, c, f, v: ops.rasterize(ctx, c, f + 1000, (16, 16), 0.05), "MeshError",
     r"faces index vertices outside 0..41 \(they reach 1000..1041\)"),
    (lambda ctx, c, f, v: ops.vertex_normals(ctx, v, -f - 1), "MeshError", "faces index vertices outside 0..41"),
    (lambda ctx, c, f, v: ops.interpolate(v, c, f, torch.full((1, 16, 16), 10**6)), "MeshError",
     r"face_id names faces outside -1..79"),
    (lambda ctx, c, f, v: ops.rasterize(ctx, c, f, (100_000, 100_000), 0.05), "ConfigError",
     r"resolution = \(100000, 100000\): needs at least .* of memory \(1 images of 100000x100000 pixels\)"),
    (lambda ctx, c, f, v: ops.rasterize(ctx, c, f, 16, 0.05), "RenderInputError",
     r"resolution is 16; pass `resolution=\(height, width\)`, two integers"),
    (lambda ctx, c, f, v: ops.rasterize(ctx, c, f, ("a", "b"), 0.05), "RenderInputError", "resolution is"),
    (lambda ctx, c, f, v: ops.rasterize(None, c, f, (16, 16), 0.05), "InputTypeError",
     "rasterize: ctx is NoneType, not a renderer backend"),
    (lambda ctx, c, f, v: ops.shade("torch", c, f, None, v, v, None), "InputTypeError", "shade: ctx is str"),
], ids=["inf-clip", "faces-range", "negative-faces", "face-id-range", "huge-resolution", "one-number", "text",
        "no-backend", "backend-name"])
def test_each_op_refuses_what_its_backend_cannot_draw(call, error, words):
    """Issue 34 campaign: these reached the backend and ended in an IndexError (an inf vertex gave a pixel index of
    -2**63), an 80 GB allocation, or a TypeError/AttributeError naming nothing."""
    import cerberus_core.errors as errors

    ctx, cam, faces, v, clip = _scene()
    with pytest.raises(getattr(errors, error), match=words):
        call(ctx, clip, faces, v)
