"""Vectorised voxelization of triangle meshes on a lattice, and grid-level IoU.

Lattice convention: voxel ``(i, j, k)`` spans ``[i, i+1) x [j, j+1) x [k, k+1)`` in
lattice coordinates (see :class:`cerberus_metrics.protocols.Frame`); its centre is at
``(i, j, k) + 0.5``. Arrays of triangles are ``(F, 3, 3)`` float64 lattice coordinates
(face, corner, axis). Occupancy arrays are boolean, indexed ``[x, y, z]``.

Two rules:

``surface`` (Kato et al.)
    For each axis, rays parallel to it run along the *integer* lattice lines of the other
    two axes. A ray that hits a triangle (closed barycentric test; triangles whose
    projection is degenerate are skipped) at height ``h`` marks the four voxels that share
    that line at height index ``floor(h)``. Voxels holding a triangle corner are marked too.
    The empty voxels 6-connected to the grid border are the exterior; the solid is its
    complement (:func:`fill_exterior`).
``center``
    A voxel is solid when its centre is inside the surface by the non-zero winding rule.
    Winding numbers are counted with signed ray crossings along each axis at voxel
    centres (watertight edge functions with a top-left tie rule, so a ray through a
    shared edge or vertex counts once); a voxel is solid when at least two of the three
    axes say so (all three agree on closed meshes).
"""

from __future__ import annotations

import warnings
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from .io import Mesh, MeshInputError, MeshQualityWarning
from .protocols import MAX_GRID_VOXELS, Frame, Protocol, lattice_box

__all__ = [
    "VoxelGrid",
    "PartGrids",
    "voxelize_parts",
    "kato_surface",
    "kato_surface_parts",
    "fill_exterior",
    "center_occupancy",
    "grid_iou",
    "OUTSIDE",
]

OUTSIDE = ("error", "clamp")
"""What a fixed-frame protocol (``kato``) does with a part that reaches outside its grid ``[0, R)^3``:
``"error"`` raises :class:`MeshInputError` naming the part; ``"clamp"`` applies one rule in every
direction (faces, edges and corners alike): the part is voxelized whole, then its voxels outside the
grid are dropped, and the grid counts it in :attr:`VoxelGrid.clamped`."""

# Ray axis -> the (u, w) axes of its lattice lines, in the order the reference kernel uses
# ("y", "x"); this only matters for floating-point rounding of the barycentric test.
_RAY_AXES = {0: (2, 1), 1: (0, 2), 2: (0, 1)}
_MAX_CANDIDATES = 1 << 22  # (triangle, line) pairs per vectorised chunk
_MAX_BATCH_VOXELS = 1 << 25  # padded voxels up to which parts are flood-filled as one batch


@dataclass(frozen=True, eq=False)
class VoxelGrid:
    """Solid occupancy on a protocol's lattice.

    occupancy: (nx, ny, nz) bool. origin: lattice index of ``occupancy[0, 0, 0]``.
    frame: the mesh-to-lattice map (its ``pitch`` is the voxel edge in mesh units).
    protocol: protocol name. For the ``kato`` protocol origin is (0, 0, 0) and the
    shape is (R, R, R); other frames may extend past ``[0, R)^3`` to hold a prediction.
    clamped: number of parts (meshes) that reached outside a fixed frame's grid and were clamped
    to it (``outside="clamp"``, see :data:`OUTSIDE`); 0 otherwise.
    """

    occupancy: np.ndarray
    origin: tuple[int, int, int]
    frame: Frame
    protocol: str
    clamped: int = 0

    @property
    def count(self) -> int:
        """Number of solid voxels."""
        return int(np.count_nonzero(self.occupancy))

    @property
    def volume(self) -> float:
        """Solid volume in mesh units cubed (count * pitch**3)."""
        return self.count * self.frame.pitch**3

    def dense(self) -> np.ndarray:
        """(R, R, R) bool occupancy of the evaluation grid ``[0, R)^3`` (clips any extension)."""
        r = self.frame.resolution
        out = np.zeros((r, r, r), bool)
        _paste(out, (0, 0, 0), self.occupancy, self.origin, np.logical_or)
        return out

    def centers(self) -> np.ndarray:
        """(N, 3) mesh coordinates of the solid voxels' centres."""
        idx = np.argwhere(self.occupancy) + np.asarray(self.origin) + 0.5
        return self.frame.to_mesh(idx)


