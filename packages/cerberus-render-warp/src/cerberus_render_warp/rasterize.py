"""Z-buffered rasterization as Warp kernels (the rule of :mod:`cerberus_core.render.interface`).

A first kernel projects every vertex once to its pixel bounds; then a Warp thread sets a triangle up
(homogeneous edge cross products, determinant, and its pixel bounding box: the union of its
vertices' bounds) and walks the pixel centres in its box. On parallel devices (CUDA: one thread per (scene, triangle))
two launches of the same kernel make the result deterministic: pass 0 keeps the nearest depth per
pixel with ``atomic_min`` on a float z-buffer; pass 1 repeats the exact same arithmetic and, where a
triangle's depth equals the z-buffer, keeps the smallest face id with an integer ``atomic_min``; a
last per-pixel kernel turns "no face" into ``-1``. Warp's CPU device runs a launch's threads one
after another, so there one thread per scene loops over its triangles and keeps the lexicographic
minimum of (depth, face id) in a single pass, straight into the output.

The arithmetic mirrors the torch backend operation by operation (see :mod:`.arith`), so face ids
agree with it bit for bit.
"""
from __future__ import annotations

from typing import Any

import torch

from cerberus_core.errors import ConfigError, RenderInputError
from cerberus_core.render.camera import BBOX_EPS, PIXEL_CENTRE, pixel_centres
from cerberus_render_warp._common import KERNEL_OPTIONS, Tensor, span, wp
from cerberus_render_warp._runtime import as_warp, items_per_thread, launch_scenes, launch_stream, vec_view, warp_device
from cerberus_render_warp.arith import cross_term, torch_cross_is_fused

wp.set_module_options(KERNEL_OPTIONS)

@wp.func
def _pixel_bound(lo: Any, hi: Any, size: int):
    """The kernel form of :func:`cerberus_core.render.camera.centre_range`: the inclusive index range
    of pixel centres ``k + PIXEL_CENTRE`` inside ``[lo, hi]`` (pixels), widened by ``BBOX_EPS``,
    clipped to ``0 .. size - 1``. Coordinates are clamped before the integer conversion."""
    lo_c = wp.clamp(lo, type(lo)(-2.0), type(lo)(size) + type(lo)(2.0))
    hi_c = wp.clamp(hi, type(lo)(-2.0), type(lo)(size) + type(lo)(2.0))
    first = wp.max(int(wp.ceil(lo_c - type(lo)(PIXEL_CENTRE) - type(lo)(BBOX_EPS))), 0)
    last = wp.min(int(wp.floor(hi_c - type(lo)(PIXEL_CENTRE) + type(lo)(BBOX_EPS))), size - 1)
    return first, last


NO_FACE = wp.constant(2147483647)
"""Initial value of the parallel path's face-id buffer (no face drawn yet)."""

MODE_DEPTH, MODE_FACE, MODE_SERIAL = 0, 1, 2
"""Kernel modes: z-buffer pass and face-id pass of the parallel (CUDA) path, and the single pass
used where threads run one after another (Warp's CPU device), which keeps the lexicographic minimum
of (depth, face id) directly in the output."""


@wp.kernel
def _vertex_bounds_kernel(
    clip: wp.array2d(dtype=Any),
    near: Any,
    width: int,
    height: int,
    vertices_per_thread: int,
    bounds: wp.array2d(dtype=wp.vec4i),
):
    """Thread ``t``: vertices ``k * vertices_per_thread ..`` of scene ``b``. Each vertex's pixel
    bounds ``(first col, last col, first row, last row)`` as :func:`_pixel_bound` gives them for the
    degenerate box ``[u, u] x [v, v]`` of its projection (vertices with ``w <= near`` get an empty
    range; their triangles are not drawn)."""
    b, v_first, v_last = span(wp.tid(), clip.shape[1], vertices_per_thread)
    one = type(near)(1.0)
    half_w = type(near)(0.5) * type(near)(width)
    half_h = type(near)(0.5) * type(near)(height)
    for i in range(v_first, v_last):
        p = clip[b, i]
        w = p[3]
        if w > near:
            r = one / w
            u = (p[0] * r + one) * half_w
            v = (one - p[1] * r) * half_h
            col0, col1 = _pixel_bound(u, u, width)
            row0, row1 = _pixel_bound(v, v, height)
            bounds[b, i] = wp.vec4i(col0, col1, row0, row1)
        else:
            bounds[b, i] = wp.vec4i(width, -1, height, -1)


