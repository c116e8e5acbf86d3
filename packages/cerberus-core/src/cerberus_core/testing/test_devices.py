"""Every backend on CUDA against itself on the CPU: the same scene moved to the GPU renders the same
face ids (up to pixel-centre ties), images, masks and depths within 1e-4, and vertex gradients within
1e-3 relative; the outputs stay on the input's device. Skipped without a CUDA device."""
from __future__ import annotations

import pytest
import torch

from cerberus_core.render.api import render_parts
from cerberus_core.viz import part_colors

from .scenes import body_scene

pytestmark = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")


def test_cuda_render_matches_cpu(renderer) -> None:
    parts, faces, camera = body_scene(batch=3, image_size=64, seed=31)
    colours = part_colors(parts.shape[1])
    g = torch.Generator().manual_seed(5)
    w_img = torch.rand(parts.shape[0], 3, camera.height, camera.width, generator=g)
    inputs, outs = [], []
    for device in ("cpu", "cuda"):
        p = parts.detach().to(device).requires_grad_(True)
        out = render_parts(renderer, p, faces.to(device), camera.to(device), albedo=colours,
                           background=(0.1, 0.2, 0.3))
        assert out.image.device.type == device and out.face_id.device.type == device
        inputs.append(p)
        outs.append(out)
    cpu, gpu = outs
    same = cpu.face_id == gpu.face_id.cpu()
    assert (~same).sum() <= max(1, 0.002 * same.numel()), f"{int((~same).sum())} pixels show another face"
    for what in ("image", "alpha", "depth"):
        x, y = getattr(cpu, what), getattr(gpu, what).cpu()
        m = same.unsqueeze(1).expand_as(x)
        torch.testing.assert_close(y[m], x[m], rtol=0, atol=1e-4, msg=lambda s, w=what: f"{w}: {s}")
    weights = w_img * same.unsqueeze(1)  # gradients compared where both show the same face
    grads = []
    for p, out in zip(inputs, outs, strict=True):
        (out.image * weights.to(p.device)).sum().backward()
        grads.append(p.grad.cpu())
    scale = grads[0].abs().max()
    assert scale > 0
    err = (grads[1] - grads[0]).abs().max() / scale
    assert err <= 1e-3, f"vertex gradients differ by {float(err):.2e} of the largest entry"
