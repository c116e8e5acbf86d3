"""Visibility gradients: ``render(..., antialias=True)`` and :meth:`Renderer.antialias` on every backend.

* finite differences at silhouette pixels, where the plain barycentric renderer's gradient is exactly
  zero (an open triangle and a closed icosphere over a black background, image and alpha losses);
* every backend's ``antialias`` against the reference backend's on the same inputs (values 1e-5,
  gradients 1e-4 relative);
* ``antialias=False`` (the default) leaves the render exactly as before: the plain composite, a hard
  0/1 alpha without gradient;
* a silhouette fit: one sphere's translation and scale move towards a target mask with an alpha L2
  loss when antialiasing is on, and get no gradient when it is off.
"""
from __future__ import annotations

import pytest
import torch

from cerberus_core.render.api import pack_parts, render, render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.light import Light
from cerberus_core.render.templates import icosphere

from .scenes import body_scene, double_camera

STEP_AND_RTOL = {torch.float64: (1e-7, 1e-5), torch.float32: (1e-4, 3e-2)}
"""Finite-difference step (world units, far below a pixel so no pixel centre is crossed) and allowed
relative error per dtype."""


def _camera(size: int, dtype: torch.dtype) -> Camera:
    cam = Camera.look_at(torch.tensor([20.0]), 10.0, 2.5, image_size=size)
    return double_camera(cam) if dtype == torch.float64 else cam


def _scene(kind: str, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor, Camera]:
    """``(vertices (1, V, 3), faces, camera)``: one triangle (open: boundary edges) or a sphere."""
    camera = _camera(24, dtype)
    if kind == "triangle":
        # in the plane facing the camera at the origin, corners well inside the image
        right, up = camera.rotation[0, 0].to(torch.float64), camera.rotation[0, 1].to(torch.float64)
        corners = torch.stack([-0.31 * right - 0.23 * up, 0.27 * right - 0.29 * up, 0.04 * right + 0.33 * up])
        return corners.unsqueeze(0).to(dtype), torch.tensor([[0, 1, 2]]), camera
    sphere = icosphere(2)
    return (0.3 * sphere.vertices.to(torch.float64) + torch.tensor([0.02, -0.03, 0.01])).unsqueeze(0).to(dtype), \
        sphere.faces, camera


def _outline_weights(face_id: torch.Tensor, dtype: torch.dtype) -> tuple[torch.Tensor, torch.Tensor]:
    """Random weights on the background pixels next to the silhouette (``(1, 3, H, W)`` for the image)
    and on the silhouette's covered pixels (``(1, 1, H, W)`` for the alpha)."""
    fg = (face_id >= 0).to(torch.float64).unsqueeze(1)
    near_fg = torch.nn.functional.max_pool2d(fg, 3, stride=1, padding=1)
    near_bg = 1 - (-torch.nn.functional.max_pool2d(-fg, 3, stride=1, padding=1))
    g = torch.Generator().manual_seed(7)
    w_img = torch.rand(1, 3, *face_id.shape[1:], generator=g, dtype=torch.float64) * (near_fg * (1 - fg))
    w_alpha = torch.rand(1, 1, *face_id.shape[1:], generator=g, dtype=torch.float64) * (near_bg * fg)
    return w_img.to(dtype), w_alpha.to(dtype)


@pytest.mark.parametrize("kind", ["triangle", "sphere"])
def test_silhouette_gradient_matches_finite_differences(renderer, grad_dtype, kind: str) -> None:
    verts, faces, camera = _scene(kind, grad_dtype)
    light = Light.following(camera)
    with torch.no_grad():
        rest = render(renderer, verts, faces, camera, light)
    w_img, w_alpha = _outline_weights(rest.face_id, grad_dtype)
    assert w_img.count_nonzero() > 10 and w_alpha.count_nonzero() > 10

    def loss(v: torch.Tensor, antialias: bool) -> torch.Tensor:
        out = render(renderer, v, faces, camera, light, antialias=antialias)
        return (out.image * w_img).sum() + (out.alpha * w_alpha).sum()

    plain = verts.clone().requires_grad_(True)
    loss(plain, False).backward()
    assert plain.grad is None or plain.grad.abs().max() == 0, "the plain renderer has no silhouette gradient"

    v = verts.clone().requires_grad_(True)
    loss(v, True).backward()
    grad = v.grad
    assert torch.isfinite(grad).all() and grad.abs().max() > 0
    step, rtol = STEP_AND_RTOL[grad_dtype]
    g = torch.Generator().manual_seed(1)
    shift = torch.zeros_like(verts)
    shift[..., 0] = 1.0  # a translation along x
    one_vertex = torch.zeros_like(verts)
    one_vertex[0, 0] = torch.randn(3, generator=g, dtype=torch.float64).to(grad_dtype)  # a vertex alone
    for direction in (grad / grad.norm(), shift, one_vertex,
                      torch.randn(verts.shape, generator=g, dtype=torch.float64).to(grad_dtype)):
        with torch.no_grad():
            fd = float((loss(verts + step * direction, True) - loss(verts - step * direction, True)) / (2 * step))
        ad = float((grad * direction).sum())
        assert abs(fd - ad) <= rtol * max(abs(fd), 1e-3 * float(grad.norm())), (kind, fd, ad)