@wp.kernel
def _raster_kernel(
    clip: wp.array2d(dtype=Any),
    bounds: wp.array2d(dtype=wp.vec4i),
    faces: wp.array(dtype=wp.vec3i),
    px_of_col: wp.array(dtype=Any),
    py_of_row: wp.array(dtype=Any),
    near: Any,
    fused: int,
    mode: int,
    faces_per_thread: int,
    zbuf: wp.array3d(dtype=Any),
    winner: wp.array3d(dtype=wp.int32),
    out: wp.array3d(dtype=wp.int64),
):
    """Thread ``t``: faces ``k * faces_per_thread ..`` of scene ``b`` (``t = b * chunks + k``)."""
    b, f_first, f_last = span(wp.tid(), faces.shape[0], faces_per_thread)
    zero = type(near)(0.0)
    one = type(near)(1.0)
    inf = type(near)(wp.inf)
    for f in range(f_first, f_last):
        tri = faces[f]
        p0 = clip[b, tri[0]]
        p1 = clip[b, tri[1]]
        p2 = clip[b, tri[2]]
        w0 = p0[3]
        w1 = p1[3]
        w2 = p2[3]
        if w0 > near and w1 > near and w2 > near:
            x0 = p0[0]
            y0 = p0[1]
            x1 = p1[0]
            y1 = p1[1]
            x2 = p2[0]
            y2 = p2[1]
            # Pixel bounding box: _pixel_bound is monotone in both ends, so the box of the
            # triangle's projected extent is the union of its vertices' (precomputed) boxes.
            q0 = bounds[b, tri[0]]
            q1 = bounds[b, tri[1]]
            q2 = bounds[b, tri[2]]
            col0 = wp.min(wp.min(q0[0], q1[0]), q2[0])
            col1 = wp.max(wp.max(q0[1], q1[1]), q2[1])
            row0 = wp.min(wp.min(q0[2], q1[2]), q2[2])
            row1 = wp.max(wp.max(q0[3], q1[3]), q2[3])
            if col0 <= col1 and row0 <= row1:
                # Edge cross products e_k = v_{k+1} x v_{k+2} with v = (x, y, w): c_k = p . e_k.
                e0x = cross_term(y1, w2, w1, y2, fused)
                e0y = cross_term(w1, x2, x1, w2, fused)
                e0w = cross_term(x1, y2, y1, x2, fused)
                e1x = cross_term(y2, w0, w2, y0, fused)
                e1y = cross_term(w2, x0, x2, w0, fused)
                e1w = cross_term(x2, y0, y2, x0, fused)
                e2x = cross_term(y0, w1, w0, y1, fused)
                e2y = cross_term(w0, x1, x0, w1, fused)
                e2w = cross_term(x0, y1, y0, x1, fused)
                det = x0 * e0x + y0 * e0y + w0 * e0w
                if det != zero:
                    sgn = one
                    if det < zero:
                        sgn = -one
                    for row in range(row0, row1 + 1):
                        py = py_of_row[row]
                        # Rounded as torch rounds it: c = (e.x * px + e.y * py) + e.w, each op rounded.
                        t0 = e0y * py
                        t1 = e1y * py
                        t2 = e2y * py
                        for col in range(col0, col1 + 1):
                            px = px_of_col[col]
                            c0 = (e0x * px + t0) + e0w
                            c1 = (e1x * px + t1) + e1w
                            c2 = (e2x * px + t2) + e2w
                            if c0 * sgn >= zero and c1 * sgn >= zero and c2 * sgn >= zero:
                                s = c0 + c1 + c2
                                depth = det / s
                                if s != zero and depth > zero and depth < inf:  # finite and positive
                                    if mode == MODE_SERIAL:
                                        z = zbuf[b, row, col]
                                        if depth < z or (depth == z and wp.int64(f) < out[b, row, col]):
                                            zbuf[b, row, col] = depth
                                            out[b, row, col] = wp.int64(f)
                                    elif mode == MODE_DEPTH:
                                        wp.atomic_min(zbuf, b, row, col, depth)
                                    elif depth == zbuf[b, row, col]:
                                        wp.atomic_min(winner, b, row, col, f)


@wp.kernel
def _finalize_kernel(winner: wp.array3d(dtype=wp.int32), out: wp.array3d(dtype=wp.int64)):
    """Pixel (b, r, c): the winning face id, or -1 where none was drawn (``winner`` still NO_FACE)."""
    b, r, c = wp.tid()
    f = winner[b, r, c]
    if f == NO_FACE:
        out[b, r, c] = wp.int64(-1)
    else:
        out[b, r, c] = wp.int64(f)


