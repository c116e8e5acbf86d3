"""Fused differentiable shading as Warp kernels, wrapped in a :class:`torch.autograd.Function`.

Computes exactly what :func:`cerberus_core.render.shading.shade` computes, per covered pixel:
perspective-correct barycentrics from the clip-space vertices (homogeneous edge functions),
interpolated normal and albedo, ``normalize(eps=1e-12)``, Lambert with ``clamp_min(0)`` and the
interpolated depth. The backward kernel recomputes that forward per covered pixel and applies
hand-written adjoints (torch's conventions at the kinks: ``clamp_min`` passes the gradient where its
input is ``>=`` the bound), accumulating into per-vertex and per-scene gradients with atomics.

Work is proportional to the covered pixels: a background pixel costs one face-id read (and, in the
forward pass, writing its zero colour). On the CPU one Warp thread handles one image row (Warp runs
CPU threads one after another, so fewer, longer threads cost less); on CUDA one thread per pixel.
"""
from __future__ import annotations

from typing import Any

import torch
from torch.autograd.function import once_differentiable

from cerberus_core.render.camera import pixel_centres
from cerberus_core.render.light import Light
from cerberus_core.render.templates import NORMAL_EPS
from cerberus_render_warp._common import KERNEL_OPTIONS, Tensor, overloads, row_span, wp
from cerberus_render_warp._runtime import as_warp, items_per_thread, launch_scenes, launch_stream, vec_view, warp_device
from cerberus_render_warp.arith import cross, torch_cross_is_fused

wp.set_module_options(KERNEL_OPTIONS)


@wp.func
def _xyw(c: Any):
    """Homogeneous screen vector ``(x, y, w)`` of a clip-space vertex ``(x, y, z, w)``."""
    return wp.vector(c[0], c[1], c[3])


@wp.func
def _edge(px: Any, py: Any, e: Any):
    """``p . e`` for ``p = (px, py, 1)``, summed in torch's order."""
    return px * e[0] + py * e[1] + e[2]


@wp.func
def _lerp3(a0: Any, a1: Any, a2: Any, b0: Any, b1: Any, b2: Any):
    """``a0 b0 + a1 b1 + a2 b2`` (vectors times barycentrics), summed in torch's order."""
    return a0 * b0 + a1 * b1 + a2 * b2


@wp.func
def _barycentrics(clip: wp.array2d(dtype=Any), b: int, tri: wp.vec3i, px: Any, py: Any, fused: int):
    """Screen vectors ``(x, y, w)`` of a triangle's vertices and its perspective-correct barycentrics
    at ``p = (px, py, 1)`` (as :func:`cerberus_core.render.shading.homogeneous_barycentrics`), plus
    ``1 / s`` for the backward pass."""
    v0 = _xyw(clip[b, tri[0]])
    v1 = _xyw(clip[b, tri[1]])
    v2 = _xyw(clip[b, tri[2]])
    c0 = _edge(px, py, cross(v1, v2, fused))
    c1 = _edge(px, py, cross(v2, v0, fused))
    c2 = _edge(px, py, cross(v0, v1, fused))
    s = c0 + c1 + c2
    return v0, v1, v2, c0 / s, c1 / s, c2 / s, type(s)(1.0) / s


@wp.func
def _unit_normal(n: Any, ldir: Any):
    """``normalize(n, eps=1e-12)`` as torch computes it and the cosine with the light direction:
    ``(|n|, max(|n|, eps), n / max(|n|, eps), cos before clamping)``."""
    length = wp.length(n)
    den = wp.max(length, type(length)(NORMAL_EPS))
    nh = n / den
    return length, den, nh, wp.dot(nh, ldir)


