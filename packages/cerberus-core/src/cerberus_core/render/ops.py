"""The rendering ops as free functions over a backend context, after nvdiffrast: one op per function.

``ctx`` is a renderer backend (:class:`~cerberus_core.render.interface.Renderer`, from
:func:`cerberus_core.make_renderer`); each op validates its inputs once (shapes, dtypes, one device:
:class:`~cerberus_core.errors.ShapeError`, :class:`~cerberus_core.errors.DeviceError`; the ops that take
geometry without face ids, :func:`rasterize` and :func:`vertex_normals`, also that the faces index existing
vertices: :class:`~cerberus_core.errors.MeshError`), calls the backend's kernel for it (or the shared torch
reference the backend inherits; backends do not check again) and returns plain tensors, channels last like
nvdiffrast's. The other ops take the faces :func:`rasterize` was given, which its face ids index. These ops are the one way to a
backend: :func:`cerberus_core.render.render` is them composed:

>>> import torch
>>> from cerberus_core import Camera, Light, icosphere, make_renderer
>>> from cerberus_core.render import ops
>>> ctx = make_renderer("torch")
>>> cam = Camera.look_at(30.0, 10.0, 2.5, image_size=32)
>>> sphere = icosphere(2)
>>> v = 0.4 * sphere.vertices[None]
>>> clip = cam.world_to_clip(v)
>>> face_id = ops.rasterize(ctx, clip, sphere.faces, (32, 32), cam.near)
>>> normals = ops.vertex_normals(ctx, v, sphere.faces)
>>> rgb, depth = ops.shade(ctx, clip, sphere.faces, face_id, normals, torch.full_like(v, 0.8), Light.following(cam))
>>> xyz = ops.interpolate(v, clip, sphere.faces, face_id)  # (1, 32, 32, 3) surface points
>>> rgba = ops.antialias(ctx, torch.cat([rgb, (face_id >= 0).float()[..., None]], -1), clip, sphere.faces, face_id)

Shapes: ``clip`` ``(B, V, 4)`` clip-space vertices (:meth:`Camera.world_to_clip`), ``faces`` ``(F, 3)``
int64, ``face_id`` ``(B, H, W)`` int64 (-1 on background), images ``(B, H, W, C)``.
"""
from __future__ import annotations

import operator

import torch

from cerberus_core.errors import InputTypeError, MeshError, RenderInputError
from cerberus_core.plumbing.machine import check_memory
from cerberus_core.render.interface import Renderer
from cerberus_core.render.light import Light
from cerberus_core.render.shading import foreground, homogeneous_barycentrics, pixel_ndc
from cerberus_core.render.shading import interpolate as interpolate_at
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

FLOATS = (torch.float32, torch.float64)
"""The geometry dtypes the ops take."""
INTS = (torch.int32, torch.int64)
"""The index dtypes the ops take (faces, face ids are int64)."""


RASTER_BYTES_PER_PIXEL = 24
"""Memory a rasterization holds per pixel of the batch at least: the face ids, a depth buffer and the winners
(int64 / float64 each); a resolution whose total exceeds the device's memory is refused before allocating."""


def _check_backend(op: str, ctx: object) -> None:
    if not isinstance(ctx, Renderer):
        raise InputTypeError(f"{op}: ctx is {type(ctx).__name__}, not a renderer backend; pass one from "
                             "cerberus_core.make_renderer(name)")


def _check_faces(op: str, faces: Tensor, nverts: int, face_id: Tensor | None = None) -> None:
    """:class:`MeshError` when ``faces`` index a vertex outside ``0..nverts - 1``, or ``face_id`` a face outside
    ``-1..F - 1`` (a backend would index out of bounds, or read another scene's memory)."""
    if faces.numel() and (int(faces.min()) < 0 or int(faces.max()) >= nverts):
        raise MeshError(f"{op}: faces index vertices outside 0..{nverts - 1} (they reach {int(faces.min())}.."
                        f"{int(faces.max())}); check the face template matches the vertex count")
    if face_id is not None and face_id.numel() and (int(face_id.min()) < -1 or int(face_id.max()) >= len(faces)):
        raise MeshError(f"{op}: face_id names faces outside -1..{len(faces) - 1} (it reaches {int(face_id.min())}.."
                        f"{int(face_id.max())}); pass the face ids rasterize gave for these faces")


