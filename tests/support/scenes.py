"""Scene builders for the renderer tests (the render API, the torch and the Warp backends), imported by the test
modules."""
from __future__ import annotations

import torch

from cerberus_core import Camera, Light, icosphere
from cerberus_core.render.api import pack_parts
from cerberus_core.render.templates import vertex_normals

Tensor = torch.Tensor



def two_sphere_scene() -> tuple[Tensor, Tensor, Camera]:
    """Two icosphere parts side by side, in a batch of 2 seen from azimuths 0 and 40 at 32 x 48 pixels.

    Returns:
        ``parts`` ``(2, 2, V, 3)``, template ``faces`` ``(F, 3)`` and the cameras.
    """
    t = icosphere(2)
    parts = torch.stack([t.vertices * 0.25 + torch.tensor([-0.25, 0.0, 0.0]),
                         t.vertices * 0.2 + torch.tensor([0.25, 0.1, 0.1])]).expand(2, -1, -1, -1)
    cam = Camera.look_at(torch.tensor([0.0, 40.0]), 10.0, 2.5, fov_y_deg=30.0, image_size=(32, 48))
    return parts, t.faces, cam

def part_scene(batch: int, num_parts: int, size: int | tuple[int, int], *, seed: int = 0, radius: float = 0.1,
               level: int = 2, dtype: torch.dtype = torch.float32) -> tuple[Tensor, Tensor, Camera]:
    """The training workload in miniature: ``num_parts`` icosphere parts of ``radius`` at random
    centres in ``[-0.5, 0.5]^3``, cameras at distance 2.5 (fov 30) at random azimuth/elevation.

    Returns:
        ``parts`` ``(B, P, V, 3)``, template ``faces`` ``(F, 3)`` and the cameras.
    """
    g = torch.Generator().manual_seed(seed)
    sphere = icosphere(level)
    centres = torch.rand(batch, num_parts, 1, 3, generator=g, dtype=torch.float64) - 0.5
    parts = (radius * sphere.vertices.double()).expand(batch, num_parts, -1, -1) + centres
    cam = Camera.look_at(360 * torch.rand(batch, generator=g), 40 * torch.rand(batch, generator=g) - 20, 2.5,
                         fov_y_deg=30.0, image_size=size)
    return parts.to(dtype), sphere.faces, cam


def clip_scene(batch: int, num_parts: int, size, *, seed: int = 0, radius: float = 0.1,
               dtype: torch.dtype = torch.float32):
    """``(clip (B, V, 4), packed faces (F, 3), vertices (B, V, 3), camera)`` of :func:`part_scene`."""
    parts, faces, cam = part_scene(batch, num_parts, size, seed=seed, radius=radius, dtype=dtype)
    vertices, packed, _ = pack_parts(parts, faces)
    cam = Camera(cam.rotation.to(dtype), cam.translation.to(dtype), cam.fov_y_deg.to(dtype), cam.height,
                 cam.width, cam.near, cam.far)
    return cam.world_to_clip(vertices), packed, vertices, cam


def shading_inputs(batch: int = 3, size=24, *, seed: int = 0, dtype: torch.dtype = torch.float64,
                   backlit: bool = True):
    """Leaf tensors for :func:`shade`: ``(clip, faces, face_id, normals, albedo, light)``.

    Random per-vertex albedo and light; with ``backlit`` the first scene is lit from behind so that
    some visible pixels have ``n . l < 0`` (clamped, zero diffuse gradient).
    """
    from cerberus_render_warp import rasterize

    clip, faces, vertices, cam = clip_scene(batch, 3, size, seed=seed, radius=0.2, dtype=dtype)
    g = torch.Generator().manual_seed(seed + 1)
    face_id = rasterize(clip.detach(), faces, cam.height, cam.width, cam.near)
    normals = vertex_normals(vertices, faces).detach()
    albedo = torch.rand(vertices.shape, generator=g, dtype=torch.float64).to(dtype)
    light = Light.following(cam)
    direction = light.direction.clone()
    if backlit:
        direction[0] = -direction[0] + 0.3
    leaves = [t.detach().clone().requires_grad_(True) for t in (
        clip, normals, albedo, direction, torch.rand(batch, 3, generator=g, dtype=torch.float64).to(dtype),
        torch.rand(batch, 3, generator=g, dtype=torch.float64).to(dtype))]
    clip, normals, albedo, direction, ambient, diffuse = leaves
    return clip, faces, face_id, normals, albedo, Light(direction, ambient, diffuse)
