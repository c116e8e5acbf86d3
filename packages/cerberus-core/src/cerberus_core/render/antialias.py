"""Analytic anti-aliasing of silhouette edges: visibility gradients for the rasterized image.

The barycentric renderer (:mod:`cerberus_core.render.shading`) has no gradient where visibility
changes: a pixel's face id is a step function of the vertices. This op, after the ``antialias``
primitive of nvdiffrast (Laine et al. 2020, "Modular primitives for high-performance differentiable
rendering"), blends the colours of neighbouring pixels across silhouette edges by how far the edge
lies from the pixel centres, which makes the colour a continuous, piecewise-smooth function of the
positions of the edge's two vertices.

For every pair of horizontally or vertically adjacent pixels ``(p, q)`` whose face ids differ:

1. The *front* pixel ``i`` is the covered one; if both are covered, the one whose own face is nearer
   at its own centre (smaller depth ``d = D / s`` of :mod:`cerberus_core.render.interface`, ties to
   ``p``, the left / upper pixel). Its face is ``T``, the other pixel is ``o``.
2. The segment from ``i``'s centre to ``o``'s centre leaves ``T`` through the edge ``(a, b)`` whose
   homogeneous edge function ``e(x) = x . (v_a x v_b)`` (``v = (x, y, w)`` in clip space) changes sign
   first along it; the crossing is at ``t = e(i) / (e(i) - e(o))`` (exact for the projected edge, as
   ``e`` is affine in the pixel position).
3. If that edge is a *silhouette* edge, i.e. no face lies across it (:func:`edge_neighbors`) or the
   face across folds back over ``T`` in screen space (its third vertex lies on ``T``'s side of the
   edge, or on it; independent of the winding), the pair blends across it. Otherwise the segment is
   followed into the face across and step 2 repeats there (at most :data:`MAX_WALK` faces), until it
   crosses a silhouette edge or ends inside a face (then the pair is left alone: e.g. an interior
   edge of one surface). Unlike nvdiffrast, which tests only ``T``'s own edges, this finds the
   silhouette behind the thin, foreshortened faces that line the outline of a coarse closed mesh,
   whose pixel centres are mostly covered by faces one or two rows further in.
4. A crossing is used only by the pairs its edge runs most nearly perpendicular to, in pixels
   (horizontal pairs for ``|l_x| / W >= |l_y| / H`` with ``l = v_a x v_b``, vertical pairs otherwise),
   so a diagonal edge is not blended twice.

(A pair whose two faces share a non-silhouette edge is skipped up front: the walk would end in the
other face. This is most pairs inside a part, and only a shortcut.)
5. If ``t > 1/2`` the edge is inside ``o``'s pixel, which gets ``o += (t - 1/2) (i - o)``; otherwise
   it is inside ``i``'s pixel, which gets ``i += (1/2 - t) (o - i)``. The deltas of all pairs are
   computed from the input colours and summed, so the result does not depend on the order.

The result equals the input away from silhouettes, is continuous when an edge sweeps over a pixel
centre (both sides give the pixel the average of the two colours there), and its gradient reaches
the ``x``, ``y`` and ``w`` clip coordinates of the silhouette edges' vertices (and the colours).

Limits (as nvdiffrast's): one crossing per pixel pair (thin slivers narrower than a pixel are seen
at most once per pair); intersections of interpenetrating surfaces are not edges and get no
gradient; edges crossing the near plane or with a vertex behind the camera are not treated
specially; pixels at the image border are not blended with the outside.
"""
from __future__ import annotations

import torch

from cerberus_core.render.shading import homogeneous_barycentrics, pixel_ndc

Tensor = torch.Tensor

_NEIGHBOR_CACHE: dict[tuple[str, tuple[int, ...]], list[tuple[Tensor, Tensor]]] = {}
_CACHE_PER_KEY = 4