def rasterize(ctx: Renderer, clip: Tensor, faces: Tensor, resolution: tuple[int, int], near: float) -> Tensor:
    """The visible face of every pixel (not differentiable: the barycentrics are recomputed by the
    differentiable ops from ``clip`` and these ids). The rule is the contract of
    :mod:`cerberus_core.render.interface`.

    Args:
        resolution: ``(H, W)`` pixels. near: triangles with a vertex at ``w <= near`` are not drawn.
    Returns:
        ``(B, H, W)`` int64 face ids, -1 on background.

    >>> import torch
    >>> from cerberus_core import Camera, Light, icosphere, make_renderer
    >>> from cerberus_core.render import ops
    >>> ctx, cam, sphere = make_renderer("torch"), Camera.look_at(30.0, 10.0, 2.5, image_size=32), icosphere(2)
    >>> v = 0.4 * sphere.vertices[None]  # (1, V, 3)
    >>> clip = cam.world_to_clip(v)
    >>> face_id = ops.rasterize(ctx, clip, sphere.faces, (32, 32), cam.near)
    >>> face_id.shape, face_id.dtype, bool((face_id >= 0).any())
    (torch.Size([1, 32, 32]), torch.int64, True)
    """
    _check_backend("rasterize", ctx)
    check_shapes("rasterize", same_device=True, clip=(clip, "B V 4", FLOATS), faces=(faces, "F 3", INTS))
    _check_faces("rasterize", faces, clip.shape[1])
    if not bool(torch.isfinite(clip).all()):
        raise MeshError(f"rasterize: {int((~torch.isfinite(clip)).any(-1).sum())} clip-space vertices are NaN or inf; "
                        "the geometry (or the camera) is not finite — check the vertices given to the camera")
    try:
        height, width = (operator.index(n) for n in resolution)
    except (TypeError, ValueError):
        raise RenderInputError(f"rasterize: resolution is {resolution!r}; pass `resolution=(height, width)`, two "
                               "integers") from None
    if height < 1 or width < 1:
        raise RenderInputError(f"rasterize: the image size must be positive, got {height}x{width}; pass "
                               "`resolution=(height, width)` with both 1 or more")
    check_memory("resolution", (height, width), clip.shape[0] * height * width * RASTER_BYTES_PER_PIXEL,
                 f"{clip.shape[0]} images of {height}x{width} pixels", device=clip.device)
    with torch.no_grad():
        return ctx.rasterize(clip.detach(), faces, int(height), int(width), float(near))


def interpolate(attr: Tensor, clip: Tensor, faces: Tensor, face_id: Tensor) -> Tensor:
    """Per-vertex attributes at every covered pixel, perspective-correct and differentiable w.r.t.
    ``attr`` and ``clip`` (the barycentric gradients of Genova et al.).

    Args:
        attr: ``(B, V, C)`` per-vertex attributes.
    Returns:
        ``(B, H, W, C)``, 0 on background.

    >>> import torch
    >>> from cerberus_core import Camera, Light, icosphere, make_renderer
    >>> from cerberus_core.render import ops
    >>> ctx, cam, sphere = make_renderer("torch"), Camera.look_at(30.0, 10.0, 2.5, image_size=32), icosphere(2)
    >>> v = 0.4 * sphere.vertices[None]  # (1, V, 3)
    >>> clip = cam.world_to_clip(v)
    >>> face_id = ops.rasterize(ctx, clip, sphere.faces, (32, 32), cam.near)
    >>> xyz = ops.interpolate(v, clip, sphere.faces, face_id)  # the surface point under each pixel
    >>> xyz.shape, bool(xyz[face_id >= 0].norm(dim=-1).le(0.4 + 1e-4).all())
    (torch.Size([1, 32, 32, 3]), True)
    """
    check_shapes("interpolate", same_device=True, attr=(attr, "B V C", FLOATS), clip=(clip, "B V 4", FLOATS),
                 faces=(faces, "F 3", INTS), face_id=(face_id, "B H W", (torch.int64,)))
    _check_faces("interpolate", faces, clip.shape[1], face_id)
    bsz, height, width = face_id.shape
    b, r, c, f = foreground(face_id)
    bary, _ = homogeneous_barycentrics(pixel_ndc(height, width, r, c, clip.dtype), clip[b.unsqueeze(-1), faces[f]])
    values = interpolate_at(attr, faces, b, f, bary)
    flat = (b * height + r) * width + c
    out = values.new_zeros(bsz * height * width, attr.shape[-1]).index_put((flat,), values)
    return out.view(bsz, height, width, attr.shape[-1])


