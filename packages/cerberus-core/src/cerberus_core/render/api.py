"""User-facing rendering: the ops of :mod:`cerberus_core.render.ops` composed (rasterize with a backend, shade,
composite), and the checks of a scene that no op can make (one camera per scene, finite and bounded vertices).

>>> from cerberus_core import Camera, Light, make_renderer, render_parts, icosphere
>>> r = make_renderer("torch")
>>> cam = Camera.look_at(30.0, 10.0, 2.5, image_size=64)
>>> sphere = icosphere(2)
>>> parts = 0.2 * sphere.vertices.expand(1, 3, -1, -1) + torch.tensor([[-.3, 0, 0], [0, 0, 0], [.3, 0, 0]]).view(1, 3, 1, 3)
>>> out = render_parts(r, parts, sphere.faces, cam, Light.following(cam))
>>> out.image.shape
torch.Size([1, 3, 64, 64])
"""
from __future__ import annotations

from collections.abc import Sequence

import torch

import cerberus_core.render.ops as ops
from cerberus_core.errors import MeshError, RenderInputError, ShapeError
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer, RenderOutput
from cerberus_core.render.light import Light
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

MAX_COORDINATE = 1e8
"""Largest supported absolute vertex coordinate (world units); larger ones are rejected with a clear error."""


def _check_scene(vertices: Tensor, camera: Camera) -> None:
    """What no op checks: one camera per scene, and finite world coordinates within :data:`MAX_COORDINATE`
    (``vertices`` is ``(B, V, 3)``: :func:`ops.vertex_normals <cerberus_core.render.ops.vertex_normals>` checked it)."""
    if vertices.shape[0] != camera.batch_size:
        raise ShapeError(f"render: {vertices.shape[0]} scenes but {camera.batch_size} cameras; pass one camera per scene")
    bad = ~torch.isfinite(vertices.detach()).all(-1)
    if bool(bad.any()):
        scene, vert = (int(i) for i in torch.nonzero(bad)[0])
        raise MeshError(f"render: vertex {vert} of scene {scene} is NaN or inf ({int(bad.sum())} bad vertices in all); "
                        "the model or data produced non-finite geometry — check the loss/learning rate or the input mesh")
    biggest = float(vertices.detach().abs().max()) if vertices.numel() else 0.0
    if biggest > MAX_COORDINATE:
        raise RenderInputError(f"render: vertex coordinates reach {biggest:.3g}, beyond the supported range |x| <= {MAX_COORDINATE:g} "
                               "(float32 edge functions overflow there); the geometry has diverged — check the loss/learning rate "
                               "or rescale the scene to normalised units")


def _per_vertex(value: Tensor | Sequence[float], bsz: int, nverts: int, like: Tensor, what: str) -> Tensor:
    t = torch.as_tensor(value, dtype=like.dtype, device=like.device)
    if t.shape == (3,):
        return t.expand(bsz, nverts, 3)
    if t.ndim == 2 and t.shape == (bsz, 3):
        return t.unsqueeze(1).expand(bsz, nverts, 3)
    if t.shape == (bsz, nverts, 3):
        return t
    raise ShapeError(f"render: {what} must be (3,), (B, 3) or (B, V, 3); got {tuple(t.shape)}; pass one colour, "
                     "one per scene or one per vertex")


def render(renderer: Renderer, vertices: Tensor, faces: Tensor, camera: Camera, light: Light | None = None, *,
           albedo: Tensor | Sequence[float] = (0.8, 0.8, 0.8), face_part: Tensor | None = None,
           background: Sequence[float] | Tensor = (0.0, 0.0, 0.0), antialias: bool = False) -> RenderOutput:
    """Render a batch of triangle meshes.

    Args:
        renderer: a backend from :func:`cerberus_core.make_renderer`.
        vertices: ``(B, V, 3)`` world coordinates.
        faces: ``(F, 3)`` int vertex indices shared by the batch.
        camera: ``B`` cameras (one per scene).
        light: the light (default: white light following the camera, ambient 0.4, diffuse 0.6).
        albedo: ``(3,)``, ``(B, 3)`` or ``(B, V, 3)`` RGB albedo in [0, 1].
        face_part: ``(F,)`` part index of each face (default all 0).
        background: ``(3,)`` RGB background colour.
        antialias: blend image and alpha across silhouette edges with :meth:`Renderer.antialias`,
            which makes both differentiable w.r.t. the silhouette vertices (visibility gradients).
            Off (default), the alpha is a hard 0/1 mask without gradient.
    Returns:
        :class:`RenderOutput`.
    """
    # The ops check the tensors (the first, vertex_normals: vertices, faces and their indices), render the scene.
    if isinstance(vertices, Tensor) and isinstance(faces, Tensor):  # anything else: the op names what came
        faces = faces.to(vertices.device)
    normals = ops.vertex_normals(renderer, vertices, faces)
    _check_scene(vertices, camera)
    faces = faces.long()
    bsz, nverts, _ = vertices.shape
    light = Light.following(camera) if light is None else light
    alb = _per_vertex(albedo, bsz, nverts, vertices, "albedo")
    clip = camera.world_to_clip(vertices)
    face_id = ops.rasterize(renderer, clip, faces, (camera.height, camera.width), camera.near)
    rgb, depth = ops.shade(renderer, clip, faces, face_id, normals, alb, light)
    alpha = (face_id >= 0).to(vertices.dtype).unsqueeze(-1)
    bg = torch.as_tensor(background, dtype=vertices.dtype, device=vertices.device)
    check_shapes("render", background=(bg, "3"), **({} if face_part is None else {"faces": (faces, "F 3"),
                                                                                  "face_part": (face_part, "F")}))
    bg = bg.reshape(1, 1, 1, 3)
    # rgb is 0 on the background: over black (training's case) compositing would add zeros
    image = rgb + (1 - alpha) * bg if bg.requires_grad or bool(bg.any()) else rgb
    if antialias:
        blended = ops.antialias(renderer, torch.cat([image, alpha], dim=-1), clip, faces, face_id)
        image, alpha = blended.split([3, 1], dim=-1)
    if face_part is None:
        part_id = torch.where(face_id >= 0, torch.zeros_like(face_id), face_id)
    else:
        fp = face_part.to(device=face_id.device, dtype=torch.int64)
        part_id = torch.cat([fp, fp.new_full((1,), -1)])[face_id]  # face id -1 picks the trailing -1
    return RenderOutput(
        image=image.permute(0, 3, 1, 2),
        alpha=alpha.permute(0, 3, 1, 2),
        depth=depth.unsqueeze(1),
        face_id=face_id,
        part_id=part_id,
    )