def edge_neighbors(faces: Tensor) -> Tensor:
    """The face across each edge of each face (the mesh topology the op needs), cached per faces.

    Edge ``k`` of face ``f`` joins its vertices ``faces[f, (k + 1) % 3]`` and ``faces[f, (k + 2) % 3]``
    (it is opposite vertex ``k``, like the edge function ``c_k`` of the rasterization rule).

    Args:
        faces: ``(F, 3)`` int vertex indices (not checked here: the op that needs the topology,
            :func:`cerberus_core.render.ops.antialias`, checked them).
    Returns:
        ``(F, 3)`` int64: the other face sharing edge ``k`` of face ``f``, or -1 on a boundary edge.
        On a non-manifold edge (more than two faces) one of the others is picked.

    The result is cached by the faces' content (an equality check per call), so calling it every
    render with freshly packed faces costs one comparison.
    """
    key = (str(faces.device), tuple(faces.shape))
    entries = _NEIGHBOR_CACHE.setdefault(key, [])
    for cached, nbrs in entries:
        if cached.dtype == faces.dtype and torch.equal(cached, faces):
            return nbrs
    nbrs = _compute_edge_neighbors(faces.to(torch.int64))
    entries.insert(0, (faces.detach().clone(), nbrs))
    del entries[_CACHE_PER_KEY:]
    return nbrs


def _compute_edge_neighbors(faces: Tensor) -> Tensor:
    nfaces = faces.shape[0]
    nbrs = torch.full((nfaces, 3), -1, dtype=torch.int64, device=faces.device)
    if nfaces == 0:
        return nbrs
    a = faces[:, [1, 2, 0]].reshape(-1)  # half-edge 3 f + k: vertices (k + 1, k + 2) of face f
    b = faces[:, [2, 0, 1]].reshape(-1)
    nverts = int(faces.max()) + 1
    keys = torch.minimum(a, b) * nverts + torch.maximum(a, b)
    keys, order = torch.sort(keys, stable=True)
    same = torch.nonzero(keys[1:] == keys[:-1]).squeeze(-1)
    first, second = order[same], order[same + 1]
    flat = nbrs.view(-1)
    flat[first] = second // 3
    flat[second] = first // 3
    return nbrs


def _det(v: Tensor) -> Tensor:
    """``v0 . (v1 x v2)`` of ``(N, 3, 3)`` screen vectors: the signed area term ``D`` of the rule."""
    return (v[:, 0] * torch.linalg.cross(v[:, 1], v[:, 2], dim=-1)).sum(-1)


MAX_WALK = 8
"""Most faces a pair's segment is followed through before it is given up (see :func:`antialias`)."""


def _walk_to_silhouette(clip: Tensor, faces: Tensor, nbrs: Tensor, b: Tensor, face: Tensor, p_in: Tensor,
                        p_out: Tensor) -> tuple[Tensor, Tensor]:
    """Follow the segments ``p_in -> p_out`` from ``face`` across non-silhouette edges.

    Args:
        clip: ``(B, V, 4)``; faces, nbrs: ``(F, 3)``; b, face: ``(N,)``; p_in, p_out: ``(N, 3)``.
    Returns:
        ``(face, k)`` each ``(N,)`` int64: the face and local edge index of the silhouette edge each
        segment crosses first, or ``-1`` where it crosses none (it ends inside the surface, or the
        walk takes more than :data:`MAX_WALK` faces).
    """
    count = b.shape[0]
    out_face = torch.full((count,), -1, dtype=torch.int64, device=b.device)
    out_k = torch.full_like(out_face, -1)
    live = torch.arange(count, device=b.device)
    for _ in range(MAX_WALK):
        if live.numel() == 0:
            break
        bl, fl = b[live], face[live]
        tri = faces[fl]
        v = clip[bl.unsqueeze(-1), tri][..., (0, 1, 3)]  # (M, 3, 3)
        det = _det(v)
        lines = torch.stack([torch.linalg.cross(v[:, 1], v[:, 2], dim=-1),
                             torch.linalg.cross(v[:, 2], v[:, 0], dim=-1),
                             torch.linalg.cross(v[:, 0], v[:, 1], dim=-1)], dim=1)  # (M, 3 edges, 3)
        e_in = (lines * p_in[live].unsqueeze(1)).sum(-1)
        e_out = (lines * p_out[live].unsqueeze(1)).sum(-1)
        leaving = torch.sign(det).unsqueeze(-1) * (e_out - e_in) < 0  # the edge function falls along the segment
        t_all = torch.where(leaving, e_in / torch.where(leaving, e_in - e_out, 1.0), float("inf"))
        t_exit, k = t_all.min(-1)
        exits = (t_exit < 1) & (det != 0)  # else the segment ends inside this face
        nb = nbrs[fl, k]
        # silhouette: no face across, or the face across folds back over this one (its third vertex
        # lies on this face's side of the edge, or on the edge), whatever the winding
        line = lines[torch.arange(k.shape[0], device=k.device), k]
        opposite = faces[nb.clamp_min(0)].sum(-1) - tri.gather(1, ((k + 1) % 3).unsqueeze(-1)).squeeze(-1) \
            - tri.gather(1, ((k + 2) % 3).unsqueeze(-1)).squeeze(-1)
        o_side = (clip[bl, opposite][:, (0, 1, 3)] * line).sum(-1)
        silhouette = (nb < 0) | (o_side * det >= 0)
        hit = exits & silhouette
        out_face[live[hit]] = fl[hit]
        out_k[live[hit]] = k[hit]
        go = exits & ~silhouette
        face = face.clone()
        face[live[go]] = nb[go]
        live = live[go]
    return out_face, out_k


