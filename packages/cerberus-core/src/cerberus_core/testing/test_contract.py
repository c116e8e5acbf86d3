"""The rasterization rule of ``cerberus_core.render.interface``, checked on hand-made clip-space
triangles whose edge functions are exact in float32 (dyadic coordinates), so no tolerance is needed."""
from __future__ import annotations

import torch

H = W = 8
# Pixel centres of an 8x8 image sit at NDC (2j + 1) / 8 - 1: exact binary fractions.
LOWER_LEFT = [(-7 / 8, -7 / 8), (7 / 8, -7 / 8), (-7 / 8, 7 / 8)]
"""A triangle whose three edges pass exactly through pixel centres: covers (row i, col j) iff j <= i."""


def _clip(tri_ndc, w: float) -> torch.Tensor:
    """``(3, 4)`` clip coordinates of NDC vertices at clip ``w`` (z unused by the rule)."""
    return torch.tensor([[x * w, y * w, 0.0, w] for x, y in tri_ndc], dtype=torch.float32)


def _raster(renderer, *tris: torch.Tensor, height: int = H, width: int = W, near: float = 0.05) -> torch.Tensor:
    clip = torch.cat(tris).unsqueeze(0)
    faces = torch.arange(clip.shape[1], dtype=torch.int64).view(-1, 3)
    fid = renderer.rasterize(clip, faces, height, width, near)
    assert fid.shape == (1, height, width) and fid.dtype == torch.int64
    return fid[0]


def _lower_left_mask() -> torch.Tensor:
    i, j = torch.meshgrid(torch.arange(H), torch.arange(W), indexing="ij")
    return j <= i


def test_edges_through_pixel_centres_are_included(renderer) -> None:
    fid = _raster(renderer, _clip(LOWER_LEFT, 1.0))
    assert torch.equal(fid >= 0, _lower_left_mask())
    assert set(fid.unique().tolist()) == {-1, 0}


def test_perspective_division_and_no_backface_culling(renderer) -> None:
    reversed_winding = list(reversed(LOWER_LEFT))
    for w in (0.5, 3.0):
        for tri in (LOWER_LEFT, reversed_winding):
            assert torch.equal(_raster(renderer, _clip(tri, w)) >= 0, _lower_left_mask()), (w, tri)


def test_nearest_face_wins_and_exact_ties_pick_smallest_id(renderer) -> None:
    far, near_a, near_b = _clip(LOWER_LEFT, 4.0), _clip(LOWER_LEFT, 2.0), _clip(LOWER_LEFT, 2.0)
    fid = _raster(renderer, far, near_b, near_a)  # faces 1 and 2 tie at w = 2, in front of face 0
    assert set(fid[_lower_left_mask()].tolist()) == {1}
    fid = _raster(renderer, near_a, far)
    assert set(fid[_lower_left_mask()].tolist()) == {0}


def test_triangles_reaching_the_near_plane_are_dropped_whole(renderer) -> None:
    tri = _clip(LOWER_LEFT, 1.0)
    tri[2, 3] = 0.04  # one vertex in front of the near plane 0.05 ...
    tri[2, :2] = torch.tensor([-7 / 8, 7 / 8]) * 0.04
    assert (_raster(renderer, tri) == -1).all()
    tri[2, 3] = -1.0  # ... or behind the camera
    assert (_raster(renderer, tri) == -1).all()


def test_degenerate_and_offscreen_triangles_cover_nothing(renderer) -> None:
    line = _clip([(-0.5, -0.5), (0.0, 0.0), (0.5, 0.5)], 1.0)  # collinear: zero area
    point = _clip([(1 / 8, 1 / 8)] * 3, 1.0)
    outside = _clip([(1.5, 1.5), (3.0, 1.5), (1.5, 3.0)], 1.0)
    assert (_raster(renderer, line, point, outside) == -1).all()


def test_non_square_image_and_pixel_centre_convention(renderer) -> None:
    # A small triangle around the centre of pixel (row 1, col 5) of a 4x8 image only.
    cx, cy = (2 * 5 + 1) / 8 - 1, 1 - (2 * 1 + 1) / 4
    tri = _clip([(cx - 0.1, cy - 0.1), (cx + 0.1, cy - 0.1), (cx, cy + 0.1)], 2.0)
    fid = _raster(renderer, tri, height=4, width=8)
    expected = torch.full((4, 8), -1, dtype=torch.int64)
    expected[1, 5] = 0
    assert torch.equal(fid, expected)


def test_batch_scenes_are_independent(renderer) -> None:
    a = _clip(LOWER_LEFT, 1.0)
    b = _clip([(x, -y) for x, y in LOWER_LEFT], 1.0)  # mirrored: covers j <= 7 - i
    clip = torch.stack([a, b])
    fid = renderer.rasterize(clip, torch.tensor([[0, 1, 2]]), H, W, 0.05)
    assert torch.equal(fid[0] >= 0, _lower_left_mask())
    assert torch.equal(fid[1] >= 0, _lower_left_mask().flip(0))
