"""The fused Warp shading against core's torch reference: values, gradients, kinks and options."""
from __future__ import annotations

import pytest
import torch

from cerberus_core.render.light import Light
from cerberus_core.render.shading import shade as reference_shade
from cerberus_render_warp import rasterize, shade
from tests.support.scenes import shading_inputs

Tensor = torch.Tensor


def _leaves(clip, normals, albedo, light) -> list[Tensor]:
    return [clip, normals, albedo, light.direction, light.ambient, light.diffuse]


def _run(fn, inputs, g_rgb: Tensor | None, g_depth: Tensor | None):
    """Forward with ``fn``; gradients of ``<rgb, g_rgb> + <depth, g_depth>`` w.r.t. every leaf."""
    clip, faces, face_id, normals, albedo, light = inputs
    rgb, depth = fn(clip, faces, face_id, normals, albedo, light)
    loss = 0
    if g_rgb is not None:
        loss = loss + (rgb * g_rgb).sum()
    if g_depth is not None:
        loss = loss + (depth * g_depth).sum()
    leaves = _leaves(clip, normals, albedo, light)
    grads = torch.autograd.grad(loss, leaves, allow_unused=True)
    return rgb.detach(), depth.detach(), grads


def _cotangents(face_id: Tensor, dtype: torch.dtype) -> tuple[Tensor, Tensor]:
    g = torch.Generator().manual_seed(5)
    shape = face_id.shape
    return (torch.randn(*shape, 3, generator=g, dtype=torch.float64).to(dtype),
            torch.randn(*shape, generator=g, dtype=torch.float64).to(dtype))


@pytest.mark.parametrize("dtype, rtol", [(torch.float32, 1e-4), (torch.float64, 1e-10)])
def test_values_and_gradients_match_reference(dtype: torch.dtype, rtol: float) -> None:
    inputs = shading_inputs(3, (24, 20), dtype=dtype)
    face_id = inputs[2]
    assert (face_id >= 0).any() and (face_id < 0).any()
    g_rgb, g_depth = _cotangents(face_id, dtype)
    rgb, depth, grads = _run(shade, inputs, g_rgb, g_depth)
    ref_rgb, ref_depth, ref_grads = _run(reference_shade, inputs, g_rgb, g_depth)
    assert rgb.dtype == depth.dtype == dtype
    assert torch.allclose(rgb, ref_rgb, rtol=0, atol=1e-5) and torch.allclose(depth, ref_depth, rtol=0, atol=1e-5)
    assert (rgb[face_id < 0] == 0).all() and (depth[face_id < 0] == 0).all()
    names = ["clip", "normals", "albedo", "direction", "ambient", "diffuse"]
    for name, ours, ref in zip(names, grads, ref_grads, strict=False):
        scale = ref.abs().max()
        assert scale > 0, name
        assert ((ours - ref).abs().max() / scale) < rtol, name
    assert (grads[0][..., 2] == 0).all(), "clip z does not enter the shading"


def test_gradcheck_float64() -> None:
    # Two triangles of a tilted quad (different w per vertex) filling most of an 8x8 image.
    g = torch.Generator().manual_seed(2)
    clip = torch.tensor([[[-0.9, -0.8, 0.0, 1.0], [1.5, -1.2, 0.0, 1.6], [-1.1, 1.3, 0.0, 1.4],
                          [1.6, 1.5, 0.0, 1.9]]], dtype=torch.float64).requires_grad_(True)
    faces = torch.tensor([[0, 1, 2], [2, 1, 3]])
    face_id = rasterize(clip.detach(), faces, 8, 8, 0.05)
    assert set(face_id.unique().tolist()) >= {0, 1}
    normals = torch.nn.functional.normalize(torch.randn(1, 4, 3, generator=g, dtype=torch.float64) + 2.0, dim=-1)
    albedo = torch.rand(1, 4, 3, generator=g, dtype=torch.float64)
    direction = torch.nn.functional.normalize(torch.tensor([[0.3, 0.4, 1.0]], dtype=torch.float64), dim=-1)
    ambient, diffuse = torch.rand(2, 1, 3, generator=g, dtype=torch.float64)
    leaves = [t.detach().clone().requires_grad_(True) for t in (clip, normals, albedo, direction, ambient, diffuse)]

    def fn(clip, normals, albedo, direction, ambient, diffuse):
        return shade(clip, faces, face_id, normals, albedo, Light(direction, ambient, diffuse))

    assert torch.autograd.gradcheck(fn, leaves, eps=1e-6, atol=1e-7, rtol=1e-5)


