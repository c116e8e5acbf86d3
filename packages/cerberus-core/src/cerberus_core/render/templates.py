"""Mesh templates: the icosphere each part deforms, with the connectivity the losses need.

The paper deforms a sphere of 162 vertices and 320 faces (icosphere subdivision level 2) per part.
Icospheres come from :func:`trimesh.creation.icosphere`; this module adds what the model and the
smoothness loss need (edges, dihedral quadruples, vertex adjacency) as torch tensors. trimesh (which
imports scipy when it is installed) is imported only when a template is built, so that
``import cerberus_core.render`` needs torch alone.
"""
from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from typing import TYPE_CHECKING

import numpy as np
import torch

from cerberus_core.errors import ConfigError, MeshError

if TYPE_CHECKING:
    import trimesh

Tensor = torch.Tensor


@dataclass(frozen=True)
class MeshTemplate:
    """A closed triangle mesh used as the starting shape of a part.

    Attributes:
        vertices: ``(V, 3)`` float32 rest positions (unit sphere for icospheres).
        faces: ``(F, 3)`` int64, counter-clockwise seen from outside.
        edges: ``(E, 2)`` int64 unique undirected edges ``(i, j)`` with ``i < j``.
        dihedral: ``(E', 4)`` int64 for every edge shared by two faces: ``(a, b, c, d)`` where ``a-b``
            is the shared edge and ``c``, ``d`` are the opposite vertices of the two faces. The
            smoothness loss of Kato et al. measures the angle between the faces ``(a, b, c)`` and
            ``(a, b, d)`` through these.
        neighbours: ``(V, K)`` int64 vertex adjacency padded with ``-1`` (K = max valence).
    """

    vertices: Tensor
    faces: Tensor
    edges: Tensor
    dihedral: Tensor
    neighbours: Tensor

    @property
    def num_vertices(self) -> int:
        return self.vertices.shape[0]

    @property
    def num_faces(self) -> int:
        return self.faces.shape[0]

    def to(self, device: torch.device | str) -> MeshTemplate:
        return MeshTemplate(*(getattr(self, k).to(device) for k in ("vertices", "faces", "edges", "dihedral", "neighbours")))

    @classmethod
    def from_trimesh(cls, mesh: trimesh.Trimesh) -> MeshTemplate:
        """Build a template (with its connectivity) from any closed trimesh."""
        if len(mesh.faces) == 0:
            raise MeshError("MeshTemplate needs a mesh with at least one face; build it from a closed triangle mesh")
        faces = np.asarray(mesh.faces, dtype=np.int64)
        edges = np.asarray(mesh.edges_unique, dtype=np.int64)
        edges = np.sort(edges, axis=1)
        shared = np.asarray(mesh.face_adjacency_edges, dtype=np.int64)
        opposite = np.asarray(mesh.face_adjacency_unshared, dtype=np.int64)
        dihedral = np.concatenate([shared, opposite], axis=1) if len(shared) else np.zeros((0, 4), np.int64)
        nbrs = mesh.vertex_neighbors
        k = max((len(n) for n in nbrs), default=0)
        table = np.full((len(mesh.vertices), k), -1, dtype=np.int64)
        for i, n in enumerate(nbrs):
            table[i, : len(n)] = n
        return cls(
            torch.as_tensor(np.asarray(mesh.vertices, dtype=np.float32)),
            torch.as_tensor(faces),
            torch.as_tensor(edges),
            torch.as_tensor(dihedral),
            torch.as_tensor(table),
        )


@lru_cache(maxsize=8)
def _icosphere_cached(level: int) -> MeshTemplate:
    # Heavy dependency, imported when a template is first built: trimesh pulls in scipy (when
    # installed), which `import cerberus_core.render` must not need (module docstring).
    import trimesh.creation

    return MeshTemplate.from_trimesh(trimesh.creation.icosphere(subdivisions=level, radius=1.0))


def icosphere(level: int = 2, radius: float = 1.0) -> MeshTemplate:
    """The icosphere template of a subdivision level.

    Level 2 is the paper's part template: 162 vertices, 320 faces. Level ``k`` has
    ``10 * 4**k + 2`` vertices and ``20 * 4**k`` faces.

    Args:
        level: subdivision level, 0 to 6.
        radius: sphere radius.
    """
    if not isinstance(level, int) or not 0 <= level <= 6:
        raise ConfigError.about("level", level, "icosphere level must be an integer in 0..6",
                                "`level=2` is the paper's part template")
    t = _icosphere_cached(level)
    if radius == 1.0:
        return t
    return MeshTemplate(t.vertices * radius, t.faces, t.edges, t.dihedral, t.neighbours)


NORMAL_EPS = 1e-12
"""The ``eps`` of every normalisation of a normal (``torch.nn.functional.normalize``): vertex normals
here, interpolated normals in the shading; backends that compute them in kernels use the same."""


def vertex_normals(vertices: Tensor, faces: Tensor) -> Tensor:
    """Area-weighted vertex normals, differentiable.

    Args:
        vertices: ``(B, V, 3)``.
        faces: ``(F, 3)`` int64 indices into ``V``.
    Returns:
        ``(B, V, 3)`` unit normals (zero vectors stay zero-safe: a vertex with no area gets ``(0,0,0)``).
    """
    v0 = vertices[:, faces[:, 0]]
    v1 = vertices[:, faces[:, 1]]
    v2 = vertices[:, faces[:, 2]]
    face_n = torch.linalg.cross(v1 - v0, v2 - v0, dim=-1)  # length = 2 * area
    normals = torch.zeros_like(vertices)
    idx = faces.reshape(-1)
    normals = normals.index_add(1, idx, face_n.repeat_interleave(3, dim=1))
    return torch.nn.functional.normalize(normals, dim=-1, eps=NORMAL_EPS)
