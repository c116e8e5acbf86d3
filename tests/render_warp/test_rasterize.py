"""The Warp rasterizer against the torch backend: identical face ids, on both of its code paths."""
from __future__ import annotations

import pytest
import torch

from cerberus_render_torch import rasterize as torch_rasterize
from cerberus_render_warp import rasterize
from tests.support.scenes import clip_scene


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
@pytest.mark.parametrize("size", [(64, 64), (37, 53)])
def test_face_ids_identical_to_torch_backend(dtype: torch.dtype, size: tuple[int, int]) -> None:
    clip, faces, _, cam = clip_scene(6, 9, size, seed=3, dtype=dtype)
    ours = rasterize(clip, faces, cam.height, cam.width, cam.near)
    ref = torch_rasterize(clip, faces, cam.height, cam.width, cam.near)
    assert ours.dtype == torch.int64 and ours.shape == (6, *size)
    assert 0.05 < (ref >= 0).float().mean() < 0.5, "the scene should cover part of the image"
    assert torch.equal(ours, ref)


def test_serial_and_parallel_paths_agree_and_break_ties_by_smallest_id() -> None:
    clip, faces, _, cam = clip_scene(4, 9, 48, seed=5)
    doubled = torch.cat([faces, faces.flip(0)])  # every triangle twice: exact depth ties everywhere
    serial = rasterize(clip, doubled, 48, 48, cam.near, serial=True)
    parallel = rasterize(clip, doubled, 48, 48, cam.near, serial=False)
    assert torch.equal(serial, parallel)
    assert torch.equal(serial, torch_rasterize(clip, doubled, 48, 48, cam.near))
    assert int(serial.max()) < faces.shape[0], "ties must go to the first copy (smaller face id)"
    assert torch.equal(serial, rasterize(clip, faces, 48, 48, cam.near))


def test_shared_edges_through_pixel_centres_leave_no_gaps() -> None:
    # A 5x5 grid of quads whose vertices sit exactly on pixel centres of a 16x16 image, seen at
    # perspective depth: every pixel centre inside the grid is covered, including those on edges.
    n, size = 5, 16
    idx = torch.arange(2, 2 + 2 * (n + 1), 2)[: n + 1]
    xs = (2 * idx.double() + 1) / size - 1
    gy, gx = torch.meshgrid(-xs, xs, indexing="ij")
    w = 1.5 + 0.25 * gx  # tilted plane: w varies across the grid
    clip = torch.stack([gx * w, gy * w, torch.zeros_like(w), w], -1).reshape(1, -1, 4).float()
    v = torch.arange((n + 1) ** 2).view(n + 1, n + 1)
    a, b, c, d = v[:-1, :-1], v[:-1, 1:], v[1:, :-1], v[1:, 1:]
    faces = torch.cat([torch.stack([a, c, b], -1).reshape(-1, 3), torch.stack([b, c, d], -1).reshape(-1, 3)])
    fid = rasterize(clip, faces, size, size, 0.05)
    assert torch.equal(fid, torch_rasterize(clip, faces, size, size, 0.05))
    lo, hi = int(idx[0]), int(idx[-1])
    assert (fid[0, lo:hi + 1, lo:hi + 1] >= 0).all()
    outside = torch.ones(size, size, dtype=torch.bool)
    outside[lo:hi + 1, lo:hi + 1] = False
    assert (fid[0][outside] == -1).all()


def test_degenerate_behind_and_huge_triangles() -> None:
    tris = torch.tensor([
        [[-0.5, -0.5, 0, 1], [0.0, 0.0, 0, 1], [0.5, 0.5, 0, 1]],        # collinear
        [[0.1, 0.1, 0, 1], [0.1, 0.1, 0, 1], [0.3, -0.2, 0, 1]],         # repeated vertex
        [[-0.5, -0.5, 0, -1], [0.5, -0.5, 0, -1], [0.0, 0.5, 0, -1]],    # behind the camera
        [[-0.5, -0.5, 0, 1], [0.5, -0.5, 0, 1], [0.0, 0.5, 0, 0.01]],    # crosses the near plane
        [[-1e30, -1e30, 0, 1], [1e30, -1e30, 0, 1], [0.0, 1e30, 0, 1]],  # huge: edge functions overflow
        [[-3e3, -3e3, 0, 2], [3e3, -3e3, 0, 2], [0.0, 3e3, 0, 2]],       # large, covers the image
    ], dtype=torch.float32).view(1, -1, 4)
    faces = torch.arange(tris.shape[1]).view(-1, 3)
    for keep in ([0, 1, 2, 3], [0, 1, 2, 3, 4], [0, 1, 2, 3, 4, 5]):
        sub = faces[keep]
        ours = rasterize(tris, sub, 12, 10, 0.05)
        assert torch.equal(ours, torch_rasterize(tris, sub, 12, 10, 0.05)), keep
    assert (rasterize(tris, faces[:4], 12, 10, 0.05) == -1).all()
    assert (rasterize(tris, faces, 12, 10, 0.05) == 5).all()


def test_empty_inputs() -> None:
    clip, faces, _, cam = clip_scene(2, 1, 8)
    assert (rasterize(clip, faces[:0], 8, 8, cam.near) == -1).all()
    empty = rasterize(clip[:0], faces, 8, 8, cam.near)
    assert empty.shape == (0, 8, 8) and empty.dtype == torch.int64
