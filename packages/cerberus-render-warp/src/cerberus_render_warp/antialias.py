"""Fused analytic silhouette anti-aliasing as Warp kernels, wrapped in a :class:`torch.autograd.Function`.

Computes what :func:`cerberus_core.render.antialias.antialias` computes (that module's docstring is
the contract): per pair of adjacent pixels with different face ids, the front face, the walk along
the segment between the pixel centres across non-silhouette edges up to the first silhouette edge,
and the blend by the crossing position. The forward kernel records each blended pair (which pixel
is in front, the silhouette edge's two vertices); the backward kernel reads those records, without
searching the pairs again, and applies the hand-written adjoint of ``t = e_i / (e_i - e_o)`` with
``e = p . (v_a x v_b)``, accumulating into the colour and clip-space gradients with atomics.

One Warp thread handles the pairs to the right of and below the pixels of one image row on the CPU
(one pixel on CUDA); a pixel pair with equal face ids costs two face-id reads.
"""
from __future__ import annotations

from typing import Any

import torch
from torch.autograd.function import once_differentiable

from cerberus_core.render.antialias import MAX_WALK as _MAX_WALK
from cerberus_core.render.antialias import edge_neighbors
from cerberus_core.render.camera import pixel_centres
from cerberus_render_warp._common import KERNEL_OPTIONS, Tensor, overloads, row_span, wp
from cerberus_render_warp._runtime import as_warp, items_per_thread, launch_scenes, launch_stream, vec_view, warp_device
from cerberus_render_warp.arith import cross, torch_cross_is_fused
from cerberus_render_warp.shade import _barycentrics, _xyw

wp.set_module_options(KERNEL_OPTIONS)
MAX_WALK = wp.constant(_MAX_WALK)


@wp.func
def _depth_at(clip: wp.array2d(dtype=Any), faces: wp.array(dtype=wp.vec3i), b: int, f: int, px: Any, py: Any,
              fused: int):
    """Depth of face ``f`` at ``(px, py)``, rounded as the reference's barycentric depth."""
    v0, v1, v2, b0, b1, b2, inv_s = _barycentrics(clip, b, faces[f], px, py, fused)
    return b0 * v0[2] + b1 * v1[2] + b2 * v2[2]


@wp.func
def _det(clip: wp.array2d(dtype=Any), b: int, tri: wp.vec3i, fused: int):
    """``D = v0 . (v1 x v2)`` of a face, rounded as the reference's."""
    v0 = _xyw(clip[b, tri[0]])
    v1 = _xyw(clip[b, tri[1]])
    v2 = _xyw(clip[b, tri[2]])
    c = cross(v1, v2, fused)
    return v0[0] * c[0] + v0[1] * c[1] + v0[2] * c[2]


@wp.func
def _dot_p(px: Any, py: Any, e: Any):
    """``(px, py, 1) . e`` summed in torch's order of ``(lines * p).sum(-1)``."""
    return px * e[0] + py * e[1] + e[2]


