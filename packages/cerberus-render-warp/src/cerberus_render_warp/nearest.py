"""The image-plane nearest-neighbour search of the training pulls as one Warp kernel for both
directions: the renderer interface's ``nearest_indices`` (the contract is
:func:`cerberus_core.render.nearest.nearest_indices`, core's batched torch search).

Both point sets of an image are sorted by ``y`` first (torch's sort). One Warp thread then finds,
for one point, its nearest real target (or, for one real target, its nearest point): a binary search
for its ``y`` among the sorted other set, then a scan outwards in both directions that stops once
the ``y`` gap alone exceeds the best squared distance found. That is the exact nearest neighbour by
squared distance (the first by index among equal distances) in far fewer distance evaluations than
the full table; on the CPU one thread takes all the items of an image. Nothing is differentiated
(the pulls recompute the chosen pairs' distances with gradient).
"""
from __future__ import annotations

from typing import Any

import torch

from cerberus_render_warp._common import KERNEL_OPTIONS, Tensor, span, wp
from cerberus_render_warp._runtime import as_warp, items_per_thread, launch_scenes, launch_stream, vec_view, warp_device

wp.set_module_options(KERNEL_OPTIONS)


@wp.func
def _scan(p: Any, pool: wp.array2d(dtype=Any), order: wp.array2d(dtype=wp.int64), b: int, first: int, end: int,
          step: int, best_in: int, best_d_in: Any):
    """Scan ``pool[b, first], pool[b, first + step], ..`` (up to ``end``, excluded) for a point nearer
    to ``p`` than ``(best_in, best_d_in)`` (index, squared distance; index -1: none yet), until the
    ``y`` gap alone exceeds the best squared distance; returns the new best."""
    best = wp.int32(best_in)
    best_d = best_d_in * type(best_d_in)(1.0)
    j = wp.int32(first)
    while j != end:
        q = pool[b, j]
        dy = q[1] - p[1]
        if best >= 0 and dy * dy > best_d:
            break
        d = wp.length_sq(q - p)
        k = wp.int32(order[b, j])
        if best < 0 or d < best_d or (d == best_d and k < best):
            best_d = d
            best = k
        j += step
    return best, best_d


@wp.func
def _nearest_sorted(p: Any, pool: wp.array2d(dtype=Any), order: wp.array2d(dtype=wp.int64), b: int, count: int):
    """Index (in the unsorted set) of the point of ``pool[b, :count]`` (sorted by ``y``, ``order``
    mapping back) nearest to ``p``: the smallest index among equal squared distances."""
    lo = wp.int32(0)
    hi = wp.int32(count)
    while lo < hi:  # first sorted position with y >= p.y
        mid = (lo + hi) / 2
        if pool[b, mid][1] < p[1]:
            lo = mid + 1
        else:
            hi = mid
    best, best_d = _scan(p, pool, order, b, lo, count, 1, -1, p[0] * p[0])  # upwards from there
    best, best_d = _scan(p, pool, order, b, lo - 1, -1, -1, best, best_d)  # and downwards
    return best


@wp.kernel
def _nearest_kernel(points: wp.array2d(dtype=Any), targets: wp.array2d(dtype=Any), sorted_points: wp.array2d(dtype=Any),
                    sorted_targets: wp.array2d(dtype=Any), point_order: wp.array2d(dtype=wp.int64),
                    target_order: wp.array2d(dtype=wp.int64), counts: wp.array(dtype=wp.int64), items: int,
                    per_thread: int, to_target: wp.array2d(dtype=wp.int64), to_point: wp.array2d(dtype=wp.int64)):
    """Items ``i < M`` of image ``b``: point ``i``'s nearest of the ``counts[b]`` real targets; items
    ``M + j``: real target ``j``'s nearest point. Outputs arrive zeroed (the answer where nothing is
    real)."""
    b, first, last = span(wp.tid(), items, per_thread)
    m = points.shape[1]
    count = int(counts[b])
    for i in range(first, last):
        if i < m:
            if count > 0:
                to_target[b, i] = wp.int64(_nearest_sorted(points[b, i], sorted_targets, target_order, b, count))
        else:
            j = i - m
            if j < count and m > 0:
                to_point[b, j] = wp.int64(_nearest_sorted(targets[b, j], sorted_points, point_order, b, m))


_VEC2 = ("points", "targets", "sorted_points", "sorted_targets")
_KERNEL = {dtype: wp.overload(_nearest_kernel, {name: wp.array2d(dtype=wp.types.vector(2, t)) for name in _VEC2})
           for dtype, t in ((torch.float32, wp.float32), (torch.float64, wp.float64))}


def _sorted_by_y(points: Tensor, real: Tensor | None = None) -> tuple[Tensor, Tensor]:
    """``points`` ``(N, P, 2)`` sorted by ``y`` per image (the unreal ones, ``~real``, last) and the
    ``(N, P)`` int64 indices that sorted them."""
    y = points[..., 1] if real is None else points[..., 1].masked_fill(~real, float("inf"))
    order = torch.sort(y, dim=1, stable=True).indices
    return points.gather(1, order.unsqueeze(-1).expand_as(points)).contiguous(), order.contiguous()


def nearest_indices(points: Tensor, targets: Tensor, counts: Tensor, both: bool = True) -> tuple[Tensor, Tensor | None]:
    """Nearest neighbours between 2-D point sets per image, without gradient (drop-in for
    :func:`cerberus_core.render.nearest.nearest_indices`, whose docstring is the contract).

    Args:
        points: ``(N, M, 2)`` float32 or float64; targets: ``(N, K, 2)`` in the same dtype, the first
            ``counts[n]`` real in image ``n``; counts: ``(N,)`` int; both: also each target's nearest point.
    Returns:
        ``to_target`` ``(N, M)`` and ``to_point`` ``(N, K)`` (``None`` without ``both``), int64.
    """
    n, m = points.shape[:2]
    k = targets.shape[1]
    to_target = torch.zeros(n, m, dtype=torch.int64, device=points.device)
    to_point = torch.zeros(n, k, dtype=torch.int64, device=points.device)
    items = m + (k if both else 0)
    if n and items:
        device = warp_device(points.device)
        with torch.no_grad():
            points, targets = points.detach().contiguous(), targets.detach().to(points.dtype).contiguous()
            counts = counts.to(device=points.device, dtype=torch.int64).contiguous()
            sorted_points, point_order = _sorted_by_y(points)
            sorted_targets, target_order = _sorted_by_y(targets, torch.arange(k, device=points.device) < counts[:, None])
        per_thread = items_per_thread(items, device)
        launch_scenes(_KERNEL[points.dtype], n, -(-items // per_thread), lambda b0, b1: [
            vec_view(points[b0:b1]), vec_view(targets[b0:b1]), vec_view(sorted_points[b0:b1]),
            vec_view(sorted_targets[b0:b1]), as_warp(point_order[b0:b1]), as_warp(target_order[b0:b1]),
            as_warp(counts[b0:b1]), items, per_thread, as_warp(to_target[b0:b1]), as_warp(to_point[b0:b1])],
            device, launch_stream(points.device))
    return to_target, (to_point if both else None)


__all__ = ["nearest_indices"]