_BOUNDS = {
    dtype: wp.overload(_vertex_bounds_kernel, {"clip": wp.array2d(dtype=wp.types.vector(4, T)), "near": T})
    for dtype, T in ((torch.float32, wp.float32), (torch.float64, wp.float64))
}

_RASTER = {
    dtype: wp.overload(_raster_kernel, {"clip": wp.array2d(dtype=wp.types.vector(4, T)), "px_of_col": wp.array(dtype=T),
                                        "py_of_row": wp.array(dtype=T), "near": T, "zbuf": wp.array3d(dtype=T)})
    for dtype, T in ((torch.float32, wp.float32), (torch.float64, wp.float64))
}


def rasterize(clip: Tensor, faces: Tensor, height: int, width: int, near: float = 0.05, *,
              serial: bool | None = None) -> Tensor:
    """Visible face id per pixel (not differentiable).

    Args:
        clip: ``(B, V, 4)`` float32 (or float64) clip-space vertices, on the CPU or a CUDA device.
        faces: ``(F, 3)`` int vertex indices.
        height, width: image size in pixels.
        near: triangles with a vertex of ``w <= near`` are not drawn.
        serial: ``True``: one thread per scene keeps the (depth, face id) minimum in a single pass,
            exact only where Warp runs threads one after another (its CPU device). ``False``: the
            parallel two-pass atomic path (z-buffer, then face ids; used on CUDA). Default: serial on
            the CPU, parallel on CUDA. Both give identical results.
    Returns:
        ``(B, H, W)`` int64 face ids, -1 on background, on ``clip``'s device.
    """
    bsz, nfaces = clip.shape[0], faces.shape[0]
    out = torch.full((bsz, height, width), -1, dtype=torch.int64, device=clip.device)
    if bsz == 0 or nfaces == 0:
        return out
    if nfaces >= NO_FACE:
        raise RenderInputError(f"warp renderer: at most {NO_FACE - 1} faces per scene, got {nfaces}; split the "
                               "scene, or use the 'torch' renderer")
    device = warp_device(clip.device)
    stream = launch_stream(clip.device)
    clip = clip.detach()
    px, py = pixel_centres(height, width, clip.dtype, clip.device)
    zbuf = torch.full((bsz, height, width), float("inf"), dtype=clip.dtype, device=clip.device)
    near_t = (wp.float32 if clip.dtype == torch.float32 else wp.float64)(near)
    shared = [as_warp(faces.to(torch.int32).contiguous(), wp.vec3i), as_warp(px), as_warp(py), near_t,
              torch_cross_is_fused(clip.device, clip.dtype)]
    kernel = _RASTER[clip.dtype]
    if serial is None:
        serial = device.is_cpu
    elif serial and not device.is_cpu:
        raise ConfigError("warp renderer: serial rasterization is only exact on the CPU; use `serial=False` on CUDA", key="serial", value=serial)
    # Each vertex's pixel bounds once, instead of re-projecting it for every triangle it is in.
    nverts = clip.shape[1]
    bounds = torch.empty((bsz, nverts, 4), dtype=torch.int32, device=clip.device)
    per_thread = items_per_thread(nverts, device)
    launch_scenes(_BOUNDS[clip.dtype], bsz, -(-nverts // per_thread), lambda b0, b1: [
        vec_view(clip[b0:b1]), near_t, width, height, per_thread, as_warp(bounds[b0:b1], wp.vec4i)], device, stream)

    def geometry(b0: int, b1: int) -> list[Any]:
        return [vec_view(clip[b0:b1]), as_warp(bounds[b0:b1], wp.vec4i)]
    if serial:
        # Warp runs the threads of a CPU launch one after another: one thread per scene, one pass.
        launch_scenes(kernel, bsz, 1, lambda b0, b1: [
            *geometry(b0, b1), *shared, MODE_SERIAL, nfaces, as_warp(zbuf[b0:b1]), None, as_warp(out[b0:b1])],
            device)
        return out
    winner = torch.full((bsz, height, width), NO_FACE, dtype=torch.int32, device=clip.device)
    for mode in (MODE_DEPTH, MODE_FACE):
        launch_scenes(kernel, bsz, nfaces, lambda b0, b1, mode=mode: [
            *geometry(b0, b1), *shared, mode, 1, as_warp(zbuf[b0:b1]), as_warp(winner[b0:b1]), None],
            device, stream)
    wp.launch(_finalize_kernel, dim=(bsz, height, width), inputs=[as_warp(winner), as_warp(out)],
              device=device, stream=stream)
    return out
