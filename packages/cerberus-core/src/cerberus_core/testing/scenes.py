"""Scenes the conformance suite renders: random bodies of ellipsoid parts and float64 cameras."""
from __future__ import annotations

import torch
from kornia.geometry.conversions import axis_angle_to_rotation_matrix

from cerberus_core.render.camera import Camera
from cerberus_core.render.templates import icosphere

Tensor = torch.Tensor


def ellipsoid_parts(batch: int, num_parts: int, *, level: int = 2, seed: int = 0, spread: float = 0.3,
                    radius: tuple[float, float] = (0.06, 0.17),
                    dtype: torch.dtype = torch.float32) -> tuple[Tensor, Tensor]:
    """Randomly rotated, convex ellipsoid parts forming a body inside ``[-0.5, 0.5]^3``.

    Args:
        batch, num_parts: ``B`` bodies of ``P`` parts each.
        level: icosphere level of every part (2: 162 vertices, 320 faces).
        seed: the scenes are a pure function of the arguments.
        spread: part centres are uniform in ``[-spread, spread]^3``.
        radius: range of the ellipsoid semi-axes (world units).
    Returns:
        ``parts`` ``(B, P, V, 3)`` (world units, ``dtype``) and ``faces`` ``(F, 3)`` int64.
    """
    g = torch.Generator().manual_seed(seed)
    t = icosphere(level)
    lo, hi = radius
    radii = lo + (hi - lo) * torch.rand(batch, num_parts, 1, 3, generator=g, dtype=torch.float64)
    centres = spread * (2 * torch.rand(batch, num_parts, 1, 3, generator=g, dtype=torch.float64) - 1)
    axis_angle = 3.0 * (torch.rand(batch * num_parts, 3, generator=g, dtype=torch.float64) - 0.5)
    rot = axis_angle_to_rotation_matrix(axis_angle).view(batch, num_parts, 3, 3)
    parts = (t.vertices.to(torch.float64) * radii) @ rot.transpose(-1, -2) + centres
    return parts.to(dtype), t.faces


def cameras(batch: int, *, image_size: int | tuple[int, int] = 64, seed: int = 0, distance: float = 2.5,
            fov_y_deg: float = 30.0) -> Camera:
    """``B`` look-at cameras at random azimuths and elevations in ``[-30, 30]`` degrees."""
    g = torch.Generator().manual_seed(seed + 1000)
    az = 360.0 * torch.rand(batch, generator=g)
    el = 60.0 * torch.rand(batch, generator=g) - 30.0
    return Camera.look_at(az, el, distance, fov_y_deg=fov_y_deg, image_size=image_size)


def body_scene(batch: int = 2, *, num_parts: int = 9, image_size: int | tuple[int, int] = 64, level: int = 2,
               seed: int = 0, radius: tuple[float, float] = (0.06, 0.17),
               dtype: torch.dtype = torch.float32) -> tuple[Tensor, Tensor, Camera]:
    """:func:`ellipsoid_parts` plus matching :func:`cameras`: ``(parts, faces, camera)``."""
    parts, faces = ellipsoid_parts(batch, num_parts, level=level, seed=seed, radius=radius, dtype=dtype)
    return parts, faces, cameras(batch, image_size=image_size, seed=seed)


def double_camera(camera: Camera) -> Camera:
    """The same cameras in float64, so the whole render path can run in double precision."""
    return Camera(camera.rotation.double(), camera.translation.double(), camera.fov_y_deg.double(),
                  camera.height, camera.width, camera.near, camera.far)


def interior_mask(part_id: Tensor) -> Tensor:
    """Pixels away from silhouette and part edges.

    Args:
        part_id: ``(B, H, W)`` int64, -1 on background.
    Returns:
        ``(B, 1, H, W)`` bool: the pixel and its whole 3x3 neighbourhood show the same part (image
        borders count as background).
    """
    p = part_id.unsqueeze(1).to(torch.float64)
    pad = torch.nn.functional.pad(p, (1, 1, 1, 1), value=-1.0)
    hi = torch.nn.functional.max_pool2d(pad, 3, stride=1)
    lo = -torch.nn.functional.max_pool2d(-pad, 3, stride=1)
    return (hi == lo) & (p >= 0)
