"""Z-buffered rasterization in plain torch, by bounding-box enumeration.

Each drawable triangle expands into the pixel centres inside its screen bounding box;
each candidate is tested with the homogeneous edge functions of the contract
(:mod:`cerberus_core.render.interface`), and a two-pass scatter-min keeps the nearest face per pixel
(ties: the smallest face id). Work and memory scale with the covered area, processed in chunks of at
most ``max_candidates`` pixel-triangle pairs.
"""
from __future__ import annotations

import torch

from cerberus_core.errors import ConfigError
from cerberus_core.render.camera import centre_range, pixel_centres
from cerberus_core.render.interface import Renderer

Tensor = torch.Tensor



def _triangle_setup(clip: Tensor, faces: Tensor, height: int, width: int, near: float):
    """Per-triangle data: drawability, edge cross products, determinant and pixel bounding box."""
    tri = clip[:, faces]  # (B, F, 3, 4)
    w = tri[..., 3]
    v = tri[..., (0, 1, 3)]  # (B, F, 3, 3)
    v0, v1, v2 = v.unbind(-2)
    cross = torch.stack([torch.linalg.cross(v1, v2, dim=-1), torch.linalg.cross(v2, v0, dim=-1),
                         torch.linalg.cross(v0, v1, dim=-1)], dim=-2)  # (B, F, 3, 3): c_k = p . cross[k]
    det = (v0 * cross[..., 0, :]).sum(-1)  # (B, F)
    drawable = (w > near).all(-1) & (det != 0)
    safe_w = torch.where(w > near, w, torch.ones_like(w))
    u = ((tri[..., 0] / safe_w) + 1) * (0.5 * width)
    vv = (1 - (tri[..., 1] / safe_w)) * (0.5 * height)
    # Clamp before converting to integers so huge coordinates cannot overflow.
    u = u.clamp(-2.0, width + 2.0)
    vv = vv.clamp(-2.0, height + 2.0)
    col0, col1 = centre_range(u.amin(-1), u.amax(-1), width)
    row0, row1 = centre_range(vv.amin(-1), vv.amax(-1), height)
    drawable = drawable & (col1 >= col0) & (row1 >= row0)
    return drawable, cross, det, row0, row1, col0, col1


def rasterize(clip: Tensor, faces: Tensor, height: int, width: int, near: float = 0.05,
              max_candidates: int = 1 << 23) -> Tensor:
    """Visible face id per pixel.

    Args:
        clip: ``(B, V, 4)`` clip-space vertices.
        faces: ``(F, 3)`` int64.
        height, width: image size.
        near: near plane (triangles with any ``w <= near`` are dropped).
        max_candidates: chunk size in pixel-triangle pairs (bounds peak memory).
    Returns:
        ``(B, H, W)`` int64 face ids, -1 on background.
    """
    bsz = clip.shape[0]
    device = clip.device
    npix = bsz * height * width
    out = torch.full((npix,), -1, dtype=torch.int64, device=device)
    if faces.shape[0] == 0 or bsz == 0:
        return out.view(bsz, height, width)
    drawable, cross, det, row0, row1, col0, col1 = _triangle_setup(clip, faces, height, width, near)
    b_idx, f_idx = torch.nonzero(drawable, as_tuple=True)
    if b_idx.numel() == 0:
        return out.view(bsz, height, width)
    r0, c0 = row0[b_idx, f_idx], col0[b_idx, f_idx]
    bw = col1[b_idx, f_idx] - c0 + 1
    counts = (row1[b_idx, f_idx] - r0 + 1) * bw
    cross_t = cross[b_idx, f_idx]  # (T, 3, 3)
    det_t = det[b_idx, f_idx]
    zbuf = torch.full((npix,), float("inf"), dtype=clip.dtype, device=device)
    big = torch.iinfo(torch.int64).max
    winner = torch.full((npix,), big, dtype=torch.int64, device=device)

    # Chunk the triangles so that each chunk expands into at most max_candidates pairs.
    csum = torch.cumsum(counts, 0)
    bounds = [0]
    while bounds[-1] < len(counts):
        start_total = int(csum[bounds[-1] - 1]) if bounds[-1] > 0 else 0
        nxt = int(torch.searchsorted(csum, start_total + max_candidates, right=True))
        bounds.append(max(nxt, bounds[-1] + 1))
    px_of_col, py_of_row = pixel_centres(height, width, clip.dtype, device)
    passes = []
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=False):
        sel = slice(lo, hi)
        cnt = counts[sel]
        tri = torch.repeat_interleave(torch.arange(hi - lo, device=device), cnt)
        start = torch.cumsum(cnt, 0) - cnt
        k = torch.arange(tri.numel(), device=device) - start[tri]
        width_t = bw[sel][tri]
        rows = r0[sel][tri] + k // width_t
        cols = c0[sel][tri] + k % width_t
        px, py = px_of_col[cols], py_of_row[rows]
        cr = cross_t[sel][tri]  # (N, 3, 3)
        c = cr[..., 0] * px.unsqueeze(-1) + cr[..., 1] * py.unsqueeze(-1) + cr[..., 2]  # (N, 3)
        d = det_t[sel][tri]
        sgn = torch.sign(d).unsqueeze(-1)
        s = c.sum(-1)
        covered = ((c * sgn) >= 0).all(-1) & (s != 0)
        depth = d / s
        covered &= torch.isfinite(depth) & (depth > 0)
        key = (b_idx[sel][tri] * height + rows) * width + cols
        key, depth, face = key[covered], depth[covered], f_idx[sel][tri][covered]
        zbuf.scatter_reduce_(0, key, depth, reduce="amin")
        passes.append((key, depth, face))
    for key, depth, face in passes:
        hit = depth == zbuf[key]
        winner.scatter_reduce_(0, key[hit], face[hit], reduce="amin")
    out = torch.where(winner == big, out, winner)
    return out.view(bsz, height, width)


class TorchRenderer(Renderer):
    """Pure-PyTorch backend. Runs on the device of the tensors it is given.

    Args:
        max_candidates: chunk size in pixel-triangle pairs (default 8M); lower it to save memory.
    """

    name = "torch"

    def __init__(self, max_candidates: int = 1 << 23, **options) -> None:
        super().__init__(**options)
        if max_candidates < 1:
            raise ConfigError.about("max_candidates", max_candidates, "must be positive",
                                    "lower it to save memory, but keep it 1 or more")
        self.max_candidates = int(max_candidates)

    def rasterize(self, clip: Tensor, faces: Tensor, height: int, width: int, near: float) -> Tensor:
        return rasterize(clip, faces, height, width, near, self.max_candidates)
