"""The renderer contract every backend implements, and the types that cross it.

The split follows nvdiffrast and TF Graphics: a backend's must-have is the hot, non-differentiable
step, :meth:`Renderer.rasterize` (clip-space triangles → visible face id per pixel). Everything
differentiable (vertex normals, perspective-correct barycentrics recomputed from the face ids,
interpolation of normals and albedo, Lambertian shading, depth) is done by
:func:`cerberus_core.render.templates.vertex_normals` and :func:`cerberus_core.render.shading.shade` in plain
torch, shared by all backends. A backend may override :meth:`Renderer.vertex_normals`,
:meth:`Renderer.shade` and :meth:`Renderer.antialias` with fused kernels (forward and backward) when that is faster; the conformance suite in ``tests/conformance``
holds both paths to the same numbers.

Rasterization rule (all backends, so that face ids agree):

* Pixel ``(row i, col j)`` is sampled at its centre, NDC ``p = (2 (j + 0.5) / W - 1, 1 - 2 (i + 0.5) / H, 1)``.
* A triangle with clip vertices ``(x_k, y_k, z_k, w_k)`` is drawn only if ``w_k > near`` for all
  three vertices (no near-plane clipping: a triangle crossing the near plane is dropped whole) and it
  is not degenerate. With ``v_k = (x_k, y_k, w_k)``:
  ``c_0 = p · (v_1 × v_2)``, ``c_1 = p · (v_2 × v_0)``, ``c_2 = p · (v_0 × v_1)``, ``s = c_0 + c_1 + c_2``,
  ``D = v_0 · (v_1 × v_2)``. The pixel is covered iff ``D != 0``, ``s != 0`` and ``c_k * sign(D) >= 0``
  for all k (edges included). Its perspective-correct barycentrics are ``c_k / s`` and its depth
  ``d = D / s`` (equal to the interpolated ``w``, i.e. the distance along the view axis).
* Candidate pixels of a triangle are those whose centres fall in its screen bounding box (a backend
  may widen it slightly against rounding: coverage is decided by the test above); the z-buffer keeps the smallest depth, and among equal depths the smallest face id.
* Background pixels get face id ``-1``. No back-face culling.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import torch

Tensor = torch.Tensor


def pixel_centres(height: int, width: int, dtype: torch.dtype = torch.float32,
                  device: torch.device | str | None = None) -> tuple[Tensor, Tensor]:
    """NDC coordinates of the pixel centres, the rule above: the one place it is computed (the
    backends' rasterizers and the shared shading all take it from here, so they agree bit for bit in
    every dtype).

    Returns:
        ``px`` ``(W,)`` = ``2 (j + 0.5) / W - 1`` per column and ``py`` ``(H,)`` = ``1 - 2 (i + 0.5) / H``
        per row, in ``dtype``.
    """
    cols = torch.arange(width, device=device).to(dtype)
    rows = torch.arange(height, device=device).to(dtype)
    return (2.0 * cols + 1.0) / width - 1.0, 1.0 - (2.0 * rows + 1.0) / height


@dataclass
class Light:
    """One directional light plus ambient light, in world coordinates.

    Attributes:
        direction: ``(B, 3)`` unit vectors pointing *towards* the light.
        ambient: ``(B, 3)`` ambient RGB intensity.
        diffuse: ``(B, 3)`` directional RGB intensity.

    A surface point with unit normal ``n`` and albedo ``a`` gets the colour
    ``a * (ambient + diffuse * max(0, n · direction))``.
    """

    direction: Tensor
    ambient: Tensor
    diffuse: Tensor

    @classmethod
    def white(cls, direction: Tensor, ambient: float = 0.4, diffuse: float = 0.6) -> Light:
        """White light from ``direction`` ``(B, 3)`` (normalised here)."""
        d = torch.nn.functional.normalize(direction, dim=-1)
        b = d.shape[0]
        ones = torch.ones(b, 3, dtype=d.dtype, device=d.device)
        return cls(d, ones * ambient, ones * diffuse)

    @classmethod
    def following(cls, camera, ambient: float = 0.4, diffuse: float = 0.6) -> Light:
        """White light shining along each camera's viewing direction (the paper's set-up)."""
        return cls.white(camera.view_direction(), ambient, diffuse)

    def index(self, idx) -> Light:
        return Light(self.direction[idx], self.ambient[idx], self.diffuse[idx])


@dataclass
class RenderOutput:
    """What :func:`cerberus_core.render.render` returns.

    Attributes:
        image: ``(B, 3, H, W)`` shaded RGB composited over the background colour (differentiable).
        alpha: ``(B, 1, H, W)`` 1 where a face is visible, 0 on background (not differentiable).
            With ``render(..., antialias=True)`` image and alpha are blended across silhouette edges
            (:mod:`cerberus_core.render.antialias`): alpha takes values in ``[0, 1]`` at silhouette
            pixels and both become differentiable w.r.t. the vertices of the silhouette edges (the
            visibility gradients); depth, face_id and part_id are never antialiased.
        depth: ``(B, 1, H, W)`` depth ``d = -z_cam`` in world units, 0 on background (differentiable).
        face_id: ``(B, H, W)`` int64 index into the packed faces, -1 on background.
        part_id: ``(B, H, W)`` int64 part index, -1 on background.
    """

    image: Tensor
    alpha: Tensor
    depth: Tensor
    face_id: Tensor
    part_id: Tensor


class Renderer(ABC):
    """A rasterizer backend. Subclasses register under the ``cerberus.renderers`` entry-point group.

    Args:
        device: ignored by backends that follow the tensors' device (both shipped ones do); kept so
            configs can pass it uniformly.
    """

    name: ClassVar[str] = "abstract"

    def __init__(self, **options) -> None:
        unknown = set(options) - {"device"}
        if unknown:
            raise TypeError(f"renderer '{self.name}' got unknown options {sorted(unknown)}")

    @abstractmethod
    def rasterize(self, clip: Tensor, faces: Tensor, height: int, width: int, near: float) -> Tensor:
        """Visible face per pixel (not differentiable; called under ``torch.no_grad``).

        Args:
            clip: ``(B, V, 4)`` float32 clip-space vertices (finite; checked by the caller).
            faces: ``(F, 3)`` int64 vertex indices (valid; checked by the caller).
            height, width: image size in pixels.
            near: triangles with a vertex of ``w <= near`` are not drawn.
        Returns:
            ``(B, H, W)`` int64 face ids, -1 on background, following the rule in this module's
            docstring.
        """

    def vertex_normals(self, vertices: Tensor, faces: Tensor) -> Tensor:
        """Differentiable area-weighted unit vertex normals (default: the shared torch code).

        Args:
            vertices: ``(B, V, 3)`` world coordinates.
            faces: ``(F, 3)`` int64.
        Returns:
            ``(B, V, 3)`` unit normals, the maths of :func:`cerberus_core.render.templates.vertex_normals`.
        """
        from cerberus_core.render.templates import vertex_normals

        return vertex_normals(vertices, faces)

    def shade(self, clip: Tensor, faces: Tensor, face_id: Tensor, normals: Tensor, albedo: Tensor,
              light: Light) -> tuple[Tensor, Tensor]:
        """Differentiable shading of the visible surface (default: the shared torch reference).

        Args:
            clip: ``(B, V, 4)`` clip-space vertices.
            faces: ``(F, 3)`` int64.
            face_id: ``(B, H, W)`` int64 from :meth:`rasterize`.
            normals: ``(B, V, 3)`` unit world-space vertex normals.
            albedo: ``(B, V, 3)`` per-vertex albedo.
            light: the scene light.
        Returns:
            ``rgb`` ``(B, H, W, 3)`` and ``depth`` ``(B, H, W)``, both 0 on background pixels.
        """
        from cerberus_core.render.shading import shade

        return shade(clip, faces, face_id, normals, albedo, light)

    def antialias(self, color: Tensor, clip: Tensor, faces: Tensor, face_id: Tensor) -> Tensor:
        """Differentiable analytic anti-aliasing of silhouette edges (default: the shared torch
        reference :func:`cerberus_core.render.antialias.antialias`, whose docstring is the contract).

        Args:
            color: ``(B, H, W, C)`` channels-last colours (e.g. RGB and alpha concatenated).
            clip: ``(B, V, 4)`` clip-space vertices the image was rasterized from.
            faces: ``(F, 3)`` int64.
            face_id: ``(B, H, W)`` int64 from :meth:`rasterize`.
        Returns:
            ``(B, H, W, C)`` blended colours, differentiable w.r.t. ``color`` and ``clip``.
        """
        from cerberus_core.render.antialias import antialias

        return antialias(color, clip, faces, face_id)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"
