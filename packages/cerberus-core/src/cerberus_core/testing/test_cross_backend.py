"""Every backend against the reference backend (torch) on the same float32 scenes: face ids identical
except exact depth ties (and pixel centres on an edge), images, masks and depths within 1e-5,
vertex gradients within 1e-4 relative. Skipped when only the reference backend is installed."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from cerberus_core.render.api import pack_parts, render_parts
from cerberus_core.viz import part_colors

from .reference import explain_mismatches
from .scenes import body_scene

ATOL = 1e-5
GRAD_RTOL = 1e-4
SCENES = {"body-64": dict(batch=4, image_size=64, seed=21), "body-48x80": dict(batch=2, image_size=(48, 80), seed=22)}


def _agreement(a, b, parts: torch.Tensor, faces: torch.Tensor, camera) -> torch.Tensor:
    """``(B, H, W)`` bool where the two renders show the same face; fails on unexplained differences."""
    differ = a.face_id != b.face_id
    _, packed, _ = pack_parts(parts, faces)
    verts = parts.reshape(parts.shape[0], -1, 3)
    clip = camera.world_to_clip(verts).double().numpy()
    h, w = camera.height, camera.width
    for s in range(parts.shape[0]):
        rows, cols = np.nonzero(differ[s].numpy())
        ia, ib = a.face_id[s].numpy()[rows, cols], b.face_id[s].numpy()[rows, cols]
        ok = explain_mismatches(clip[s], packed.numpy(), h, w, camera.near, rows, cols, ia, ib)
        bad = [(int(r), int(c), int(x), int(y)) for r, c, x, y, k in zip(rows, cols, ia, ib, ok, strict=False) if not k]
        assert not bad, f"scene {s}: face ids differ at (row, col, backend, reference) {bad[:5]}"
    assert differ.sum() <= max(1, 0.005 * differ.numel()), f"{int(differ.sum())} edge/tie disagreements"
    return ~differ


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_forward_matches_reference_backend(other_renderer, reference_renderer, scene: str) -> None:
    parts, faces, camera = body_scene(**SCENES[scene])
    colours = part_colors(parts.shape[1])
    a = render_parts(other_renderer, parts, faces, camera, albedo=colours, background=(0.1, 0.2, 0.3))
    b = render_parts(reference_renderer, parts, faces, camera, albedo=colours, background=(0.1, 0.2, 0.3))
    same = _agreement(a, b, parts, faces, camera)
    for what in ("image", "alpha", "depth"):
        x, y = getattr(a, what), getattr(b, what)
        assert x.shape == y.shape and x.dtype == y.dtype, what
        m = same.unsqueeze(1).expand_as(x)
        torch.testing.assert_close(x[m], y[m], rtol=0, atol=ATOL, msg=lambda s, w=what: f"{w}: {s}")
    assert torch.equal(a.part_id[same], b.part_id[same])


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_gradients_match_reference_backend(other_renderer, reference_renderer, scene: str) -> None:
    parts, faces, camera = body_scene(**SCENES[scene])
    with torch.no_grad():
        same = _agreement(render_parts(other_renderer, parts, faces, camera),
                          render_parts(reference_renderer, parts, faces, camera), parts, faces, camera)
    g = torch.Generator().manual_seed(3)
    w_img = torch.rand(parts.shape[0], 3, camera.height, camera.width, generator=g) * same.unsqueeze(1)
    w_dep = torch.rand(parts.shape[0], 1, camera.height, camera.width, generator=g) * same.unsqueeze(1)
    grads = []
    for r in (other_renderer, reference_renderer):
        p = parts.clone().requires_grad_(True)
        out = render_parts(r, p, faces, camera)
        ((out.image * w_img).sum() + 0.1 * (out.depth * w_dep).sum()).backward()
        assert torch.isfinite(p.grad).all()
        grads.append(p.grad)
    scale = grads[1].abs().max()
    assert scale > 0
    err = (grads[0] - grads[1]).abs().max() / scale
    assert err <= GRAD_RTOL, f"vertex gradients differ by {float(err):.2e} of the largest entry"
