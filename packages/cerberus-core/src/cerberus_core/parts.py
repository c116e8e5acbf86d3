"""Posed parts: the one object for "``P`` part meshes per image" (the model's output, what
evaluation scores, what the exporters and figures take).

A part set of ``B`` images with ``P`` parts is, for every part, a deformed template in the part's own
local frame plus a rigid transform into a frame (the world frame of
:mod:`cerberus_core.render.camera`, +Y up, normalised units, unless said otherwise). A part's posed
vertices are ``local @ R^T + T`` (:func:`pose_parts`, the one place that formula is written).

Keeping the shapes and the transforms apart is what lets the evaluation re-pose one image's parts
with another image's transforms (the paper's "Hard Human" test and Figure 1 (f), "New Pose"):
:func:`transfer_pose`.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from cerberus_core.errors import MeshError, ShapeError
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor


def pose_parts(local_vertices: Tensor, rotations: Tensor, translations: Tensor) -> Tensor:
    """Rotate and translate part meshes: ``x' = R x + T`` (any leading batch dimensions).

    Args:
        local_vertices: ``(..., P, V, 3)``.
        rotations: ``(..., P, 3, 3)``.
        translations: ``(..., P, 3)``.
    Returns:
        ``(..., P, V, 3)``.
    """
    return local_vertices @ rotations.transpose(-1, -2) + translations.unsqueeze(-2)


@dataclass
class PartSet:
    """``P`` part meshes for each of ``B`` images.

    Attributes:
        local_vertices: ``(B, P, V, 3)`` each part's deformed template in its local frame (before
            rotation and translation), normalised units.
        faces: ``(F, 3)`` int64 template faces shared by every part and image.
        rotations: ``(B, P, 3, 3)`` local→world rotations.
        translations: ``(B, P, 3)`` world-frame translations (normalised units).
    """

    local_vertices: Tensor
    faces: Tensor
    rotations: Tensor
    translations: Tensor

    def __post_init__(self) -> None:
        lv, f, r, t = self.local_vertices, self.faces, self.rotations, self.translations
        v = check_shapes("PartSet", local_vertices=(lv, "B P V 3"), faces=(f, "F 3"), rotations=(r, "B P 3 3"),
                         translations=(t, "B P 3"))["V"]
        if f.dtype not in (torch.int32, torch.int64):
            raise ShapeError(f"PartSet.faces must be an integer tensor, got {f.dtype}; pass `faces.long()`")
        if f.numel() and (int(f.min()) < 0 or int(f.max()) >= v):
            raise MeshError(f"PartSet.faces index vertices outside 0..{v - 1}; pass the faces of the template the "
                            "vertices were made from")

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_posed(cls, vertices: Tensor, faces: Tensor) -> PartSet:
        """Wrap meshes already in world coordinates (identity rotations, zero translations).

        Useful for baselines that predict one mesh per image (``P = 1``, e.g. NMR) or for ground
        truths made of parts.

        Args:
            vertices: ``(B, P, V, 3)`` or ``(B, V, 3)`` (one part) world coordinates.
            faces: ``(F, 3)`` shared faces.
        """
        if vertices.ndim == 3:
            vertices = vertices.unsqueeze(1)
        b, p = vertices.shape[:2]
        eye = torch.eye(3, dtype=vertices.dtype, device=vertices.device).expand(b, p, 3, 3).clone()
        zero = torch.zeros(b, p, 3, dtype=vertices.dtype, device=vertices.device)
        return cls(vertices, faces.to(device=vertices.device, dtype=torch.int64), eye, zero)

    # ------------------------------------------------------------------ properties
    @property
    def batch_size(self) -> int:
        return self.local_vertices.shape[0]

    @property
    def num_parts(self) -> int:
        return self.local_vertices.shape[1]

    @property
    def num_vertices(self) -> int:
        """Vertices per part."""
        return self.local_vertices.shape[2]

    def posed(self) -> Tensor:
        """``(B, P, V, 3)`` world vertices ``local @ R^T + T`` (differentiable)."""
        return pose_parts(self.local_vertices, self.rotations, self.translations)

    # ------------------------------------------------------------------ batch handling
    def index(self, idx: int | slice | list[int] | Tensor) -> PartSet:
        """A sub-batch (an ``int`` keeps a batch dimension of 1)."""
        if isinstance(idx, int):
            idx = slice(idx, idx + 1) if idx != -1 else slice(-1, None)
        return PartSet(self.local_vertices[idx], self.faces, self.rotations[idx], self.translations[idx])

    def to(self, device: torch.device | str) -> PartSet:
        return PartSet(self.local_vertices.to(device), self.faces.to(device), self.rotations.to(device),
                       self.translations.to(device))

    def detach(self) -> PartSet:
        return PartSet(self.local_vertices.detach(), self.faces.detach(), self.rotations.detach(),
                       self.translations.detach())

    @staticmethod
    def cat(items: list[PartSet]) -> PartSet:
        """Concatenate batches that share the face template."""
        first = items[0]
        for it in items[1:]:
            if it.faces.shape != first.faces.shape or not torch.equal(it.faces.cpu(), first.faces.cpu()):
                raise MeshError("PartSet.cat: reconstructions must share one face template; concatenate only "
                                "reconstructions of one model")
        return PartSet(torch.cat([i.local_vertices for i in items]), first.faces,
                                  torch.cat([i.rotations for i in items]), torch.cat([i.translations for i in items]))

    def part_meshes(self, i: int) -> list[tuple[np.ndarray, np.ndarray]]:
        """The posed parts of image ``i`` as ``(vertices (V, 3) float64, faces (F, 3) int64)`` numpy
        pairs (the form the ``voxel_iou`` metric and the exporters take)."""
        posed = self.index(i).posed()[0].detach().cpu().double().numpy()
        faces = self.faces.detach().cpu().numpy().astype(np.int64)
        return [(posed[k], faces) for k in range(self.num_parts)]


def transfer_pose(shapes: PartSet, poses: PartSet) -> PartSet:
    """Give the part shapes of ``shapes`` the rotations and translations of ``poses``.

    Used by the identity-conditional ("Hard Human") evaluation, where the parts extracted once from
    a subject's canonical-pose image are posed with the transforms predicted from every other image
    of that subject, and by the "new pose" picture of Figure 1 (f).

    Args:
        shapes: batch ``1`` (broadcast) or ``B`` — provides ``local_vertices``.
        poses: batch ``B`` — provides ``rotations`` and ``translations``; must have the same number
            of parts as ``shapes``.
    Returns:
        A batch-``B`` reconstruction whose ``posed()`` is ``shapes.local @ poses.R^T + poses.T``.
    """
    if shapes.num_parts != poses.num_parts:
        raise ShapeError(f"transfer_pose: shapes have {shapes.num_parts} parts but poses have {poses.num_parts}; "
                         "pass shapes and poses of one model")
    b = poses.batch_size
    if shapes.batch_size not in (1, b):
        raise ShapeError(f"transfer_pose: shapes batch must be 1 or {b}, got {shapes.batch_size}; pass one shape, "
                         "or one per pose")
    local = shapes.local_vertices.to(poses.rotations.device)
    if local.shape[0] != b:
        local = local.expand(b, -1, -1, -1)
    return PartSet(local, shapes.faces.to(local.device), poses.rotations, poses.translations)


def pose_donors(n: int, avoid: Sequence[bool] | None = None) -> list[int | None]:
    """For each of ``n`` images, the image whose rotations and translations its "new pose" borrows (Figure 1 (f),
    :func:`transfer_pose`): the next image (cyclically) not marked in ``avoid`` (e.g. out of the training
    domain, whose pose is unreliable), else the next image; ``None`` for a single image (no other pose).

    Args:
        n: the number of images.
        avoid: ``n`` flags, ``True`` for an image whose pose should not be borrowed (default: none).
    Returns:
        ``n`` indices (never the image's own) or ``None``.
    """
    if avoid is not None and len(avoid) != n:
        raise ShapeError(f"pose_donors: {len(avoid)} flags for {n} images; pass one flag per image")
    if n < 2:
        return [None] * n
    flags = [False] * n if avoid is None else [bool(a) for a in avoid]
    out: list[int | None] = []
    for i in range(n):
        others = [(i + k) % n for k in range(1, n)]
        out.append(next((j for j in others if not flags[j]), others[0]))
    return out
