"""The renderer contract every backend implements, and the types that cross it.

The split follows nvdiffrast and TF Graphics: a backend's must-have is the hot, non-differentiable
step, :meth:`Renderer.rasterize` (clip-space triangles → visible face id per pixel). Everything
differentiable (vertex normals, perspective-correct barycentrics recomputed from the face ids,
interpolation of normals and albedo, Lambertian shading, depth) is done by
:func:`cerberus_core.render.templates.vertex_normals` and :func:`cerberus_core.render.shading.shade` in plain
torch, shared by all backends. A backend may override :meth:`Renderer.vertex_normals`,
:meth:`Renderer.shade`, :meth:`Renderer.antialias` and :meth:`Renderer.nearest_indices` (the image-plane
nearest-neighbour search of the training pulls) with fused kernels (forward and backward) when that is faster; the conformance suite in :mod:`cerberus_core.testing`
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

from cerberus_core.errors import InputTypeError
from cerberus_core.render.antialias import antialias
from cerberus_core.render.light import Light
from cerberus_core.render.nearest import nearest_indices
from cerberus_core.render.shading import shade
from cerberus_core.render.templates import vertex_normals

Tensor = torch.Tensor

#: The contract's types and its pixel rule, importable from here as the backends always have.
__all__ = ["RenderOutput", "Renderer"]


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
            raise InputTypeError(f"renderer '{self.name}' got unknown options {sorted(unknown)}; pass only the options "
                                 "its class documents (and `device`)")

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
        return antialias(color, clip, faces, face_id)

    def nearest_indices(self, points: Tensor, targets: Tensor, counts: Tensor,
                        both: bool = True) -> tuple[Tensor, Tensor | None]:
        """Nearest neighbours between 2-D point sets per image, without gradient (default: the
        shared batched torch search :func:`cerberus_core.render.nearest.nearest_indices`, whose
        docstring is the contract; the chamfer and hidden-part pulls of training call it).

        Args:
            points: ``(N, M, 2)``; targets: ``(N, K, 2)``, the first ``counts[n]`` real in image ``n``;
            counts: ``(N,)`` int64; both: also each target's nearest point.
        Returns:
            ``to_target`` ``(N, M)`` and ``to_point`` ``(N, K)`` (or ``None``), int64.
        """
        return nearest_indices(points, targets, counts, both)

    def __repr__(self) -> str:
        return f"{type(self).__name__}(name={self.name!r})"