def test_antialias_matches_reference_backend(other_renderer, reference_renderer) -> None:
    parts, faces, camera = body_scene(3, image_size=64, seed=31)
    vertices, packed, _ = pack_parts(parts, faces)
    clip0 = camera.world_to_clip(vertices).detach()
    with torch.no_grad():
        face_id = reference_renderer.rasterize(clip0, packed, camera.height, camera.width, camera.near)
    g = torch.Generator().manual_seed(2)
    color0 = torch.rand(*face_id.shape, 4, generator=g)
    cot = torch.randn(*face_id.shape, 4, generator=g)
    results = []
    for r in (other_renderer, reference_renderer):
        clip, color = clip0.clone().requires_grad_(True), color0.clone().requires_grad_(True)
        out = r.antialias(color, clip, packed, face_id)
        (out * cot).sum().backward()
        results.append((out.detach(), color.grad, clip.grad))
    (a, ga_col, ga_clip), (b, gb_col, gb_clip) = results
    assert (a != color0).any(dim=-1).sum() > 100, "the scene must have silhouettes to blend"
    torch.testing.assert_close(a, b, rtol=0, atol=1e-5)
    for x, y in ((ga_col, gb_col), (ga_clip, gb_clip)):
        assert float((x - y).norm()) <= 1e-4 * float(y.norm())
        torch.testing.assert_close(x, y, rtol=1e-3, atol=1e-4 * float(y.abs().max()))


def test_antialias_off_is_the_plain_render(renderer) -> None:
    parts, faces, camera = body_scene(2, image_size=48, seed=4)
    bg = (0.1, 0.2, 0.3)
    p = parts.clone().requires_grad_(True)
    out = render_parts(renderer, p, faces, camera, background=bg)
    off = render_parts(renderer, p, faces, camera, background=bg, antialias=False)
    for what in ("image", "alpha", "depth", "face_id", "part_id"):
        assert torch.equal(getattr(out, what), getattr(off, what)), what
    # the plain composite of the backend's own shading, bit for bit
    vertices, packed, _ = pack_parts(parts, faces)
    clip = camera.world_to_clip(vertices)
    with torch.no_grad():
        face_id = renderer.rasterize(clip, packed, camera.height, camera.width, camera.near)
        rgb, _ = renderer.shade(clip, packed, face_id, renderer.vertex_normals(vertices, packed),
                                torch.tensor([0.8, 0.8, 0.8]).expand(*vertices.shape), Light.following(camera))
    alpha = (face_id >= 0).float().unsqueeze(-1)
    expected = (rgb + (1 - alpha) * torch.tensor(bg).view(1, 1, 1, 3)).permute(0, 3, 1, 2)
    assert torch.equal(out.image.detach(), expected)
    assert torch.equal(out.alpha, alpha.permute(0, 3, 1, 2)) and not out.alpha.requires_grad
    on = render_parts(renderer, p, faces, camera, background=bg, antialias=True)
    soft = (on.alpha > 0) & (on.alpha < 1)
    assert soft.sum() > 50 and on.alpha.requires_grad
    assert torch.equal(on.depth, out.depth) and torch.equal(on.face_id, out.face_id)


@pytest.mark.parametrize("antialias", [True, False])
def test_silhouette_fit_moves_towards_target(renderer, antialias: bool) -> None:
    sphere = icosphere(2)
    camera = _camera(32, torch.float32)
    target_centre, target_scale = torch.tensor([0.12, -0.08, 0.05]), 0.3
    with torch.no_grad():
        target = render_parts(renderer, (target_scale * sphere.vertices + target_centre).view(1, 1, -1, 3),
                              sphere.faces, camera).alpha
    centre = torch.zeros(3, requires_grad=True)
    log_scale = torch.tensor(0.22).log().requires_grad_(True)
    opt = torch.optim.Adam([centre, log_scale], lr=0.01)

    def mismatch() -> float:
        """Pixels where the hard masks of the current and the target sphere differ."""
        with torch.no_grad():
            parts = (log_scale.exp() * sphere.vertices + centre).view(1, 1, -1, 3)
            return float((render_parts(renderer, parts, sphere.faces, camera).alpha != target).sum())

    def offset() -> float:
        """Distance in NDC between the projected centres of the current and the target sphere."""
        with torch.no_grad():
            clip = camera.world_to_clip(torch.stack([centre, target_centre]).unsqueeze(0))[0]
            ndc = clip[:, :2] / clip[:, 3:]
            return float((ndc[0] - ndc[1]).norm())

    start, start_offset = mismatch(), offset()
    assert start > 50
    for _ in range(40):
        opt.zero_grad()
        parts = (log_scale.exp() * sphere.vertices + centre).view(1, 1, -1, 3)
        out = render_parts(renderer, parts, sphere.faces, camera, antialias=antialias)
        loss = (out.alpha - target).square().sum()
        if not antialias:
            assert not loss.requires_grad, "a hard mask has no gradient: the fit cannot move"
            return
        loss.backward()
        opt.step()
    # depth and scale trade off in a silhouette: hold the fit to the mask and the projected centre
    assert mismatch() < 0.2 * start, (start, mismatch())
    assert offset() < 0.2 * start_offset, (start_offset, offset())
