"""Differentiable barycentrics, attribute interpolation and Lambertian shading (shared torch code).

This is the barycentric-gradient renderer of Genova et al. (2018): rasterization picks a face per
pixel without gradients; the pixel's perspective-correct barycentrics are then recomputed from the
clip-space vertices with differentiable torch ops, so gradients reach the vertices through the
barycentrics, the interpolated normals and the shading. Pixels off every face get no gradient.

Only foreground pixels are computed (gathered by their face id), so the cost scales with the covered
area, not with ``H x W x F``.
"""
from __future__ import annotations

import torch

from cerberus_core.render.camera import pixel_centres
from cerberus_core.render.light import Light
from cerberus_core.render.templates import NORMAL_EPS

Tensor = torch.Tensor


def pixel_ndc(height: int, width: int, rows: Tensor, cols: Tensor, dtype: torch.dtype = torch.float32) -> Tensor:
    """NDC of pixel centres (:func:`~cerberus_core.render.camera.pixel_centres`).

    Args:
        rows, cols: ``(N,)`` integer pixel indices.
        dtype: the dtype of the scene (the clip-space vertices).
    Returns:
        ``(N, 3)`` homogeneous NDC points ``(x, y, 1)``.
    """
    px, py = pixel_centres(height, width, dtype, rows.device)
    x, y = px[cols], py[rows]
    return torch.stack([x, y, torch.ones_like(x)], dim=-1)


def homogeneous_barycentrics(p: Tensor, tri_clip: Tensor) -> tuple[Tensor, Tensor]:
    """Perspective-correct barycentrics and depth of points inside clip-space triangles.

    Args:
        p: ``(N, 3)`` homogeneous NDC points ``(x, y, 1)``.
        tri_clip: ``(N, 3, 4)`` clip-space vertices of the triangle under each point.
    Returns:
        ``bary`` ``(N, 3)`` (sums to 1) and ``depth`` ``(N,)`` (the interpolated ``w``).
    """
    v = tri_clip[..., (0, 1, 3)]  # (N, 3, 3): rows (x, y, w)
    v0, v1, v2 = v.unbind(-2)
    c = torch.stack([
        (p * torch.linalg.cross(v1, v2, dim=-1)).sum(-1),
        (p * torch.linalg.cross(v2, v0, dim=-1)).sum(-1),
        (p * torch.linalg.cross(v0, v1, dim=-1)).sum(-1),
    ], dim=-1)
    s = c.sum(-1, keepdim=True)
    bary = c / s
    depth = (bary * v[..., 2]).sum(-1)
    return bary, depth


def foreground(face_id: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """Indices of covered pixels.

    Args:
        face_id: ``(B, H, W)`` int64, -1 on background.
    Returns:
        ``(b, rows, cols, faces)`` each ``(N,)`` int64 for the ``N`` covered pixels.
    """
    b, r, c = torch.nonzero(face_id >= 0, as_tuple=True)
    return b, r, c, face_id[b, r, c]


def interpolate(attr: Tensor, faces: Tensor, b: Tensor, f: Tensor, bary: Tensor) -> Tensor:
    """Interpolate per-vertex attributes at covered pixels.

    Args:
        attr: ``(B, V, C)`` per-vertex attributes.
        faces: ``(F, 3)`` int64.
        b, f: ``(N,)`` batch index and face id of each covered pixel.
        bary: ``(N, 3)`` barycentrics.
    Returns:
        ``(N, C)``.
    """
    tri = faces[f]  # (N, 3)
    vals = attr[b.unsqueeze(-1), tri]  # (N, 3, C)
    return (vals * bary.unsqueeze(-1)).sum(-2)


def lambert(normal: Tensor, albedo: Tensor, direction: Tensor, ambient: Tensor, diffuse: Tensor) -> Tensor:
    """Lambertian shading ``albedo * (ambient + diffuse * max(0, n̂ · l))``.

    Args:
        normal: ``(N, 3)`` interpolated (not necessarily unit) normals; normalised here.
        albedo: ``(N, 3)``.
        direction, ambient, diffuse: ``(N, 3)`` light terms per point.
    Returns:
        ``(N, 3)`` RGB.
    """
    n = torch.nn.functional.normalize(normal, dim=-1, eps=NORMAL_EPS)
    cos = (n * direction).sum(-1, keepdim=True).clamp_min(0.0)
    return albedo * (ambient + diffuse * cos)


def shade(clip: Tensor, faces: Tensor, face_id: Tensor, normals: Tensor, albedo: Tensor,
          light: Light) -> tuple[Tensor, Tensor]:
    """The shared differentiable shading path (see :meth:`Renderer.shade` for shapes).

    Returns:
        ``rgb`` ``(B, H, W, 3)`` and ``depth`` ``(B, H, W)``, 0 on background.
    """
    bsz, height, width = face_id.shape
    b, r, c, f = foreground(face_id)
    p = pixel_ndc(height, width, r, c, clip.dtype)
    tri_clip = clip[b.unsqueeze(-1), faces[f]]  # (N, 3, 4)
    bary, depth = homogeneous_barycentrics(p, tri_clip)
    n = interpolate(normals, faces, b, f, bary)
    a = interpolate(albedo, faces, b, f, bary)
    rgb_fg = lambert(n, a, light.direction[b], light.ambient[b], light.diffuse[b])
    flat = (b * height + r) * width + c
    rgb = clip.new_zeros(bsz * height * width, 3).index_put((flat,), rgb_fg)
    dep = clip.new_zeros(bsz * height * width).index_put((flat,), depth)
    return rgb.view(bsz, height, width, 3), dep.view(bsz, height, width)
