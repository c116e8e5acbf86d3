"""Shared mesh builders and independent oracles for the cerberus-metrics tests (the ``helpers`` fixture), and
the ``box`` and ``folders`` (a batch of predictions and ground truths) fixtures."""

from __future__ import annotations

from collections import deque

import numpy as np
import pytest
import trimesh


def box_mesh(lo, hi) -> trimesh.Trimesh:
    """Closed axis-aligned box with corners lo, hi (mesh units)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    m = trimesh.creation.box(extents=hi - lo)
    m.apply_translation((lo + hi) / 2)
    return m


def blob_mesh(seed: int, radius: float = 0.3, centre=(0.0, 0.0, 0.0), subdivisions: int = 2) -> trimesh.Trimesh:
    """Star-shaped closed blob: an icosphere with a smooth random radial deformation."""
    rng = np.random.default_rng(seed)
    m = trimesh.creation.icosphere(subdivisions=subdivisions)
    d = m.vertices
    k = rng.normal(size=(3, 3))
    r = radius * (1 + 0.25 * np.sin(d @ k[0] * 2 + k[1, 0]) * np.cos(d @ k[2] * 1.5))
    return trimesh.Trimesh(d * r[:, None] * rng.uniform(0.7, 1.2, 3) + np.asarray(centre), m.faces, process=False)


def winding_numbers(points: np.ndarray, tri: np.ndarray, chunk: int = 2048) -> np.ndarray:
    """Generalised winding number of (N,3) points w.r.t. (F,3,3) triangles (solid-angle sum / 4 pi).

    Van Oosterom-Strackee solid angle per triangle, written component-wise for speed.
    """
    out = np.empty(len(points))
    t = [[tri[None, :, i, k] for k in range(3)] for i in range(3)]  # t[corner][axis]: (1, F)
    for s in range(0, len(points), chunk):
        p = points[s : s + chunk]
        a, b, c = ([t[i][k] - p[:, k, None] for k in range(3)] for i in range(3))
        la, lb, lc = (np.sqrt(x[0] ** 2 + x[1] ** 2 + x[2] ** 2) for x in (a, b, c))
        cx = b[1] * c[2] - b[2] * c[1]
        cy = b[2] * c[0] - b[0] * c[2]
        cz = b[0] * c[1] - b[1] * c[0]
        num = a[0] * cx + a[1] * cy + a[2] * cz
        ab = a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
        bc = b[0] * c[0] + b[1] * c[1] + b[2] * c[2]
        ca = c[0] * a[0] + c[1] * a[1] + c[2] * a[2]
        den = la * lb * lc + ab * lc + bc * la + ca * lb
        out[s : s + chunk] = np.arctan2(num, den).sum(axis=1) / (2 * np.pi)
    return out


def flood_fill_bfs(surface: np.ndarray) -> np.ndarray:
    """Textbook BFS: solid = not reachable (6-connected, through empty voxels) from empty border voxels."""
    n = surface.shape
    seen = np.zeros(n, bool)
    q = deque()
    for idx in zip(*np.nonzero(~surface), strict=True):
        if min(idx) == 0 or any(i == s - 1 for i, s in zip(idx, n, strict=True)):
            seen[idx] = True
            q.append(idx)
    while q:
        x, y, z = q.popleft()
        for dx, dy, dz in ((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1)):
            j = (x + dx, y + dy, z + dz)
            if all(0 <= j[k] < n[k] for k in range(3)) and not seen[j] and not surface[j]:
                seen[j] = True
                q.append(j)
    return ~seen


def kato_surface_loops(tri: np.ndarray, size: int) -> np.ndarray:
    """Slow, literal reading of Kato's surface rule on the grid [0, size)^3 (oracle for the vectorised one).

    For each ray axis and each integer line (u, w) inside a triangle's projected box: closed barycentric
    test, skip degenerate projections, height index floor(h), mark the 4 voxels around the line.
    Plus the voxel of every triangle corner.
    """
    occ = np.zeros((size,) * 3, bool)

    def mark(c):
        if all(0 <= c[i] < size for i in range(3)):
            occ[c[0], c[1], c[2]] = True

    axes = {0: (2, 1), 1: (0, 2), 2: (0, 1)}
    for axis, (ua, wa) in axes.items():
        for t in tri:
            (u0, w0, a0), (u1, w1, a1), (u2, w2, a2) = ((v[ua], v[wa], v[axis]) for v in t)
            det = (w1 - w0) * (u2 - u0) - (w2 - w0) * (u1 - u0)
            if det == 0:
                continue
            u_lines = range(max(0, int(np.ceil(min(u0, u1, u2)))), min(size - 1, int(np.floor(max(u0, u1, u2)))) + 1)
            w_lines = range(max(0, int(np.ceil(min(w0, w1, w2)))), min(size - 1, int(np.floor(max(w0, w1, w2)))) + 1)
            for u in u_lines:
                for w in w_lines:
                    t1 = ((u2 - u0) * (w - w0) - (w2 - w0) * (u - u0)) / det
                    t2 = (-(u1 - u0) * (w - w0) + (w1 - w0) * (u - u0)) / det
                    if t1 < 0 or t2 < 0 or t1 + t2 > 1:
                        continue
                    h = int(np.floor(a0 + t1 * (a1 - a0) + t2 * (a2 - a0)))
                    for du in (0, 1):
                        for dw in (0, 1):
                            c = [0, 0, 0]
                            c[ua], c[wa], c[axis] = u - du, w - dw, h
                            mark(c)
    for v in tri.reshape(-1, 3):
        mark(np.floor(v).astype(int))
    return occ


@pytest.fixture
def helpers():
    """Namespace of builders and oracles (tests import only the installed package)."""

    class H:
        box = staticmethod(box_mesh)
        blob = staticmethod(blob_mesh)
        winding = staticmethod(winding_numbers)
        bfs_fill = staticmethod(flood_fill_bfs)
        kato_loops = staticmethod(kato_surface_loops)

    return H


@pytest.fixture
def box(helpers):
    return helpers.box((-0.3, -0.2, -0.1), (0.25, 0.3, 0.2))


@pytest.fixture
def folders(tmp_path, helpers):
    pred, gt = tmp_path / "pred", tmp_path / "gt"
    pred.mkdir()
    gt.mkdir()
    for i in range(3):
        helpers.blob(10 + i).export(gt / f"s{i}.ply")
        helpers.blob(20 + i).export(pred / f"s{i}.ply")
    (pred / "parts").mkdir()  # a prediction made of parts, matched by folder name
    helpers.box((-0.3, -0.3, -0.3), (0.0, 0.2, 0.2)).export(pred / "parts" / "a.obj")
    helpers.box((-0.1, -0.3, -0.3), (0.2, 0.2, 0.2)).export(pred / "parts" / "b.obj")
    helpers.box((-0.3, -0.3, -0.3), (0.2, 0.2, 0.2)).export(gt / "parts.obj")
    (pred / "broken.obj").write_text("this is not a mesh\nv 1\n")  # unreadable prediction
    helpers.blob(1).export(gt / "broken.obj")
    (pred / "empty.obj").write_text("# no faces\nv 0 0 0\nv 1 0 0\nv 0 1 0\n")
    helpers.blob(2).export(gt / "empty.obj")
    helpers.blob(3).export(gt / "lonely.ply")  # no prediction
    return pred, gt
