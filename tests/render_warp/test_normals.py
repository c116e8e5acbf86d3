"""The Warp vertex normals against core's torch version, and the CPU thread split of launches."""
from __future__ import annotations

import pytest
import torch

from cerberus_core import Light, make_renderer, render_parts
from cerberus_core.render.api import pack_parts
from cerberus_core.render.templates import vertex_normals as core_vertex_normals
from cerberus_render_warp import vertex_normals
from tests.support.scenes import part_scene


@pytest.mark.parametrize("dtype, rtol", [(torch.float32, 1e-5), (torch.float64, 1e-12)])
def test_matches_core_vertex_normals(dtype: torch.dtype, rtol: float) -> None:
    parts, faces, _ = part_scene(3, 4, 16, seed=1, dtype=dtype)
    vertices, packed, _ = pack_parts(parts, faces)
    g = torch.Generator().manual_seed(0)
    vertices = (vertices + 0.02 * torch.randn(vertices.shape, generator=g, dtype=dtype)).requires_grad_(True)
    cot = torch.randn(vertices.shape, generator=g, dtype=dtype)
    ours = vertex_normals(vertices, packed)
    ref = core_vertex_normals(vertices, packed)
    assert (ours - ref).abs().max() < 10 * rtol
    (g_ours,) = torch.autograd.grad((ours * cot).sum(), [vertices])
    (g_ref,) = torch.autograd.grad((ref * cot).sum(), [vertices])
    assert ((g_ours - g_ref).abs().max() / g_ref.abs().max()) < rtol


def test_isolated_vertex_gets_zero_normal_and_gradient() -> None:
    vertices = torch.tensor([[[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [5, 5, 5]]], requires_grad=True)
    faces = torch.tensor([[0, 1, 2]])
    n = vertex_normals(vertices, faces)
    assert torch.equal(n[0, 3], torch.zeros(3)) and torch.allclose(n[0, :3], torch.tensor([0.0, 0, 1]).expand(3, 3))
    n.sum().backward()
    assert torch.equal(vertices.grad[0, 3], torch.zeros(3))


def test_thread_split_gives_identical_results() -> None:
    parts, faces, cam = part_scene(6, 9, 32, seed=3)
    renderer = make_renderer("warp")
    results = []
    threads = torch.get_num_threads()
    try:
        for n in (1, 3):
            torch.set_num_threads(n)
            p = parts.clone().requires_grad_(True)
            out = render_parts(renderer, p, faces, cam, Light.following(cam))
            (out.image.square().sum() + out.depth.sum()).backward()
            vertices, packed, _ = pack_parts(p, faces)
            results.append((out.face_id, out.image.detach(), p.grad, vertex_normals(vertices.detach(), packed)))
    finally:
        torch.set_num_threads(threads)
    for a, b in zip(*results, strict=False):
        assert torch.equal(a, b)


def test_cuda_thread_layout_gives_identical_results(monkeypatch) -> None:
    # One Warp thread per pixel / face / vertex, as on CUDA, run here on the CPU.
    import cerberus_render_warp._runtime as runtime

    parts, faces, cam = part_scene(3, 9, 24, seed=8)
    renderer = make_renderer("warp")

    def run():
        p = parts.clone().requires_grad_(True)
        vertices, packed, _ = pack_parts(p, faces)
        normals = vertex_normals(vertices, packed)
        clip = cam.world_to_clip(vertices)
        face_id = renderer.rasterize(clip.detach(), packed, cam.height, cam.width, cam.near)
        light = Light.following(cam)
        rgb, depth = renderer.shade(clip, packed, face_id, normals, torch.full_like(vertices, 0.7), light)
        (rgb.square().sum() + depth.sum()).backward()
        return rgb.detach(), depth.detach(), p.grad

    per_scene = run()
    monkeypatch.setattr(runtime, "ONE_ITEM_PER_THREAD", True)
    per_item = run()
    for a, b in zip(per_scene, per_item, strict=False):
        assert torch.equal(a, b)