def test_backlit_pixels_have_zero_diffuse_gradient() -> None:
    clip, faces, face_id, normals, albedo, light = shading_inputs(2, 16, backlit=False)
    light = Light((-light.direction.detach()).requires_grad_(True), light.ambient, light.diffuse)
    # Camera-facing surfaces lit from behind: n . l < 0 on (nearly) every visible pixel.
    inputs = (clip, faces, face_id, normals, albedo, light)
    g_rgb, _ = _cotangents(face_id, torch.float64)
    _, _, grads = _run(shade, inputs, g_rgb, None)
    _, _, ref = _run(reference_shade, inputs, g_rgb, None)
    for ours, theirs in zip(grads, ref, strict=False):
        assert torch.allclose(ours, theirs, rtol=1e-9, atol=1e-12)
    assert grads[5].abs().max() < 0.05 * grads[4].abs().max(), "diffuse barely matters when back-lit"


def test_zero_normals_follow_normalize_eps() -> None:
    clip, faces, face_id, normals, albedo, light = shading_inputs(1, 12, backlit=False)
    normals = torch.zeros_like(normals).requires_grad_(True)
    inputs = (clip, faces, face_id, normals, albedo, light)
    g_rgb, _ = _cotangents(face_id, torch.float64)
    rgb, _, grads = _run(shade, inputs, g_rgb, None)
    ref_rgb, _, ref = _run(reference_shade, inputs, g_rgb, None)
    assert torch.equal(rgb, ref_rgb)
    scale = ref[1].abs().max()
    assert scale > 1e6  # 1 / eps
    assert ((grads[1] - ref[1]).abs().max() / scale) < 1e-12


@pytest.mark.parametrize("which", ["rgb", "depth"])
def test_one_output_used(which: str) -> None:
    inputs = shading_inputs(2, 16, dtype=torch.float32)
    g_rgb, g_depth = _cotangents(inputs[2], torch.float32)
    args = (g_rgb, None) if which == "rgb" else (None, g_depth)
    _, _, grads = _run(shade, inputs, *args)
    _, _, ref = _run(reference_shade, inputs, *args)
    for ours, theirs in zip(grads, ref, strict=False):
        if theirs is None:
            continue
        assert ((ours - theirs).abs().max() / theirs.abs().max().clamp_min(1e-30)) < 1e-4


def test_only_requested_gradients_and_strided_inputs() -> None:
    clip, faces, face_id, normals, albedo, light = shading_inputs(2, 16, dtype=torch.float32)
    albedo = torch.tensor([0.2, 0.5, 0.9]).expand(albedo.shape)  # expanded view, no gradient
    fixed = Light(light.direction.detach(), light.ambient.detach(), light.diffuse.detach())
    rgb, depth = shade(clip, faces, face_id, normals.detach(), albedo, fixed)
    ref_rgb, _ = reference_shade(clip, faces, face_id, normals.detach(), albedo, fixed)
    assert torch.allclose(rgb, ref_rgb, atol=1e-5, rtol=0)
    grad_out = torch.randn(2, 3, 16, 16).permute(0, 2, 3, 1)  # non-contiguous cotangent
    (g_clip,) = torch.autograd.grad((rgb * grad_out).sum(), [clip])
    (ref_clip,) = torch.autograd.grad((ref_rgb * grad_out).sum(), [clip])
    assert ((g_clip - ref_clip).abs().max() / ref_clip.abs().max()) < 1e-4