@wp.kernel
def _shade_kernel(
    clip: wp.array2d(dtype=Any),
    faces: wp.array(dtype=wp.vec3i),
    face_id: wp.array3d(dtype=wp.int64),
    px_of_col: wp.array(dtype=Any),
    py_of_row: wp.array(dtype=Any),
    normals: wp.array2d(dtype=Any),
    albedo: wp.array2d(dtype=Any),
    direction: wp.array(dtype=Any),
    ambient: wp.array(dtype=Any),
    diffuse: wp.array(dtype=Any),
    fused: int,
    cols_per_thread: int,
    rgb: wp.array3d(dtype=Any),
    depth: wp.array3d(dtype=Any),
    grad_rgb: wp.array4d(dtype=Any),
    grad_depth: wp.array3d(dtype=Any),
    has_grad_rgb: int,
    has_grad_depth: int,
    grad_clip: wp.array2d(dtype=Any),
    grad_normals: wp.array2d(dtype=Any),
    grad_albedo: wp.array2d(dtype=Any),
    grad_direction: wp.array(dtype=Any),
    grad_ambient: wp.array(dtype=Any),
    grad_diffuse: wp.array(dtype=Any),
    adjoint: int,
    need_clip: int,
    need_normals: int,
    need_albedo: int,
    need_light: int,
):
    """Thread ``t``: columns ``k * cols_per_thread ..`` of one image row (see
    :func:`~cerberus_render_warp._common.row_span`). ``adjoint`` 0: write ``rgb`` and ``depth``;
    1: recompute them and accumulate the adjoints of the inputs flagged by ``need_*`` instead."""
    b, r, c_first, c_last = row_span(wp.tid(), face_id.shape[1], face_id.shape[2], cols_per_thread)
    zero = px_of_col.dtype(0.0)
    one = px_of_col.dtype(1.0)
    eps = px_of_col.dtype(NORMAL_EPS)
    py = py_of_row[r]
    ldir = direction[b]
    amb = ambient[b]
    dif = diffuse[b]
    zero3 = wp.vector(zero, zero, zero)
    acc_dir = zero3
    acc_amb = zero3
    acc_dif = zero3
    for c in range(c_first, c_last):
        f = int(face_id[b, r, c])
        if f < 0:
            if adjoint == 0:
                rgb[b, r, c] = zero3
                depth[b, r, c] = zero
            continue
        px = px_of_col[c]
        tri = faces[f]
        v0, v1, v2, b0, b1, b2, inv_s = _barycentrics(clip, b, tri, px, py, fused)
        n0 = normals[b, tri[0]]
        n1 = normals[b, tri[1]]
        n2 = normals[b, tri[2]]
        a0 = albedo[b, tri[0]]
        a1 = albedo[b, tri[1]]
        a2 = albedo[b, tri[2]]
        n = _lerp3(n0, n1, n2, b0, b1, b2)
        a = _lerp3(a0, a1, a2, b0, b1, b2)
        length, den, nh, cos_raw = _unit_normal(n, ldir)
        cos = wp.max(cos_raw, zero)
        if adjoint == 0:
            depth[b, r, c] = b0 * v0[2] + b1 * v1[2] + b2 * v2[2]
            rgb[b, r, c] = wp.cw_mul(a, amb + dif * cos)
        else:
            g = zero3
            if has_grad_rgb != 0:
                g = wp.vector(grad_rgb[b, r, c, 0], grad_rgb[b, r, c, 1], grad_rgb[b, r, c, 2])
            gd = zero
            if has_grad_depth != 0:
                gd = grad_depth[b, r, c]
            # ---- adjoints: rgb = a * (amb + dif * cos)
            g_a = wp.cw_mul(g, amb + dif * cos)
            g_light = wp.cw_mul(g, a)
            acc_amb += g_light
            acc_dif += g_light * cos
            g_cos = wp.dot(g_light, dif)
            if not (cos_raw >= zero):  # clamp_min(0) passes the gradient only where its input >= 0
                g_cos = zero
            acc_dir += nh * g_cos
            # nh = n / max(|n|, eps): the max passes the gradient where |n| >= eps
            g_nh = ldir * g_cos
            inv_den = one / den
            g_n = g_nh * inv_den
            if length >= eps:
                g_n -= n * (wp.dot(g_nh, n) * inv_den * inv_den / length)
            if need_normals != 0:
                wp.atomic_add(grad_normals, b, tri[0], g_n * b0)
                wp.atomic_add(grad_normals, b, tri[1], g_n * b1)
                wp.atomic_add(grad_normals, b, tri[2], g_n * b2)
            if need_albedo != 0:
                wp.atomic_add(grad_albedo, b, tri[0], g_a * b0)
                wp.atomic_add(grad_albedo, b, tri[1], g_a * b1)
                wp.atomic_add(grad_albedo, b, tri[2], g_a * b2)
            if need_clip != 0:
                # depth, normal and albedo are all linear in the barycentrics b_k = c_k / s
                gb0 = gd * v0[2] + wp.dot(g_n, n0) + wp.dot(g_a, a0)
                gb1 = gd * v1[2] + wp.dot(g_n, n1) + wp.dot(g_a, a1)
                gb2 = gd * v2[2] + wp.dot(g_n, n2) + wp.dot(g_a, a2)
                g_s = -(gb0 * b0 + gb1 * b1 + gb2 * b2) * inv_s
                p = wp.vector(px, py, one)
                ge0 = p * (gb0 * inv_s + g_s)
                ge1 = p * (gb1 * inv_s + g_s)
                ge2 = p * (gb2 * inv_s + g_s)
                # c_k = p . e_k with e0 = v1 x v2, e1 = v2 x v0, e2 = v0 x v1; depth adds w_k b_k
                gv0 = wp.cross(ge1, v2) + wp.cross(v1, ge2)
                gv1 = wp.cross(v2, ge0) + wp.cross(ge2, v0)
                gv2 = wp.cross(ge0, v1) + wp.cross(v0, ge1)
                wp.atomic_add(grad_clip, b, tri[0], wp.vector(gv0[0], gv0[1], zero, gv0[2] + gd * b0))
                wp.atomic_add(grad_clip, b, tri[1], wp.vector(gv1[0], gv1[1], zero, gv1[2] + gd * b1))
                wp.atomic_add(grad_clip, b, tri[2], wp.vector(gv2[0], gv2[1], zero, gv2[2] + gd * b2))
    if adjoint != 0 and need_light != 0:
        wp.atomic_add(grad_direction, b, acc_dir)
        wp.atomic_add(grad_ambient, b, acc_amb)
        wp.atomic_add(grad_diffuse, b, acc_dif)


