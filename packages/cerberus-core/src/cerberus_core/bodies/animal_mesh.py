"""Meshing helpers for the procedural animals: a crack-free marching cubes and a decimation wrapper.

The marching-cubes table is generated (not copied) from one fixed rule for ambiguous cube faces:
on a face whose two diagonal corners are inside, the inside corners are *separated*. Because the
rule depends only on the four corner signs of a face, the two cubes sharing a face always cut it
the same way, so the output is a closed, edge- and vertex-manifold, consistently wound surface
whenever the sampled field is positive on the whole grid border. Each cube's polygon loops are
fan-triangulated from a root chosen so that no fan diagonal joins two vertices on a common cube
face (such a diagonal could be generated again by the neighbouring cube).

Sign convention: the field is negative inside the solid; triangles are counter-clockwise seen
from outside (normals point towards increasing field).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from cerberus_core.errors import BodyError, MeshError, MissingPackageError
from cerberus_core.shapes import check_shapes

_CORNERS = np.array([[c & 1, (c >> 1) & 1, (c >> 2) & 1] for c in range(8)])
"""``(8, 3)`` corner offsets of a cube; corner index ``c = x + 2 y + 4 z``."""

_EDGES = np.array([(c, c | (1 << ax), ax) for c in range(8) for ax in range(3) if not (c >> ax) & 1])
"""``(12, 3)`` cube edges as (low corner, high corner, axis)."""


def _face_cycles() -> list[list[int]]:
    faces = []
    for ax in range(3):
        others = [a for a in range(3) if a != ax]
        for side in (0, 1):
            cyc = []
            for u, v in ((0, 0), (1, 0), (1, 1), (0, 1)):
                c = np.zeros(3, int)
                c[ax], c[others[0]], c[others[1]] = side, u, v
                cyc.append(int(c[0] + 2 * c[1] + 4 * c[2]))
            faces.append(cyc)
    return faces


def _edge_index(a: int, b: int) -> int:
    for i, (p, q, _) in enumerate(_EDGES):
        if {int(p), int(q)} == {a, b}:
            return i
    raise MeshError(f"the marching-cubes table has no edge between corners {a} and {b}")


def _case_triangles(case: int, faces: list[list[int]], edge_faces: list[set[int]]) -> list[tuple[int, int, int]]:
    """Triangles (as triples of cube-edge indices) for one of the 256 inside/outside corner cases."""
    inside = [(case >> c) & 1 for c in range(8)]
    adj: dict[int, list[int]] = {}
    for cyc in faces:
        s = [inside[c] for c in cyc]
        if sum(s) in (0, 4):
            continue
        for i in range(4):  # every maximal run of inside corners yields one segment
            if s[i] and not s[i - 1]:
                j = i
                while s[(j + 1) % 4]:
                    j = (j + 1) % 4
                a, b = _edge_index(cyc[i - 1], cyc[i]), _edge_index(cyc[j], cyc[(j + 1) % 4])
                adj.setdefault(a, []).append(b)
                adj.setdefault(b, []).append(a)
    seen: set[int] = set()
    tris: list[tuple[int, int, int]] = []
    for start in sorted(adj):
        if start in seen:
            continue
        loop, prev, cur = [start], -1, start
        seen.add(start)
        while True:
            nxt = adj[cur][0] if adj[cur][0] != prev else adj[cur][1]
            if nxt == start:
                break
            loop.append(nxt)
            seen.add(nxt)
            prev, cur = cur, nxt
        # orient: polygon normal must point from the inside corners to the outside corners
        mid = np.array([0.5 * (_CORNERS[_EDGES[e, 0]] + _CORNERS[_EDGES[e, 1]]) for e in loop], float)
        normal = np.cross(mid, np.roll(mid, -1, axis=0)).sum(0)
        out_dir = np.zeros(3)
        for e in loop:
            lo, hi = _CORNERS[_EDGES[e, 0]], _CORNERS[_EDGES[e, 1]]
            out_dir += (hi - lo) if inside[_EDGES[e, 0]] else (lo - hi)
        if normal @ out_dir < 0:
            loop = loop[::-1]
        n = len(loop)
        for r in range(n):
            lp = loop[r:] + loop[:r]
            if all(not (edge_faces[lp[0]] & edge_faces[lp[k]]) for k in range(2, n - 1)):
                tris.extend((lp[0], lp[k], lp[k + 1]) for k in range(1, n - 1))
                break
        else:  # never happens for the separated-inside rule (checked when the table is built)
            raise BodyError(f"marching cubes table: no safe fan for case {case}")
    return tris


@lru_cache(maxsize=1)
def _mc_table() -> tuple[np.ndarray, np.ndarray]:
    """``(table (256, T, 3) cube-edge indices, -1 padded; ntri (256,))``."""
    faces = _face_cycles()
    edge_faces = [{f for f, cyc in enumerate(faces) if _EDGES[e, 0] in cyc and _EDGES[e, 1] in cyc} for e in range(12)]
    cases = [_case_triangles(c, faces, edge_faces) for c in range(256)]
    max_t = max(len(t) for t in cases)
    table = -np.ones((256, max_t, 3), np.int64)
    for c, t in enumerate(cases):
        if t:
            table[c, : len(t)] = t
    return table, np.array([len(t) for t in cases])


def marching_cubes(values: np.ndarray, origin: np.ndarray, spacing: float) -> tuple[np.ndarray, np.ndarray]:
    """Extract the zero level set of a sampled scalar field.

    Args:
        values: ``(nx, ny, nz)`` field samples, negative inside; must be positive on the grid border
            for the output to be closed.
        origin: ``(3,)`` world position of ``values[0, 0, 0]``.
        spacing: grid step (world units).

    Returns:
        ``(vertices (V, 3) float64, faces (F, 3) int64)``; faces counter-clockwise from outside.
        Vertices lie on grid edges (interpolation parameter clipped to [0.02, 0.98] so no two
        vertices coincide).
    """
    vals = np.asarray(values, np.float64)
    check_shapes("marching_cubes", values=(vals, "X Y Z"))
    if min(vals.shape) < 2:
        raise BodyError(f"marching_cubes needs >= 2 samples per axis, got {vals.shape}")
    table, ntri = _mc_table()
    nx, ny, nz = vals.shape
    inside = vals < 0
    case = np.zeros((nx - 1, ny - 1, nz - 1), np.uint8)
    for c, (dx, dy, dz) in enumerate(_CORNERS):
        case |= inside[dx : nx - 1 + dx, dy : ny - 1 + dy, dz : nz - 1 + dz].astype(np.uint8) << c
    ci, cj, ck = np.nonzero((case > 0) & (case < 255))
    if ci.size == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    cs = case[ci, cj, ck]
    base = (ci * ny + cj) * nz + ck
    corner_off = (_CORNERS[:, 0] * ny + _CORNERS[:, 1]) * nz + _CORNERS[:, 2]
    edge_lo_off, edge_axis = corner_off[_EDGES[:, 0]], _EDGES[:, 2]
    nt = ntri[cs]
    keys = []
    for n in range(table.shape[1]):
        sel = np.nonzero(nt > n)[0]
        if sel.size == 0:
            break
        e = table[cs[sel], n]  # (S, 3) cube-edge indices
        keys.append(3 * (base[sel, None] + edge_lo_off[e]) + edge_axis[e])  # unique id per grid edge
    uniq, inverse = np.unique(np.concatenate(keys).ravel(), return_inverse=True)
    faces = inverse.reshape(-1, 3).astype(np.int64)
    lo, axis = np.divmod(uniq, 3)
    hi = lo + np.array([ny * nz, nz, 1])[axis]
    flat = vals.ravel()
    v0, v1 = flat[lo], flat[hi]
    t = np.clip(v0 / (v0 - v1), 0.02, 0.98)
    i, rem = np.divmod(lo, ny * nz)
    j, k = np.divmod(rem, nz)
    pos = np.stack([i, j, k], axis=1).astype(np.float64)
    pos[np.arange(len(pos)), axis] += t
    return np.asarray(origin, np.float64) + spacing * pos, faces


def decimate(vertices: np.ndarray, faces: np.ndarray, target_faces: int) -> tuple[np.ndarray, np.ndarray]:
    """Quadric edge-collapse decimation (pymeshlab) that preserves topology.

    Args:
        vertices: ``(V, 3)`` float.
        faces: ``(F, 3)`` int.
        target_faces: desired face count; meshes already at or below it are returned unchanged.

    Returns:
        ``(vertices (V', 3) float64, faces (F', 3) int64)``.
    """
    if len(faces) <= target_faces:
        return vertices, faces
    try:
        import pymeshlab  # local import: only needed when decimating
    except ImportError as exc:
        raise MissingPackageError("the animal bodies need pymeshlab: pip install 'cerberus-core[animal]'") from exc

    ms = pymeshlab.MeshSet()
    ms.add_mesh(pymeshlab.Mesh(np.ascontiguousarray(vertices, np.float64), np.ascontiguousarray(faces, np.int32)))
    ms.meshing_decimation_quadric_edge_collapse(
        targetfacenum=int(target_faces), preservetopology=True, optimalplacement=True, qualitythr=0.4, autoclean=True
    )
    m = ms.current_mesh()
    return np.asarray(m.vertex_matrix(), np.float64), np.asarray(m.face_matrix(), np.int64)
