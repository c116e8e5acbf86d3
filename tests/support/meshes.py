"""Checks of generated meshes, for the body-source tests."""
from __future__ import annotations

import numpy as np
import trimesh
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from cerberus_core.bodies.body import PosedBody


def vertex_manifold(faces: np.ndarray, n_vertices: int) -> bool:
    """True if the faces around every used vertex form one closed fan (link is a single cycle)."""
    a, b, c = (np.concatenate([faces[:, i], faces[:, (i + 1) % 3], faces[:, (i + 2) % 3]]) for i in range(3))
    k1, k2 = a.astype(np.int64) * n_vertices + b, a.astype(np.int64) * n_vertices + c
    keys, inv = np.unique(np.concatenate([k1, k2]), return_inverse=True)
    m = len(k1)
    graph = coo_matrix((np.ones(m), (inv[:m], inv[m:])), shape=(len(keys), len(keys)))
    n_comp, comp = connected_components(graph, directed=False)
    centre = np.zeros(n_comp, np.int64)
    centre[comp] = keys // n_vertices
    per_vertex = np.bincount(centre, minlength=n_vertices)
    return bool((per_vertex[np.unique(faces)] == 1).all())


def assert_closed(body_or_mesh: PosedBody | tuple[np.ndarray, np.ndarray]) -> None:
    """A closed, consistently wound, outward-facing and vertex-manifold triangle mesh (a body or ``(v, f)``)."""
    v, f = (body_or_mesh.vertices, body_or_mesh.faces) if isinstance(body_or_mesh, PosedBody) else body_or_mesh
    mesh = trimesh.Trimesh(v, f, process=False)
    assert mesh.is_watertight
    assert mesh.is_winding_consistent
    assert mesh.volume > 0  # outward normals
    assert vertex_manifold(np.asarray(f), len(v))
    assert trimesh.Trimesh(v, f).is_watertight  # still closed after trimesh merges close vertices