_VEC3_IN = {"normals": wp.array2d, "albedo": wp.array2d, "direction": wp.array, "ambient": wp.array,
            "diffuse": wp.array}
_SCALAR_IN = {"px_of_col": wp.array, "py_of_row": wp.array}
_KERNEL = overloads(
    _shade_kernel,
    {**_VEC3_IN, "rgb": wp.array3d, "grad_normals": wp.array2d, "grad_albedo": wp.array2d,
     "grad_direction": wp.array, "grad_ambient": wp.array, "grad_diffuse": wp.array},
    {"clip": wp.array2d, "grad_clip": wp.array2d},
    {**_SCALAR_IN, "depth": wp.array3d, "grad_rgb": wp.array4d, "grad_depth": wp.array3d})


def _scene_inputs(b0: int, b1: int, clip, faces, face_id, px, py, normals, albedo, direction, ambient,
                  diffuse) -> list[Any]:
    """The kernel's scene arguments (both directions), for scenes ``b0 .. b1 - 1``."""
    sl = slice(b0, b1)
    return [vec_view(clip[sl]), as_warp(faces, wp.vec3i), as_warp(face_id[sl]), as_warp(px), as_warp(py),
            *[vec_view(t[sl]) for t in (normals, albedo, direction, ambient, diffuse)]]


def _sliced(t: Tensor | None, b0: int, b1: int, vec: bool = False):
    if t is None:
        return None
    return vec_view(t[b0:b1]) if vec else as_warp(t[b0:b1])