def differing_pairs(face_id: Tensor) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """Adjacent pixel pairs with different face ids.

    Args:
        face_id: ``(B, H, W)`` int64.
    Returns:
        ``(b, n0, n1, horizontal)`` each ``(N,)``: scene and flat pixel indices ``(b H + row) W + col``
        (int64) of the left/upper and the right/lower pixel of each pair, and whether the pair is a
        horizontal one (bool; horizontal pairs come first).
    """
    bsz, height, width = face_id.shape
    bh, rh, ch = torch.nonzero(face_id[:, :, :-1] != face_id[:, :, 1:], as_tuple=True)
    bv, rv, cv = torch.nonzero(face_id[:, :-1, :] != face_id[:, 1:, :], as_tuple=True)
    nh = (bh * height + rh) * width + ch
    nv = (bv * height + rv) * width + cv
    horizontal = torch.arange(nh.shape[0] + nv.shape[0], device=face_id.device) < nh.shape[0]
    return torch.cat([bh, bv]), torch.cat([nh, nv]), torch.cat([nh + 1, nv + width]), horizontal


def antialias(color: Tensor, clip: Tensor, faces: Tensor, face_id: Tensor) -> Tensor:
    """Analytic silhouette anti-aliasing (the torch reference; see this module's docstring).

    Args:
        color: ``(B, H, W, C)`` channels-last colours to blend (any ``C``: RGB, alpha, or both
            concatenated), float32 or float64.
        clip: ``(B, V, 4)`` clip-space vertices the image was rasterized from (gradients flow to
            their ``x``, ``y`` and ``w`` columns).
        faces: ``(F, 3)`` int vertex indices.
        face_id: ``(B, H, W)`` int64 visible face per pixel from :meth:`Renderer.rasterize`, -1 on
            background.
    Returns:
        ``(B, H, W, C)`` the blended colours, differentiable w.r.t. ``color`` and ``clip``.

    The inputs are not checked here: :func:`cerberus_core.render.ops.antialias`, the one way to a
    backend's op, checks them once.
    """
    bsz, height, width, nch = color.shape
    faces = faces.to(torch.int64)
    fid = face_id.reshape(-1)
    b, n0, n1, horizontal = differing_pairs(face_id)
    if b.numel() == 0:
        return color + 0.0 * color  # a new tensor either way (as when pairs exist)

    def ndc(n: Tensor) -> Tensor:
        rc = n % (height * width)
        return pixel_ndc(height, width, rc // width, rc % width, clip.dtype)

    nbrs = edge_neighbors(faces)
    with torch.no_grad():
        f0, f1 = fid[n0], fid[n1]
        # fast path: the two faces share an edge that is not a silhouette (an interior edge of one
        # surface, most pairs inside parts); the walk would end in the other face anyway
        shared = (nbrs[f0.clamp_min(0)] == f1.unsqueeze(-1)) & ((f0 >= 0) & (f1 >= 0)).unsqueeze(-1)
        adjacent = torch.nonzero(shared.any(-1)).squeeze(-1)
        ka = shared[adjacent].to(torch.int8).argmax(-1)
        tri_a = faces[f0[adjacent]]
        ia = tri_a.gather(1, ((ka + 1) % 3).unsqueeze(-1)).squeeze(-1)
        ib = tri_a.gather(1, ((ka + 2) % 3).unsqueeze(-1)).squeeze(-1)
        ba = b[adjacent]
        line = torch.linalg.cross(clip[ba, ia][:, (0, 1, 3)], clip[ba, ib][:, (0, 1, 3)], dim=-1)
        opposite = faces[f1[adjacent]].sum(-1) - ia - ib
        folds = (clip[ba, opposite][:, (0, 1, 3)] * line).sum(-1) * _det(clip[ba.unsqueeze(-1), tri_a][..., (0, 1, 3)])
        interior = torch.zeros_like(f0, dtype=torch.bool)
        interior[adjacent] = folds < 0
        rest = torch.nonzero(~interior).squeeze(-1)
        b, n0, n1, horizontal, f0, f1 = (x[rest] for x in (b, n0, n1, horizontal, f0, f1))
        p0, p1 = ndc(n0), ndc(n1)
        inf = torch.full_like(p0[:, 0], float("inf"))
        d0 = torch.where(f0 >= 0, homogeneous_barycentrics(p0, clip[b.unsqueeze(-1), faces[f0.clamp_min(0)]])[1], inf)
        d1 = torch.where(f1 >= 0, homogeneous_barycentrics(p1, clip[b.unsqueeze(-1), faces[f1.clamp_min(0)]])[1], inf)
        first = d0 <= d1
        n_in, n_out = torch.where(first, n0, n1), torch.where(first, n1, n0)
        p_in, p_out = torch.where(first.unsqueeze(-1), p0, p1), torch.where(first.unsqueeze(-1), p1, p0)
        face, k = _walk_to_silhouette(clip, faces, nbrs, b, torch.where(first, f0, f1), p_in, p_out)
        found = torch.nonzero(face >= 0).squeeze(-1)
        b, face, k, n_in, n_out, p_in, p_out, horizontal = (
            x[found] for x in (b, face, k, n_in, n_out, p_in, p_out, horizontal))
        ia = faces[face, (k + 1) % 3]
        ib = faces[face, (k + 2) % 3]
        line = torch.linalg.cross(clip[b, ia][:, (0, 1, 3)], clip[b, ib][:, (0, 1, 3)], dim=-1)
        # each edge is counted across the pixel pairs it runs most nearly perpendicular to (in pixels)
        across_x, across_y = line[:, 0].abs() / width, line[:, 1].abs() / height
        keep = torch.nonzero(torch.where(horizontal, across_x >= across_y, across_y > across_x)).squeeze(-1)
        b, ia, ib, n_in, n_out, p_in, p_out = (x[keep] for x in (b, ia, ib, n_in, n_out, p_in, p_out))
    va = clip[b, ia][:, (0, 1, 3)]
    vb = clip[b, ib][:, (0, 1, 3)]
    line = torch.linalg.cross(va, vb, dim=-1)
    e_in = (line * p_in).sum(-1)
    e_out = (line * p_out).sum(-1)
    t = e_in / (e_in - e_out)
    beyond = t > 0.5
    n_mod = torch.where(beyond, n_out, n_in)
    n_src = torch.where(beyond, n_in, n_out)
    weight = torch.where(beyond, t - 0.5, 0.5 - t).unsqueeze(-1)
    flat = color.reshape(-1, nch)
    delta = weight * (flat[n_src] - flat[n_mod])
    return flat.index_add(0, n_mod, delta.to(color.dtype)).view(bsz, height, width, nch)