@wp.func
def _pair(clip: wp.array2d(dtype=Any), faces: wp.array(dtype=wp.vec3i), nbrs: wp.array(dtype=wp.vec3i),
          face_id: wp.array3d(dtype=wp.int64), px_of_col: wp.array(dtype=Any), py_of_row: wp.array(dtype=Any),
          b: int, r0: int, c0: int, r1: int, c1: int, fused: int):
    """The silhouette crossing between pixels ``(r0, c0)`` and ``(r1, c1)`` of scene ``b``.

    Returns ``(keep, r_in, c_in, r_out, c_out, ia, ib, t)``: ``keep`` is 0 when the pair is left
    alone; else the front pixel, the other one, the edge's vertex indices and the crossing ``t``.
    """
    zero = px_of_col.dtype(0.0)
    f0 = int(face_id[b, r0, c0])
    f1 = int(face_id[b, r1, c1])
    px0 = px_of_col[c0]
    py0 = py_of_row[r0]
    px1 = px_of_col[c1]
    py1 = py_of_row[r1]
    if f0 >= 0 and f1 >= 0:
        # fast path (as the reference): the faces share an edge that is not a silhouette
        nb0 = nbrs[f0]
        ka = wp.int32(-1)
        for k in range(3):
            if nb0[2 - k] == f1:
                ka = 2 - k
        if ka >= 0:
            tri0 = faces[f0]
            ja = tri0[(ka + 1) % 3]
            jb = tri0[(ka + 2) % 3]
            line_a = cross(_xyw(clip[b, ja]), _xyw(clip[b, jb]), fused)
            t1 = faces[f1]
            o1 = _xyw(clip[b, t1[0] + t1[1] + t1[2] - ja - jb])
            if (o1[0] * line_a[0] + o1[1] * line_a[1] + o1[2] * line_a[2]) * _det(clip, b, tri0, fused) < zero:
                return wp.int32(0), r0, c0, r1, c1, wp.int32(0), wp.int32(0), zero
    first = wp.int32(1)
    if f0 < 0:
        first = 0
    elif f1 >= 0:
        if not (_depth_at(clip, faces, b, f0, px0, py0, fused) <= _depth_at(clip, faces, b, f1, px1, py1, fused)):
            first = 0
    r_in = r0
    c_in = c0
    r_out = r1
    c_out = c1
    tri_id = f0
    if first == 0:
        r_in = r1
        c_in = c1
        r_out = r0
        c_out = c0
        tri_id = f1
    pix = px_of_col[c_in]
    piy = py_of_row[r_in]
    pox = px_of_col[c_out]
    poy = py_of_row[r_out]
    one = px_of_col.dtype(1.0)
    keep = wp.int32(0)
    ia = wp.int32(0)
    ib = wp.int32(0)
    t_best = zero
    face = wp.int32(tri_id)
    step = wp.int32(0)
    while step < MAX_WALK:
        step += 1
        tri = faces[face]
        v0 = _xyw(clip[b, tri[0]])
        v1 = _xyw(clip[b, tri[1]])
        v2 = _xyw(clip[b, tri[2]])
        det = _det(clip, b, tri, fused)
        sign = zero
        if det > zero:
            sign = one
        elif det < zero:
            sign = -one
        best = wp.int32(-1)
        t_best = zero
        best_line = v0
        for k in range(3):
            va = v1
            vb = v2
            if k == 1:
                va = v2
                vb = v0
            elif k == 2:
                va = v0
                vb = v1
            line = cross(va, vb, fused)
            e_in = _dot_p(pix, piy, line)
            e_out = _dot_p(pox, poy, line)
            if sign * (e_out - e_in) < zero:
                t = e_in / (e_in - e_out)
                if best < 0 or t < t_best:
                    best = k
                    t_best = t
                    best_line = line
        if best < 0 or not (t_best < one) or det == zero:
            break  # the segment ends inside this face: no silhouette between the pixels
        nb = nbrs[face][best]
        ia = tri[(best + 1) % 3]
        ib = tri[(best + 2) % 3]
        silhouette = wp.int32(1)
        if nb >= 0:
            tn = faces[nb]
            o = _xyw(clip[b, tn[0] + tn[1] + tn[2] - ia - ib])
            if (o[0] * best_line[0] + o[1] * best_line[1] + o[2] * best_line[2]) * det < zero:
                silhouette = 0
        if silhouette != 0:
            # each edge is counted across the pixel pairs it runs most nearly perpendicular to
            across_x = wp.abs(best_line[0]) / px_of_col.dtype(float(face_id.shape[2]))
            across_y = wp.abs(best_line[1]) / px_of_col.dtype(float(face_id.shape[1]))
            if r0 == r1:
                if across_x >= across_y:
                    keep = 1
            elif across_y > across_x:
                keep = 1
            break
        face = nb
    return keep, r_in, c_in, r_out, c_out, ia, ib, t_best