class _WarpShade(torch.autograd.Function):
    """``(clip, faces, face_id, normals, albedo, direction, ambient, diffuse) -> (rgb, depth)``.

    Shapes as in :meth:`cerberus_core.render.interface.Renderer.shade`; ``faces`` must be int32 and
    contiguous. Differentiable w.r.t. ``clip`` (its x, y and w columns), ``normals``, ``albedo`` and
    the three light tensors; once differentiable (no double backward).
    """

    @staticmethod
    def forward(ctx, clip, faces, face_id, normals, albedo, direction, ambient, diffuse):
        device = warp_device(clip.device)
        bsz, height, width = face_id.shape
        px, py = pixel_centres(height, width, clip.dtype, clip.device)
        rgb = torch.empty((bsz, height, width, 3), dtype=clip.dtype, device=clip.device)
        depth = torch.empty((bsz, height, width), dtype=clip.dtype, device=clip.device)
        cols = items_per_thread(width, device)
        fused = torch_cross_is_fused(clip.device, clip.dtype)
        tensors = (clip, faces, face_id, px, py, normals, albedo, direction, ambient, diffuse)
        launch_scenes(_KERNEL[clip.dtype], bsz, height * -(-width // cols), lambda b0, b1: [
            *_scene_inputs(b0, b1, *tensors), fused, cols, vec_view(rgb[b0:b1]), as_warp(depth[b0:b1]),
            None, None, 0, 0, *[None] * 6, 0, 0, 0, 0, 0], device, launch_stream(clip.device))
        ctx.save_for_backward(clip, faces, face_id, normals, albedo, direction, ambient, diffuse)
        ctx.set_materialize_grads(False)
        return rgb, depth

    @staticmethod
    @once_differentiable
    def backward(ctx, grad_rgb, grad_depth):
        clip, faces, face_id, normals, albedo, direction, ambient, diffuse = ctx.saved_tensors
        need = ctx.needs_input_grad
        need_light = need[5] or need[6] or need[7]
        if grad_rgb is None and grad_depth is None:
            return (None,) * 8
        device = warp_device(clip.device)
        bsz, height, width = face_id.shape

        def zeros_if(flag: bool, like: Tensor) -> Tensor | None:
            return torch.zeros(like.shape, dtype=like.dtype, device=like.device) if flag else None

        grads = [zeros_if(need[0], clip), zeros_if(need[3], normals), zeros_if(need[4], albedo),
                 zeros_if(need_light, direction), zeros_if(need_light, ambient), zeros_if(need_light, diffuse)]
        if any(g is not None for g in grads):
            px, py = pixel_centres(height, width, clip.dtype, clip.device)
            cols = items_per_thread(width, device)
            fused = torch_cross_is_fused(clip.device, clip.dtype)
            flags = [int(need[0]), int(need[3]), int(need[4]), int(need_light)]
            tensors = (clip, faces, face_id, px, py, normals, albedo, direction, ambient, diffuse)
            launch_scenes(_KERNEL[clip.dtype], bsz, height * -(-width // cols), lambda b0, b1: [
                *_scene_inputs(b0, b1, *tensors), fused, cols, None, None, _sliced(grad_rgb, b0, b1),
                _sliced(grad_depth, b0, b1), int(grad_rgb is not None), int(grad_depth is not None),
                *[_sliced(g, b0, b1, vec=True) for g in grads], 1, *flags], device, launch_stream(clip.device))
        g_clip, g_normals, g_albedo, g_dir, g_amb, g_dif = grads
        return (g_clip, None, None, g_normals, g_albedo,
                g_dir if need[5] else None, g_amb if need[6] else None, g_dif if need[7] else None)


def shade(clip: Tensor, faces: Tensor, face_id: Tensor, normals: Tensor, albedo: Tensor,
          light: Light) -> tuple[Tensor, Tensor]:
    """Fused differentiable shading (drop-in for :func:`cerberus_core.render.shading.shade`).

    Args:
        clip: ``(B, V, 4)`` clip-space vertices (float32 or float64).
        faces: ``(F, 3)`` int vertex indices.
        face_id: ``(B, H, W)`` int64 visible face per pixel, -1 on background.
        normals: ``(B, V, 3)`` unit vertex normals.
        albedo: ``(B, V, 3)`` per-vertex albedo (may be an expanded view).
        light: ``direction``, ``ambient``, ``diffuse`` each ``(B, 3)``.
    Returns:
        ``rgb`` ``(B, H, W, 3)`` and ``depth`` ``(B, H, W)`` (world units), 0 on background.
    """
    tensors = [normals, albedo, light.direction, light.ambient, light.diffuse]  # checked by the op (render.ops.shade)
    normals, albedo, direction, ambient, diffuse = (t.to(clip.dtype) for t in tensors)
    return _WarpShade.apply(clip, faces.to(torch.int32).contiguous(), face_id.to(torch.int64), normals, albedo,
                           direction, ambient, diffuse)