def pack_parts(part_vertices: Tensor, faces: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    """Pack ``P`` parts sharing one face template into one mesh per scene.

    Args:
        part_vertices: ``(B, P, V, 3)``.
        faces: ``(F, 3)`` template faces.
    Returns:
        ``vertices`` ``(B, P*V, 3)``, ``faces`` ``(P*F, 3)`` and ``face_part`` ``(P*F,)``.
    """
    bsz, nparts, nverts, _ = part_vertices.shape
    faces = faces.to(device=part_vertices.device, dtype=torch.int64)
    offsets = torch.arange(nparts, device=faces.device).view(-1, 1, 1) * nverts
    packed_faces = (faces.unsqueeze(0) + offsets).reshape(-1, 3)
    face_part = torch.arange(nparts, device=faces.device).repeat_interleave(faces.shape[0])
    return part_vertices.reshape(bsz, nparts * nverts, 3), packed_faces, face_part


def render_parts(renderer: Renderer, part_vertices: Tensor, faces: Tensor, camera: Camera,
                 light: Light | None = None, *, albedo: Tensor | Sequence[float] = (0.8, 0.8, 0.8),
                 background: Sequence[float] | Tensor = (0.0, 0.0, 0.0), antialias: bool = False) -> RenderOutput:
    """Render scenes made of ``P`` parts that share one face template (the Cerberus case).

    Args:
        part_vertices: ``(B, P, V, 3)`` world coordinates of every part.
        faces: ``(F, 3)`` the template's faces.
        albedo: ``(3,)``, ``(P, 3)`` / ``(B, P, 3)`` per part, or ``(B, P, V, 3)`` per vertex.
        Others as in :func:`render`.
    """
    check_shapes("render_parts", part_vertices=(part_vertices, "B P V 3"))
    bsz, nparts, nverts, _ = part_vertices.shape
    vertices, packed_faces, face_part = pack_parts(part_vertices, faces)
    alb = torch.as_tensor(albedo, dtype=vertices.dtype, device=vertices.device)
    if alb.shape == (nparts, 3):
        alb = alb.expand(bsz, nparts, 3)
    if alb.ndim == 3 and alb.shape == (bsz, nparts, 3):
        alb = alb.unsqueeze(2).expand(bsz, nparts, nverts, 3)
    if alb.ndim == 4:
        alb = alb.reshape(bsz, nparts * nverts, 3)
    return render(renderer, vertices, packed_faces, camera, light, albedo=alb, face_part=face_part,
                  background=background, antialias=antialias)


def part_pixel_counts(part_id: Tensor, num_parts: int) -> Tensor:
    """Pixels each part is the front surface of, per image.

    Args:
        part_id: ``(B, H, W)`` a :class:`RenderOutput`'s ``part_id`` (-1 where no part).
        num_parts: ``P``.
    Returns:
        ``(B, P)`` int64 on ``part_id``'s device (0: the part is wholly hidden in that image).
    """
    bsz = part_id.shape[0]
    slot = part_id.reshape(bsz, -1) + 1 + torch.arange(bsz, device=part_id.device).unsqueeze(1) * (num_parts + 1)
    counts = torch.bincount(slot.reshape(-1), minlength=bsz * (num_parts + 1)).reshape(bsz, num_parts + 1)
    return counts[:, 1:]