@wp.func
def _blend_weight(r_in: int, c_in: int, r_out: int, c_out: int, t: Any):
    """Which pixel of a pair moves (``rm, cm``) towards which (``rs, cs``), by how much (``w``), and
    ``dw = dw/dt``: the pixel holding the edge (``t`` from the inner centre) moves by ``|t - 1/2|``."""
    half = type(t)(0.5)
    if t > half:
        return r_out, c_out, r_in, c_in, t - half, type(t)(1.0)
    return r_in, c_in, r_out, c_out, half - t, type(t)(-1.0)


@wp.func
def _blend(color: wp.array4d(dtype=Any), out: wp.array4d(dtype=Any), b: int, r_in: int, c_in: int, r_out: int,
           c_out: int, t: Any):
    """Add one pair's blend to ``out`` (see the contract: the pixel holding the edge moves towards the other)."""
    rm, cm, rs, cs, w, dw = _blend_weight(r_in, c_in, r_out, c_out, t)
    for ch in range(color.shape[3]):
        wp.atomic_add(out, b, rm, cm, ch, w * (color[b, rs, cs, ch] - color[b, rm, cm, ch]))


@wp.func
def _blend_adjoint(clip: wp.array2d(dtype=Any), px_of_col: wp.array(dtype=Any), py_of_row: wp.array(dtype=Any),
                   color: wp.array4d(dtype=Any), grad_out: wp.array4d(dtype=Any), grad_color: wp.array4d(dtype=Any),
                   grad_clip: wp.array2d(dtype=Any), need_color: int, need_clip: int, fused: int, b: int,
                   r_in: int, c_in: int, r_out: int, c_out: int, ia: int, ib: int):
    """Adjoint of :func:`_blend` for one pair: into ``grad_color`` (both pixels) and ``grad_clip``
    (the two vertices of the silhouette edge)."""
    zero = px_of_col.dtype(0.0)
    one = px_of_col.dtype(1.0)
    # recompute t from the edge alone, as the reference's differentiable part does
    va = _xyw(clip[b, ia])
    vb = _xyw(clip[b, ib])
    line = cross(va, vb, fused)
    pix = px_of_col[c_in]
    piy = py_of_row[r_in]
    pox = px_of_col[c_out]
    poy = py_of_row[r_out]
    e_in = _dot_p(pix, piy, line)
    e_out = _dot_p(pox, poy, line)
    inv = one / (e_in - e_out)
    t = e_in * inv
    rm, cm, rs, cs, w, dw = _blend_weight(r_in, c_in, r_out, c_out, t)
    g_w = zero
    for ch in range(color.shape[3]):
        g = grad_out[b, rm, cm, ch]
        g_w += g * (color[b, rs, cs, ch] - color[b, rm, cm, ch])
        if need_color != 0:
            wp.atomic_add(grad_color, b, rs, cs, ch, w * g)
            wp.atomic_add(grad_color, b, rm, cm, ch, -(w * g))
    if need_clip != 0:
        g_t = g_w * dw
        g_in = -g_t * e_out * inv * inv
        g_out = g_t * e_in * inv * inv
        g_line = wp.vector(pix, piy, one) * g_in + wp.vector(pox, poy, one) * g_out
        g_va = wp.cross(vb, g_line)
        g_vb = wp.cross(g_line, va)
        wp.atomic_add(grad_clip, b, ia, wp.vector(g_va[0], g_va[1], zero, g_va[2]))
        wp.atomic_add(grad_clip, b, ib, wp.vector(g_vb[0], g_vb[1], zero, g_vb[2]))


