"""An independent reference renderer in numpy (float64), dense over pixels x triangles.

It shares no code with cerberus-core or any backend: its own look-at camera, screen-space (2D)
edge functions with perspective-correct interpolation through ``1/w`` (a different formula from the
homogeneous one in the contract, equal to it for triangles in front of the camera), its own
area-weighted vertex normals and Lambert shading. Only for tiny scenes: memory is ``O(F * H * W)``.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

EDGE_TOL = 1e-5
"""A pixel whose smallest screen barycentric is within this of 0 lies on an edge: float rounding may
put it on either side, so backends may disagree there."""
DEPTH_TOL = 1e-5
"""Relative depth difference under which two faces tie at a pixel."""


@dataclass
class PinholeCamera:
    """One look-at camera (world +Y up, camera looking along -Z, OpenGL clip space)."""

    eye: np.ndarray
    target: np.ndarray
    fov_y_deg: float
    height: int
    width: int
    near: float = 0.05
    far: float = 100.0

    @classmethod
    def orbit(cls, azimuth_deg: float, elevation_deg: float, distance: float, fov_y_deg: float,
              height: int, width: int) -> PinholeCamera:
        az, el = np.radians(azimuth_deg), np.radians(elevation_deg)
        eye = distance * np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
        return cls(eye, np.zeros(3), fov_y_deg, height, width)

    def clip(self, points: np.ndarray) -> np.ndarray:
        """``(N, 3)`` world points → ``(N, 4)`` clip coordinates ``(x f / aspect, y f, z_gl, depth)``."""
        back = self.eye - self.target
        back = back / np.linalg.norm(back)
        right = np.cross([0.0, 1.0, 0.0], back)
        right /= np.linalg.norm(right)
        up = np.cross(back, right)
        rel = np.asarray(points, np.float64) - self.eye
        x, y, z = rel @ right, rel @ up, rel @ back
        f = 1.0 / np.tan(np.radians(self.fov_y_deg) / 2)
        n, fa = self.near, self.far
        z_gl = (fa + n) / (n - fa) * z + 2 * fa * n / (n - fa)
        return np.stack([x * f * self.height / self.width, y * f, z_gl, -z], axis=-1)

    @property
    def light_direction(self) -> np.ndarray:
        d = self.eye - self.target
        return d / np.linalg.norm(d)


def pixel_centres(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """NDC ``(x, y)`` of every pixel centre, each ``(H * W,)``, row-major."""
    rows, cols = np.meshgrid(np.arange(height), np.arange(width), indexing="ij")
    x = (2.0 * cols.ravel() + 1.0) / width - 1.0
    y = 1.0 - (2.0 * rows.ravel() + 1.0) / height
    return x, y


def screen_barycentrics(clip: np.ndarray, faces: np.ndarray, x: np.ndarray, y: np.ndarray, near: float):
    """Screen-space barycentrics of points in triangles.

    Args:
        clip: ``(V, 4)``; faces: ``(F, 3)``; x, y: ``(N,)`` NDC points.
    Returns:
        ``lam`` ``(F, N, 3)`` screen barycentrics (NaN where the triangle is not drawable: a vertex
        at ``w <= near`` or zero screen area), ``bary`` ``(F, N, 3)`` perspective-correct ones and
        ``depth`` ``(F, N)`` (interpolated ``w``).
    """
    tri = clip[faces]  # (F, 3, 4)
    w = tri[..., 3]
    drawable = (w > near).all(-1)
    safe_w = np.where(drawable[:, None], w, 1.0)
    sx, sy = tri[..., 0] / safe_w, tri[..., 1] / safe_w  # (F, 3)
    area = (sx[:, 1] - sx[:, 0]) * (sy[:, 2] - sy[:, 0]) - (sx[:, 2] - sx[:, 0]) * (sy[:, 1] - sy[:, 0])
    drawable &= area != 0
    area = np.where(drawable, area, np.nan)
    lam = []
    for k in range(3):
        a, b = (k + 1) % 3, (k + 2) % 3
        e = (sx[:, a, None] - x) * (sy[:, b, None] - y) - (sx[:, b, None] - x) * (sy[:, a, None] - y)
        lam.append(e / area[:, None])
    lam = np.stack(lam, axis=-1)  # (F, N, 3)
    q = lam / safe_w[:, None, :]
    depth = 1.0 / q.sum(-1)
    return lam, q * depth[..., None], depth


@dataclass
class ReferenceImage:
    """What :func:`render_reference` returns for one view: ``face_id`` ``(H, W)`` (-1 background),
    ``depth`` ``(H, W)`` (0 on background), ``rgb`` ``(H, W, 3)`` (background colour composited)."""

    face_id: np.ndarray
    depth: np.ndarray
    rgb: np.ndarray


def vertex_normals(vertices: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Area-weighted unit vertex normals ``(V, 3)``."""
    v = vertices[faces]
    fn = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    n = np.zeros_like(vertices)
    for k in range(3):
        np.add.at(n, faces[:, k], fn)
    length = np.linalg.norm(n, axis=-1, keepdims=True)
    return n / np.maximum(length, 1e-12)