@dataclass(frozen=True, eq=False)
class PartGrids:
    """Solid occupancy of each part of a multi-part shape, on one lattice box.

    occupancy: (P, nx, ny, nz) bool, part ``p``'s voxels in ``occupancy[p]``. origin, frame,
    protocol, clamped: as :class:`VoxelGrid`. :meth:`union` is the grid of the whole shape
    (the parts voxelized alone, then OR-ed), so per-part figures (a part's own voxels,
    the IoU without one part) are scored exactly like the union.
    """

    occupancy: np.ndarray
    origin: tuple[int, int, int]
    frame: Frame
    protocol: str
    clamped: int = 0

    def union(self) -> VoxelGrid:
        """The union of the parts as one :class:`VoxelGrid`."""
        return VoxelGrid(self.occupancy.any(axis=0), self.origin, self.frame, self.protocol, self.clamped)


# --------------------------------------------------------------------------- helpers


def _paste(dst: np.ndarray, dst_origin: Sequence[int], src: np.ndarray, src_origin: Sequence[int], op) -> None:
    """dst[overlap] = op(dst[overlap], src[overlap]) for two boxes placed at lattice origins."""
    d0, s0 = np.asarray(dst_origin), np.asarray(src_origin)
    lo = np.maximum(d0, s0)
    hi = np.minimum(d0 + dst.shape, s0 + src.shape)
    if (hi <= lo).any():
        return
    ds = tuple(slice(a, b) for a, b in zip(lo - d0, hi - d0, strict=True))
    ss = tuple(slice(a, b) for a, b in zip(lo - s0, hi - s0, strict=True))
    dst[ds] = op(dst[ds], src[ss])


def _overlap_count(a: np.ndarray, ao: Sequence[int], b: np.ndarray, bo: Sequence[int]) -> int:
    a0, b0 = np.asarray(ao), np.asarray(bo)
    lo = np.maximum(a0, b0)
    hi = np.minimum(a0 + a.shape, b0 + b.shape)
    if (hi <= lo).any():
        return 0
    sa = tuple(slice(x, y) for x, y in zip(lo - a0, hi - a0, strict=True))
    sb = tuple(slice(x, y) for x, y in zip(lo - b0, hi - b0, strict=True))
    return int(np.count_nonzero(a[sa] & b[sb]))


def _min3(x: np.ndarray) -> np.ndarray:
    """Row minimum of an (F, 3) array (column-wise; much faster than min(axis=1))."""
    return np.minimum(np.minimum(x[:, 0], x[:, 1]), x[:, 2])


def _max3(x: np.ndarray) -> np.ndarray:
    return np.maximum(np.maximum(x[:, 0], x[:, 1]), x[:, 2])