@wp.kernel
def _aa_kernel(
    clip: wp.array2d(dtype=Any),
    faces: wp.array(dtype=wp.vec3i),
    nbrs: wp.array(dtype=wp.vec3i),
    face_id: wp.array3d(dtype=wp.int64),
    px_of_col: wp.array(dtype=Any),
    py_of_row: wp.array(dtype=Any),
    fused: int,
    cols_per_thread: int,
    color: wp.array4d(dtype=Any),
    out: wp.array4d(dtype=Any),
    grad_out: wp.array4d(dtype=Any),
    grad_color: wp.array4d(dtype=Any),
    grad_clip: wp.array2d(dtype=Any),
    adjoint: int,
    need_color: int,
    need_clip: int,
    pair_kept: wp.array4d(dtype=wp.int32),
    pair_edge: wp.array4d(dtype=wp.int32),
):
    """Thread ``t``: the right (``d = 0``) and lower (``d = 1``) pairs of columns ``k * cols_per_thread ..``
    of one row. ``adjoint`` 0: blend ``color`` into ``out`` (which arrives holding ``color``) and record
    each blended pair, ``pair_kept[b, r, c, d]`` 1 (this pixel is the front one) or 2 (the other is) and
    ``pair_edge[b, r, c, 2 d : 2 d + 2]`` its silhouette edge's vertices (both arrive zeroed); 1: the
    adjoint over the recorded pairs, without searching them again (``grad_color`` arrives holding
    ``grad_out``, the identity part)."""
    height = face_id.shape[1]
    width = face_id.shape[2]
    b, r, c_first, c_last = row_span(wp.tid(), height, width, cols_per_thread)
    for c in range(c_first, c_last):
        f = face_id[b, r, c]
        for d in range(2):
            r1 = r + d
            c1 = c + 1 - d
            if adjoint == 0:
                if r1 < height and c1 < width:
                    if face_id[b, r1, c1] != f:
                        keep, r_in, c_in, r_out, c_out, ia, ib, t = _pair(
                            clip, faces, nbrs, face_id, px_of_col, py_of_row, b, r, c, r1, c1, fused)
                        if keep != 0:
                            _blend(color, out, b, r_in, c_in, r_out, c_out, t)
                            pair_kept[b, r, c, d] = wp.where(r_in == r and c_in == c, 1, 2)
                            pair_edge[b, r, c, 2 * d] = ia
                            pair_edge[b, r, c, 2 * d + 1] = ib
            else:
                kept = pair_kept[b, r, c, d]
                if kept == 1:
                    _blend_adjoint(clip, px_of_col, py_of_row, color, grad_out, grad_color, grad_clip, need_color,
                                   need_clip, fused, b, r, c, r1, c1, pair_edge[b, r, c, 2 * d],
                                   pair_edge[b, r, c, 2 * d + 1])
                elif kept == 2:
                    _blend_adjoint(clip, px_of_col, py_of_row, color, grad_out, grad_color, grad_clip, need_color,
                                   need_clip, fused, b, r1, c1, r, c, pair_edge[b, r, c, 2 * d],
                                   pair_edge[b, r, c, 2 * d + 1])


_SCALAR = {"px_of_col": wp.array, "py_of_row": wp.array}
_KERNEL = overloads(_aa_kernel, {}, {"clip": wp.array2d, "grad_clip": wp.array2d},
                    {**_SCALAR, "color": wp.array4d, "out": wp.array4d, "grad_out": wp.array4d,
                     "grad_color": wp.array4d})


def _inputs(b0: int, b1: int, clip, faces, nbrs, face_id, px, py, fused: int, cols: int) -> list[Any]:
    sl = slice(b0, b1)
    return [vec_view(clip[sl]), as_warp(faces, wp.vec3i), as_warp(nbrs, wp.vec3i), as_warp(face_id[sl]),
            as_warp(px), as_warp(py), fused, cols]