def vertex_normals(ctx: Renderer, vertices: Tensor, faces: Tensor) -> Tensor:
    """``(B, V, 3)`` area-weighted unit vertex normals of ``(B, V, 3)`` world vertices (differentiable;
    the backend's kernel or the shared torch code).

    >>> import torch
    >>> from cerberus_core import Camera, Light, icosphere, make_renderer
    >>> from cerberus_core.render import ops
    >>> ctx, cam, sphere = make_renderer("torch"), Camera.look_at(30.0, 10.0, 2.5, image_size=32), icosphere(2)
    >>> v = 0.4 * sphere.vertices[None]  # (1, V, 3)
    >>> clip = cam.world_to_clip(v)
    >>> normals = ops.vertex_normals(ctx, v, sphere.faces)
    >>> normals.shape, torch.allclose(normals, v / v.norm(dim=-1, keepdim=True), atol=0.1)  # a sphere's point outward
    (torch.Size([1, 162, 3]), True)
    """
    _check_backend("vertex_normals", ctx)
    check_shapes("vertex_normals", same_device=True, vertices=(vertices, "B V 3", FLOATS), faces=(faces, "F 3", INTS))
    _check_faces("vertex_normals", faces, vertices.shape[1])
    return ctx.vertex_normals(vertices, faces)


def shade(ctx: Renderer, clip: Tensor, faces: Tensor, face_id: Tensor, normals: Tensor, albedo: Tensor,
          light: Light) -> tuple[Tensor, Tensor]:
    """Lambertian shading of the visible surface (differentiable).

    Args:
        normals: ``(B, V, 3)`` unit world-space vertex normals; albedo: ``(B, V, 3)``.
    Returns:
        ``rgb`` ``(B, H, W, 3)`` and ``depth`` ``(B, H, W)`` (distance along the view axis), both 0 on
        background.

    >>> import torch
    >>> from cerberus_core import Camera, Light, icosphere, make_renderer
    >>> from cerberus_core.render import ops
    >>> ctx, cam, sphere = make_renderer("torch"), Camera.look_at(30.0, 10.0, 2.5, image_size=32), icosphere(2)
    >>> v = 0.4 * sphere.vertices[None]  # (1, V, 3)
    >>> clip = cam.world_to_clip(v)
    >>> face_id = ops.rasterize(ctx, clip, sphere.faces, (32, 32), cam.near)
    >>> normals = ops.vertex_normals(ctx, v, sphere.faces)
    >>> rgb, depth = ops.shade(ctx, clip, sphere.faces, face_id, normals, torch.full_like(v, 0.8), Light.following(cam))
    >>> rgb.shape, depth.shape, bool(rgb.max() <= 0.8 + 1e-6)  # albedo 0.8 under ambient + diffuse = 1
    (torch.Size([1, 32, 32, 3]), torch.Size([1, 32, 32]), True)
    """
    _check_backend("shade", ctx)
    check_shapes("shade", same_device=True, clip=(clip, "B V 4", FLOATS), faces=(faces, "F 3", INTS),
                 face_id=(face_id, "B H W", (torch.int64,)), normals=(normals, "B V 3", FLOATS),
                 albedo=(albedo, "B V 3", FLOATS),
                 **{f"light.{name}": (getattr(light, name), "B 3") for name in ("direction", "ambient", "diffuse")})
    _check_faces("shade", faces, clip.shape[1], face_id)
    return ctx.shade(clip, faces, face_id, normals, albedo, light)


def antialias(ctx: Renderer, color: Tensor, clip: Tensor, faces: Tensor, face_id: Tensor) -> Tensor:
    """Analytic anti-aliasing of silhouette and occlusion edges (visibility gradients): ``(B, H, W, C)``
    colours blended across the edges, differentiable w.r.t. ``color`` and ``clip``
    (:mod:`cerberus_core.render.antialias`).

    >>> import torch
    >>> from cerberus_core import Camera, Light, icosphere, make_renderer
    >>> from cerberus_core.render import ops
    >>> ctx, cam, sphere = make_renderer("torch"), Camera.look_at(30.0, 10.0, 2.5, image_size=32), icosphere(2)
    >>> v = 0.4 * sphere.vertices[None]  # (1, V, 3)
    >>> clip = cam.world_to_clip(v)
    >>> face_id = ops.rasterize(ctx, clip, sphere.faces, (32, 32), cam.near)
    >>> alpha = (face_id >= 0).float()[..., None]  # (1, 32, 32, 1): hard coverage
    >>> soft = ops.antialias(ctx, alpha, clip, sphere.faces, face_id)
    >>> soft.shape, bool(((soft > 0) & (soft < 1)).any())  # fractional coverage on the silhouette's edge
    (torch.Size([1, 32, 32, 1]), True)
    """
    _check_backend("antialias", ctx)
    check_shapes("antialias", same_device=True, color=(color, "B H W C", FLOATS), clip=(clip, "B V 4", FLOATS),
                 faces=(faces, "F 3", INTS), face_id=(face_id, "B H W", (torch.int64,)))
    _check_faces("antialias", faces, clip.shape[1], face_id)
    return ctx.antialias(color, clip, faces, face_id)


__all__ = ["FLOATS", "INTS", "antialias", "interpolate", "rasterize", "shade", "vertex_normals"]
