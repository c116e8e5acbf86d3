"""The fused Warp antialiasing against core's torch reference: values and gradients in float32 and
float64, and the CUDA thread layout on the CPU."""
from __future__ import annotations

import pytest
import torch

from cerberus_core.render.antialias import antialias as reference_antialias
from cerberus_render_warp import _runtime as runtime
from cerberus_render_warp import antialias, rasterize
from tests.support.scenes import clip_scene


def _run(fn, clip0, faces, face_id, color0, cot):
    clip, color = clip0.clone().requires_grad_(True), color0.clone().requires_grad_(True)
    out = fn(color, clip, faces, face_id)
    (out * cot).sum().backward()
    return out.detach(), color.grad, clip.grad


def _inputs(dtype, size=40, seed=3):
    clip, faces, _, cam = clip_scene(3, 9, size, seed=seed, radius=0.15, dtype=dtype)
    face_id = rasterize(clip, faces, cam.height, cam.width, cam.near)
    g = torch.Generator().manual_seed(seed)
    color = torch.rand(*face_id.shape, 4, generator=g, dtype=torch.float64).to(dtype)
    cot = torch.randn(*face_id.shape, 4, generator=g, dtype=torch.float64).to(dtype)
    return clip.detach(), faces, face_id, color, cot


@pytest.mark.parametrize("dtype, rtol", [(torch.float32, 1e-5), (torch.float64, 1e-12)])
def test_matches_reference(dtype, rtol) -> None:
    clip, faces, face_id, color, cot = _inputs(dtype)
    a = _run(antialias, clip, faces, face_id, color, cot)
    b = _run(reference_antialias, clip, faces, face_id, color, cot)
    assert (a[0] != color).any(-1).sum() > 50
    for x, y in zip(a, b, strict=True):
        assert x.dtype == dtype
        assert float((x - y).norm()) <= rtol * float(y.norm())


def test_cuda_thread_layout_on_cpu(monkeypatch) -> None:
    inputs = _inputs(torch.float32, size=24, seed=5)
    per_row = _run(antialias, *inputs)
    monkeypatch.setattr(runtime, "ONE_ITEM_PER_THREAD", True)
    per_pixel = _run(antialias, *inputs)
    for x, y in zip(per_row, per_pixel, strict=True):
        torch.testing.assert_close(x, y, rtol=1e-6, atol=1e-6)  # atomics may sum in another order


def test_no_silhouette_is_identity() -> None:
    clip, faces, face_id, color, cot = _inputs(torch.float32, size=16)
    empty = torch.full_like(face_id, -1)
    out, g_color, g_clip = _run(antialias, clip, faces, empty, color, cot)
    assert torch.equal(out, color) and torch.equal(g_color, cot) and not g_clip.any()