class _WarpAntialias(torch.autograd.Function):
    """``(color, clip, faces, neighbors, face_id) -> color_aa``.

    Shapes as in :func:`cerberus_core.render.antialias.antialias`; ``color`` contiguous in ``clip``'s
    dtype, ``faces`` and ``neighbors`` (from :func:`~cerberus_core.render.antialias.edge_neighbors`)
    int32 and contiguous. Differentiable w.r.t. ``color`` and ``clip`` (its x, y and w columns); once
    differentiable (no double backward).
    """

    @staticmethod
    def forward(ctx, color, clip, faces, nbrs, face_id):
        device = warp_device(clip.device)
        bsz, height, width, _ = color.shape
        px, py = pixel_centres(height, width, clip.dtype, clip.device)
        out = color.clone()
        kept = torch.zeros(bsz, height, width, 2, dtype=torch.int32, device=clip.device)
        edge = torch.zeros(bsz, height, width, 4, dtype=torch.int32, device=clip.device)
        cols = items_per_thread(width, device)
        fused = torch_cross_is_fused(clip.device, clip.dtype)
        launch_scenes(_KERNEL[clip.dtype], bsz, height * -(-width // cols), lambda b0, b1: [
            *_inputs(b0, b1, clip, faces, nbrs, face_id, px, py, fused, cols), as_warp(color[b0:b1]),
            as_warp(out[b0:b1]), None, None, None, 0, 0, 0, as_warp(kept[b0:b1]), as_warp(edge[b0:b1])],
            device, launch_stream(clip.device))
        ctx.save_for_backward(color, clip, faces, nbrs, face_id, kept, edge)
        ctx.set_materialize_grads(False)
        return out

    @staticmethod
    @once_differentiable
    def backward(ctx, grad_out):
        color, clip, faces, nbrs, face_id, kept, edge = ctx.saved_tensors
        need_color, need_clip = ctx.needs_input_grad[0], ctx.needs_input_grad[1]
        if grad_out is None or not (need_color or need_clip):
            return None, None, None, None, None
        device = warp_device(clip.device)
        bsz, height, width, _ = color.shape
        grad_out = grad_out.contiguous()
        grad_color = grad_out.clone() if need_color else None
        grad_clip = torch.zeros_like(clip) if need_clip else None
        px, py = pixel_centres(height, width, clip.dtype, clip.device)
        cols = items_per_thread(width, device)
        fused = torch_cross_is_fused(clip.device, clip.dtype)
        launch_scenes(_KERNEL[clip.dtype], bsz, height * -(-width // cols), lambda b0, b1: [
            *_inputs(b0, b1, clip, faces, nbrs, face_id, px, py, fused, cols), as_warp(color[b0:b1]), None,
            as_warp(grad_out[b0:b1]), None if grad_color is None else as_warp(grad_color[b0:b1]),
            None if grad_clip is None else vec_view(grad_clip[b0:b1]), 1, int(need_color), int(need_clip),
            as_warp(kept[b0:b1]), as_warp(edge[b0:b1])], device, launch_stream(clip.device))
        return grad_color, grad_clip, None, None, None


def antialias(color: Tensor, clip: Tensor, faces: Tensor, face_id: Tensor) -> Tensor:
    """Fused analytic silhouette anti-aliasing (drop-in for :func:`cerberus_core.render.antialias.antialias`).

    Args:
        color: ``(B, H, W, C)`` channels-last colours (converted to ``clip``'s dtype).
        clip: ``(B, V, 4)`` clip-space vertices (float32 or float64).
        faces: ``(F, 3)`` int vertex indices.
        face_id: ``(B, H, W)`` int64 visible face per pixel, -1 on background.
    Returns:
        ``(B, H, W, C)`` blended colours, differentiable w.r.t. ``color`` and ``clip``.
    """
    nbrs = edge_neighbors(faces).to(torch.int32).contiguous()
    return _WarpAntialias.apply(color.to(clip.dtype).contiguous(), clip, faces.to(torch.int32).contiguous(), nbrs,
                               face_id.to(torch.int64).contiguous())