def _bounds(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-axis (min, max) of (N, 3) points, column by column (min(axis=0) is slow for 3 columns)."""
    return (
        np.array([points[:, i].min() for i in range(3)]),
        np.array([points[:, i].max() for i in range(3)]),
    )


def _line_candidates(
    u: np.ndarray, w: np.ndarray, u_range: tuple, w_range: tuple, offset: float
) -> Iterator[tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Lattice lines ``(ku + offset, kw + offset)`` inside each triangle's projected bounding box.

    u, w: (F, 3) projected corner coordinates. u_range/w_range: inclusive (first, last)
    indices of the lines that exist, scalars or (F,) arrays. Yields chunks of
    (triangle index, ku, kw), each (N,) int64.
    """
    ku0 = np.maximum(np.ceil(_min3(u) - offset), u_range[0]).astype(np.int64)
    ku1 = np.minimum(np.floor(_max3(u) - offset), u_range[1]).astype(np.int64)
    kw0 = np.maximum(np.ceil(_min3(w) - offset), w_range[0]).astype(np.int64)
    kw1 = np.minimum(np.floor(_max3(w) - offset), w_range[1]).astype(np.int64)
    nu = np.clip(ku1 - ku0 + 1, 0, None)
    nw = np.clip(kw1 - kw0 + 1, 0, None)
    count = nu * nw
    tris = np.flatnonzero(count)
    if tris.size == 0:
        return
    cum = np.cumsum(count[tris])
    start = 0
    while start < tris.size:
        base = cum[start - 1] if start else 0
        stop = max(int(np.searchsorted(cum, base + _MAX_CANDIDATES, side="right")), start + 1)
        sel = tris[start:stop]
        cnt = count[sel]
        tri_idx = np.repeat(sel, cnt)
        local = np.arange(tri_idx.size) - np.repeat(np.cumsum(cnt) - cnt, cnt)
        nw_r = nw[tri_idx]
        yield tri_idx, ku0[tri_idx] + local // nw_r, kw0[tri_idx] + local % nw_r
        start = stop


class _Boxes:
    """Per-part lattice boxes ``[lo, lo + shape)`` stored back to back in one flat bool buffer."""

    def __init__(self, lo: np.ndarray, shape: np.ndarray) -> None:
        self.lo = np.asarray(lo, np.int64).reshape(-1, 3)
        self.shape = np.asarray(shape, np.int64).reshape(-1, 3)
        sizes = self.shape.prod(axis=1)
        self.offset = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        self.flat = np.zeros(int(sizes.sum()), bool)

    def mark(self, part: np.ndarray, coords: np.ndarray) -> None:
        """Set the voxels at (N, 3) lattice coords of parts ``part`` (N,), dropping those outside."""
        if len(self.lo) == 1:  # one box: scalars instead of per-voxel gathers
            lo, shp, offset = self.lo[0], self.shape[0], 0
        else:
            lo, shp, offset = self.lo[part].T, self.shape[part].T, self.offset[part]
        r0, r1, r2 = coords[:, 0] - lo[0], coords[:, 1] - lo[1], coords[:, 2] - lo[2]
        s0, s1, s2 = shp[0], shp[1], shp[2]
        keep = (r0 >= 0) & (r0 < s0) & (r1 >= 0) & (r1 < s1) & (r2 >= 0) & (r2 < s2)
        flat = offset + (r0 * s1 + r1) * s2 + r2
        self.flat[flat[keep]] = True

    def arrays(self) -> list[np.ndarray]:
        out = []
        for o, s in zip(self.offset, self.shape, strict=True):
            out.append(self.flat[o : o + int(np.prod(s))].reshape(tuple(int(x) for x in s)))
        return out


def kato_surface_parts(tris: Sequence[np.ndarray], lo: np.ndarray, shape: np.ndarray) -> list[np.ndarray]:
    """:func:`kato_surface` of several parts in one vectorised pass.

    tris: P arrays (F_i, 3, 3) in lattice coordinates. lo, shape: (P, 3) int boxes.
    Returns P bool arrays of the boxes' shapes.
    """
    tri = np.concatenate(tris)
    part = np.repeat(np.arange(len(tris)), [t.shape[0] for t in tris])
    boxes = _Boxes(lo, shape)
    first, last = boxes.lo[part], boxes.lo[part] + boxes.shape[part] - 1
    for axis, (ua, wa) in _RAY_AXES.items():
        for t_idx, ku, kw in _line_candidates(
            tri[:, :, ua], tri[:, :, wa], (first[:, ua], last[:, ua]), (first[:, wa], last[:, wa]), 0.0
        ):
            t = tri[t_idx]
            y0, x0, z0 = t[:, 0, ua], t[:, 0, wa], t[:, 0, axis]
            y1d, x1d, z1d = t[:, 1, ua] - y0, t[:, 1, wa] - x0, t[:, 1, axis] - z0
            y2d, x2d, z2d = t[:, 2, ua] - y0, t[:, 2, wa] - x0, t[:, 2, axis] - z0
            ypd, xpd = ku - y0, kw - x0
            det = x1d * y2d - x2d * y1d
            ok = det != 0
            det = np.where(ok, det, 1.0)
            t1 = (y2d * xpd - x2d * ypd) / det
            t2 = (-y1d * xpd + x1d * ypd) / det
            ok &= (t1 >= 0) & (t2 >= 0) & (t1 + t2 <= 1)
            height = np.floor(t1[ok] * z1d[ok] + t2[ok] * z2d[ok] + z0[ok]).astype(np.int64)
            ku, kw, hit_part = ku[ok], kw[ok], part[t_idx[ok]]
            n = ku.size
            coords = np.empty((4 * n, 3), np.int64)
            coords[:, axis] = np.tile(height, 4)
            coords[:, ua] = np.concatenate([ku, ku - 1, ku, ku - 1])
            coords[:, wa] = np.concatenate([kw, kw, kw - 1, kw - 1])
            boxes.mark(np.tile(hit_part, 4), coords)
    boxes.mark(np.repeat(part, 3), np.floor(tri.reshape(-1, 3)).astype(np.int64))
    return boxes.arrays()


def kato_surface(tri: np.ndarray, lo: np.ndarray, shape: Sequence[int]) -> np.ndarray:
    """Surface voxels of Kato et al.'s rule inside the lattice box ``[lo, lo + shape)``.

    tri: (F, 3, 3) lattice coordinates. Returns ``shape`` bool: voxels marked by an
    axis-aligned ray hit (four voxels around the integer line, height ``floor(h)``) or
    holding a triangle corner (``floor`` of its coordinates). Marks outside the box are
    dropped, as the reference's range checks do.
    """
    return kato_surface_parts([tri], np.asarray(lo)[None], np.asarray(shape)[None])[0]


def _spread_runs(visible: np.ndarray, empty: np.ndarray, axis: int) -> np.ndarray:
    """Make visible every empty voxel whose run of empty voxels along ``axis`` holds a visible one."""
    e = np.moveaxis(empty, axis, -1)
    v = np.moveaxis(visible, axis, -1)
    n = e.shape[-1]
    e2 = e.reshape(-1, n)
    start = e2.copy()
    start[:, 1:] &= ~e2[:, :-1]
    run = np.cumsum(start.ravel())  # run id, valid where empty; each line's first run starts there
    lit = np.zeros(int(run[-1]) + 1, bool)
    lit[run[v.reshape(-1)]] = True
    out = (e2.ravel() & lit[run]).reshape(e.shape)
    return np.moveaxis(out, -1, axis)


def fill_exterior(surface: np.ndarray) -> np.ndarray:
    """Solid = complement of the empty voxels 6-connected to the box border.

    surface: (..., nx, ny, nz) bool; leading axes are independent grids (a batch).
    Same result as Kato's iterative flood fill (seeds: empty border voxels; growth:
    6-neighbours), computed by sweeping whole runs of empty voxels along each axis
    until a full round changes nothing.
    """
    empty = ~surface
    border = np.zeros_like(surface)
    border[..., [0, -1], :, :] = True
    border[..., :, [0, -1], :] = True
    border[..., :, :, [0, -1]] = True
    visible = empty & border
    count, unchanged = int(visible.sum()), 0
    while True:
        for axis in (-3, -2, -1):
            visible = _spread_runs(visible, empty, axis)
            new = int(visible.sum())
            unchanged = unchanged + 1 if new == count else 1
            count = new
            if unchanged >= 3:
                return ~visible


def _fill_parts(surfaces: list[np.ndarray]) -> list[np.ndarray]:
    """fill_exterior of each grid, batched: grids are padded with empty voxels to one shape.

    Padding at the high ends is empty and touches the padded border, so it only re-seeds
    the voxels that were border voxels already: the result equals per-grid filling.
    """
    if len(surfaces) == 1:
        return [fill_exterior(surfaces[0])]
    big = np.max([s.shape for s in surfaces], axis=0)
    if len(surfaces) * float(np.prod(big)) > _MAX_BATCH_VOXELS:  # e.g. one clamped part far larger than the rest
        return [fill_exterior(s) for s in surfaces]
    stack = np.zeros((len(surfaces), *big), bool)
    for i, s in enumerate(surfaces):
        stack[i, : s.shape[0], : s.shape[1], : s.shape[2]] = s
    solid = fill_exterior(stack)
    return [solid[i, : s.shape[0], : s.shape[1], : s.shape[2]] for i, s in enumerate(surfaces)]


# --------------------------------------------------------------------------- centre rule


def _edge(au, aw, bu, bw, pu, pw):
    """Edge function of segment a->b at p; exactly antisymmetric in (a, b) in floating point."""
    return (au - pu) * (bw - pw) - (aw - pw) * (bu - pu)


def center_occupancy(tri: np.ndarray, lo: np.ndarray, shape: Sequence[int]) -> np.ndarray:
    """Voxels of ``[lo, lo + shape)`` whose centre has a non-zero winding number.

    tri: (F, 3, 3) lattice coordinates of an (ideally closed) surface; orientation may be
    either (only the winding's non-zero-ness is used), overlapping closed parts give their
    union. Returns ``shape`` bool, solid where >= 2 of the 3 axis-parallel ray counts agree.
    """
    lo = np.asarray(lo, np.int64)
    shape = tuple(int(s) for s in shape)
    votes = np.zeros(shape, np.int8)
    for axis, (ua, wa) in _RAY_AXES.items():
        acc_shape = list(shape)
        acc_shape[axis] += 1
        acc = np.zeros(int(np.prod(acc_shape)), np.float64)
        u_rng = (int(lo[ua]), int(lo[ua] + shape[ua] - 1))
        w_rng = (int(lo[wa]), int(lo[wa] + shape[wa] - 1))
        for t_idx, ku, kw in _line_candidates(tri[:, :, ua], tri[:, :, wa], u_rng, w_rng, 0.5):
            t = tri[t_idx]
            U, W, A = t[:, :, ua], t[:, :, wa], t[:, :, axis]
            pu, pw = ku + 0.5, kw + 0.5
            det = (U[:, 1] - U[:, 0]) * (W[:, 2] - W[:, 0]) - (U[:, 2] - U[:, 0]) * (W[:, 1] - W[:, 0])
            s = np.sign(det)
            inside = s != 0
            es = []
            for a, b in ((1, 2), (2, 0), (0, 1)):
                e = _edge(U[:, a], W[:, a], U[:, b], W[:, b], pu, pw)
                es.append(e)
                e = e * s
                du, dw = s * (U[:, b] - U[:, a]), s * (W[:, b] - W[:, a])
                top_left = (dw > 0) | ((dw == 0) & (du < 0))
                inside &= (e > 0) | ((e == 0) & top_left)
            total = es[0] + es[1] + es[2]
            inside &= total != 0
            e0, e1, e2, total = es[0][inside], es[1][inside], es[2][inside], total[inside]
            a = A[inside]
            height = (e0 * a[:, 0] + e1 * a[:, 1] + e2 * a[:, 2]) / total
            first = np.clip(np.floor(height - 0.5).astype(np.int64) + 1 - lo[axis], 0, shape[axis])
            coords = np.empty((first.size, 3), np.int64)
            coords[:, axis] = first
            coords[:, ua] = ku[inside] - lo[ua]
            coords[:, wa] = kw[inside] - lo[wa]
            flat = np.ravel_multi_index(coords.T, acc_shape)
            acc += np.bincount(flat, weights=s[inside], minlength=acc.size)
        wind = np.cumsum(acc.reshape(acc_shape), axis=axis)
        wind = np.take(wind, np.arange(shape[axis]), axis=axis)
        votes += np.abs(wind) > 0.5
    return votes >= 2


# --------------------------------------------------------------------------- meshes -> grid


def _warn_quality(mesh: Mesh, rule: str, open_mesh_option: str = "open_mesh") -> None:
    """Warn about ``mesh``'s quality defects (its report) and how ``rule`` (``"surface"`` | ``"center"``) treats
    them. open_mesh_option: the name of the option that set the mesh's open-mesh policy, so that the messages name
    the option the caller set (``"open_mesh"``; ``"gt_open_mesh"`` for a ground truth with its own policy)."""
    rep = mesh.report
    if rep is None:
        return
    opt = open_mesh_option
    if rep.holes_closed:
        warnings.warn(
            f"{mesh.name}: closed holes with pymeshlab ({opt}='close'), adding {rep.holes_closed} faces",
            MeshQualityWarning,
            stacklevel=4,
        )
    if not rep.watertight:
        treat = (
            "surface rule: voxels touched by the surface are exact, but the exterior flood fill enters "
            "through holes wider than about one voxel, so an open region counts only its surface voxels"
            if rule == "surface"
            else "centre rule: solid where >= 2 of 3 axis ray counts give a non-zero winding number; near "
            "holes the axes disagree and the result there is approximate"
        )
        warnings.warn(
            f"{mesh.name}: mesh is not watertight ({', '.join(rep.problems())}). Treatment: {treat}. "
            f"Use {opt}='close' to fill holes with pymeshlab, or {opt}='error' to reject such meshes.",
            MeshQualityWarning,
            stacklevel=4,
        )
    elif rep.self_intersecting:
        treat = (
            "the solid is every voxel enclosed by the surface (union of the overlapping regions)"
            if rule == "surface"
            else "non-zero winding rule, so overlapping regions count once (their union)"
        )
        warnings.warn(
            f"{mesh.name}: mesh is self-intersecting ({rep.self_intersecting_faces} faces). Treatment: {treat}.",
            MeshQualityWarning,
            stacklevel=4,
        )


def _check_leak(mesh: Mesh, frame: Frame, solid_voxels: int) -> None:
    """Warn when a closed mesh's filled voxels hold less than its enclosed volume (fill leaked)."""
    rep = mesh.report
    if rep is None or not rep.watertight or rep.self_intersecting:
        return
    enclosed = abs(rep.volume) * frame.scale**3  # in voxels
    if enclosed > 8 and solid_voxels < 0.9 * enclosed:
        warnings.warn(
            f"{mesh.name}: the exterior flood fill leaked into the closed mesh ({solid_voxels} solid voxels "
            f"for an enclosed volume of {enclosed:.0f} voxels): the surface has gaps between voxels at this "
            "resolution; the IoU counts only the voxels reached. Try a higher resolution.",
            MeshQualityWarning,
            stacklevel=4,
        )


def _clamp_boxes(bounds: np.ndarray, frame: Frame, names: Sequence[str]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-part lattice boxes for ``outside="clamp"`` on a fixed frame.

    bounds: (P, 2, 3) per-part (min, max) lattice coordinates. Returns ``(keep, s_lo, s_hi)``:
    keep (P,) bool, the parts that can mark a voxel of the grid ``[0, R)^3`` (a part wholly
    outside marks none, so it is not voxelized at all); s_lo, s_hi (P, 3) int64, each part's
    whole box (bounding voxels plus one empty voxel of margin), not cut by the grid, so the
    flood fill sees the part's closed surface before the grid crops it.
    """
    r = frame.resolution
    # The surface rule marks voxel R-1 for a surface at lattice coordinate R (the ray on line R marks
    # voxels R-1 and R), so a part starting exactly at R can still reach the grid; one past it cannot.
    keep = ~((bounds[:, 1] < 0).any(axis=1) | (bounds[:, 0] > r).any(axis=1))
    lo = np.floor(bounds[:, 0]) - 1
    hi = np.floor(bounds[:, 1]) + 2
    sizes = np.prod(hi - lo, axis=1)
    too_big = keep & ~(sizes <= MAX_GRID_VOXELS)  # also catches non-finite sizes
    if too_big.any():
        k = int(np.flatnonzero(too_big)[0])
        reach = float(np.abs(bounds[k] - r / 2).max()) / (r - 1)
        raise MeshInputError(
            f"{names[k]}: mesh reaches {reach:.3g} cube sizes from the centre of the [-0.5, 0.5]^3 cube, so "
            f"clamping it to the grid would voxelize {sizes[k]:.3g} voxels (limit {MAX_GRID_VOXELS:.3g}); "
            "such a mesh is not in the protocol's units: normalise it to [-0.5, 0.5]^3 or use protocol='gt_bbox'"
        )
    lo = np.where(keep[:, None], lo, 0).astype(np.int64)
    hi = np.where(keep[:, None], hi, 1).astype(np.int64)
    return keep, lo, hi


def voxelize_parts(parts: Sequence[Mesh], protocol: Protocol, frame: Frame, fill: bool = True,
                   outside: str = "error", ground_truth: bool = False, *,
                   open_mesh_option: str = "open_mesh") -> PartGrids:
    """Voxelize each of several cleaned parts alone, on one lattice box.

    parts: cleaned meshes in mesh coordinates. frame: from :func:`make_frame`.
    fill: False returns the ``surface`` rule's surface voxels without the flood fill.
    outside: ``"error"`` | ``"clamp"``, what a fixed frame (``kato``) does with a part reaching
    outside its grid ``[0, R)^3`` (see :data:`OUTSIDE`; other frames grow the grid instead).
    ground_truth: the parts are a ground truth (only the fix the outside-the-grid error names changes,
    see :func:`~cerberus_metrics.protocols.lattice_box`).
    open_mesh_option: the name of the option that set the parts' open-mesh policy (``open_mesh`` of
    :func:`~cerberus_metrics.io.load_parts`), which the warnings name as the fix.
    Issues :class:`MeshQualityWarning` for open/self-intersecting parts (see docs).
    """
    if not fill and protocol.rule != "surface":
        raise MeshInputError(f"fill=False applies to the surface rule only, not protocol {protocol.name!r}")
    if outside not in OUTSIDE:
        raise MeshInputError(f"outside={outside!r} is not a choice; use one of {list(OUTSIDE)}")
    names = [p.name for p in parts]
    tris = [frame.to_lattice(p.triangles) for p in parts]
    bounds = np.array([_bounds(t.reshape(-1, 3)) for t in tris])  # (P, 2, 3)
    r = frame.resolution
    clamped = 0
    if outside == "clamp" and frame.fixed:
        clamped = int(((bounds[:, 0] < 0).any(axis=1) | (bounds[:, 1] > r).any(axis=1)).sum())
    if clamped:
        lo, hi = np.zeros(3, np.int64), np.full(3, r, np.int64)
        keep, s_lo, s_hi = _clamp_boxes(bounds, frame, names)
    else:
        lo, hi = lattice_box(frame, bounds, names, ground_truth)
        keep = np.ones(len(parts), bool)
        # Each part gets its own box: its bounding voxels plus one empty voxel of margin, within [lo, hi).
        s_lo = np.maximum(np.floor(bounds[:, 0]).astype(np.int64) - 1, lo)
        s_hi = np.minimum(np.floor(bounds[:, 1]).astype(np.int64) + 2, hi)
    for mesh, b in zip(parts, bounds, strict=True):
        _warn_quality(mesh, protocol.rule, open_mesh_option)
        span = float((b[1] - b[0]).max())
        if span < 1.0:
            warnings.warn(
                f"{mesh.name}: mesh spans only {span:.3g} voxels (grid {frame.resolution}^3, protocol "
                f"{protocol.name!r}), so its voxels are set by rounding alone and the IoU says little about its "
                "shape: check that its scale matches the ground truth's (units), or raise the resolution",
                MeshQualityWarning,
                stacklevel=3,
            )
    idx = np.flatnonzero(keep)
    kept = [parts[i] for i in idx]
    k_tris, k_lo, k_hi = [tris[i] for i in idx], s_lo[idx], s_hi[idx]
    subs: list[np.ndarray] = []
    if not kept:
        pass  # every part lies wholly outside the fixed grid: it contributes no voxel
    elif protocol.rule == "surface":
        subs = kato_surface_parts(k_tris, k_lo, k_hi - k_lo)
        if fill:
            subs = _fill_parts(subs)
            for mesh, sub in zip(kept, subs, strict=True):
                _check_leak(mesh, frame, int(np.count_nonzero(sub)))
    else:
        subs = [center_occupancy(t, a, b - a) for t, a, b in zip(k_tris, k_lo, k_hi, strict=True)]
    occ = np.zeros((len(parts), *(hi - lo)), bool)
    for i, sub, a in zip(idx, subs, k_lo, strict=True):
        _paste(occ[i], lo, sub, a, np.logical_or)  # pastes only the overlap: this crops clamped parts to the grid
    return PartGrids(occ, tuple(int(x) for x in lo), frame, protocol.name, clamped)


# --------------------------------------------------------------------------- IoU


def grid_iou(pred: VoxelGrid | np.ndarray, gt: VoxelGrid | np.ndarray) -> float:
    """Intersection over union of two occupancy grids: |P & G| / |P | G|.

    Either two bool arrays of the same shape (0/1 integer arrays too; a float grid is refused: which
    values are occupied is the caller's threshold to choose), or two :class:`VoxelGrid` from the same
    frame (grids with different extents are aligned by their origins). Raises when both are empty.
    """
    if isinstance(pred, VoxelGrid) != isinstance(gt, VoxelGrid):
        raise MeshInputError("grid_iou: pass two VoxelGrid or two bool arrays, not one of each")
    if isinstance(pred, VoxelGrid):
        if pred.frame != gt.frame or pred.protocol != gt.protocol:
            raise MeshInputError(
                "grid_iou: the grids come from different frames or protocols; voxelize the prediction with "
                "frame=gt_grid.frame and the same protocol"
            )
        a, ao, b, bo = pred.occupancy, pred.origin, gt.occupancy, gt.origin
    else:
        for name, grid in (("pred", pred), ("gt", gt)):
            arr = np.asarray(grid)
            if arr.dtype != bool and not (np.issubdtype(arr.dtype, np.integer) and np.isin(arr, (0, 1)).all()):
                raise MeshInputError(
                    f"grid_iou: {name} is a {arr.dtype} grid, not occupancy; pass a bool array (e.g. probs >= 0.5) "
                    "so that no threshold is guessed"
                )
        a, b = np.asarray(pred, bool), np.asarray(gt, bool)
        if a.shape != b.shape:
            raise MeshInputError(f"grid_iou: grid shapes differ, {a.shape} vs {b.shape}; voxelize both alike")
        ao = bo = (0,) * a.ndim
    inter = _overlap_count(a, ao, b, bo)
    union = int(np.count_nonzero(a)) + int(np.count_nonzero(b)) - inter
    if union == 0:
        raise MeshInputError(
            "grid_iou: both grids are empty, so IoU is undefined; the shapes are smaller than one voxel's "
            "centre spacing: use a higher resolution or the surface rule"
        )
    return inter / union