def render_reference(vertices: np.ndarray, faces: np.ndarray, camera: PinholeCamera, albedo: np.ndarray,
                     ambient: float = 0.4, diffuse: float = 0.6, background=(0.0, 0.0, 0.0)) -> ReferenceImage:
    """Rasterize and shade one view by testing every pixel centre against every triangle.

    Args:
        vertices: ``(V, 3)`` world coordinates; faces: ``(F, 3)``; albedo: ``(V, 3)``.
        ambient, diffuse: white light intensities; the light follows the camera.
    """
    h, w = camera.height, camera.width
    clip = camera.clip(vertices)
    x, y = pixel_centres(h, w)
    lam, bary, depth = screen_barycentrics(clip, faces, x, y, camera.near)
    with np.errstate(invalid="ignore"):
        covered = (lam >= 0).all(-1) & (depth > 0)
    z = np.where(covered, depth, np.inf)  # (F, N)
    fid = np.argmin(z, axis=0)  # first minimum: the smallest face id among exact ties
    hit = np.isfinite(z[fid, np.arange(z.shape[1])])
    fid = np.where(hit, fid, -1)
    pix = np.nonzero(hit)[0]
    b = bary[fid[pix], pix]  # (n, 3)
    tri = faces[fid[pix]]
    normals = vertex_normals(np.asarray(vertices, np.float64), faces)
    n = (normals[tri] * b[..., None]).sum(1)
    n /= np.maximum(np.linalg.norm(n, axis=-1, keepdims=True), 1e-12)
    a = (albedo[tri] * b[..., None]).sum(1)
    cos = np.clip(n @ camera.light_direction, 0.0, None)
    rgb = np.tile(np.asarray(background, np.float64), (h * w, 1))
    rgb[pix] = a * (ambient + diffuse * cos[:, None])
    dep = np.zeros(h * w)
    dep[pix] = depth[fid[pix], pix]
    return ReferenceImage(fid.reshape(h, w), dep.reshape(h, w), rgb.reshape(h, w, 3))


def explain_mismatches(clip: np.ndarray, faces: np.ndarray, height: int, width: int, near: float,
                       rows: np.ndarray, cols: np.ndarray, ids_a: np.ndarray, ids_b: np.ndarray) -> np.ndarray:
    """Which face-id disagreements are allowed by float rounding.

    A pixel may legitimately show face ``a`` in one renderer and ``b`` in another when the two tie
    in depth (both cover it at depths equal within :data:`DEPTH_TOL`), or when one of them only
    touches it (its pixel centre lies on an edge within :data:`EDGE_TOL`; ``-1``, the background,
    is allowed against such a face).

    Args:
        clip: ``(V, 4)`` clip coordinates of one view (float64); faces: ``(F, 3)``.
        rows, cols, ids_a, ids_b: ``(N,)`` the disagreeing pixels and the two face ids there.
    Returns:
        ``(N,)`` bool, True where the disagreement is explained.
    """
    x = (2.0 * cols + 1.0) / width - 1.0
    y = 1.0 - (2.0 * rows + 1.0) / height
    ok = np.zeros(len(rows), bool)
    for i in range(len(rows)):
        margin, depth = {}, {}
        for f in (int(ids_a[i]), int(ids_b[i])):
            if f < 0:
                continue
            lam, _, d = screen_barycentrics(clip, faces[f:f + 1], x[i:i + 1], y[i:i + 1], near)
            drawable = not np.isnan(lam).any()
            margin[f] = float(lam.min()) if drawable else -np.inf
            depth[f] = float(d[0, 0]) if drawable else np.inf
        touching = any(abs(m) <= EDGE_TOL for m in margin.values())
        inside = all(m >= -EDGE_TOL for m in margin.values())
        tie = len(depth) == 2 and abs(depth[int(ids_a[i])] - depth[int(ids_b[i])]) <= DEPTH_TOL * max(depth.values())
        ok[i] = inside and (touching or tie)
    return ok
