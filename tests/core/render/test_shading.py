"""The shared shading terms (cerberus_core.render.shading): Lambert's clamp, and one pixel-centre rule in
every dtype."""
from __future__ import annotations

import torch

from cerberus_core.render.shading import lambert


def test_lambert_clamps_back_facing_light() -> None:
    n = torch.tensor([[0.0, 0.0, 2.0], [0.0, 0.0, -1.0], [0.0, 0.6, 0.8]])
    light = torch.tensor([0.0, 0.0, 1.0]).expand(3, 3)
    albedo = torch.tensor([0.5, 1.0, 0.2]).expand(3, 3)
    rgb = lambert(n, albedo, light, torch.full((3, 3), 0.3), torch.full((3, 3), 0.6))
    torch.testing.assert_close(rgb, albedo * torch.tensor([[0.9], [0.3], [0.3 + 0.6 * 0.8]]))


def test_one_pixel_centre_rule_in_every_dtype():
    """The shared shading and the rasterizers take pixel centres from one function, in the scene's dtype."""
    from cerberus_core.render.camera import pixel_centres
    from cerberus_core.render.shading import pixel_ndc

    for dtype in (torch.float32, torch.float64):
        px, py = pixel_centres(4, 6, dtype)
        assert px.dtype == py.dtype == dtype and px.shape == (6,) and py.shape == (4,)
        torch.testing.assert_close(px, (2 * torch.arange(6, dtype=dtype) + 1) / 6 - 1, rtol=0, atol=0)
        torch.testing.assert_close(py, 1 - (2 * torch.arange(4, dtype=dtype) + 1) / 4, rtol=0, atol=0)
        rows, cols = torch.tensor([0, 3]), torch.tensor([5, 1])
        p = pixel_ndc(4, 6, rows, cols, dtype)
        assert p.dtype == dtype
        assert torch.equal(p, torch.stack([px[cols], py[rows], torch.ones(2, dtype=dtype)], -1))
