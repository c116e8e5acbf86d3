"""The image-plane nearest-neighbour search of the pulls (the chamfer and hidden-part terms of
:mod:`cerberus_core.losses`): a kernel a renderer backend provides (:meth:`Renderer.nearest_indices
<cerberus_core.render.interface.Renderer.nearest_indices>`), with this batched torch search as the
shared reference every backend inherits.

The search has no gradient: the pulls recompute the distances of the chosen pairs with gradient
(the gradient of a minimum reaches only its argument). Backends may break near-ties differently
(the index then differs, the distance to within rounding does not).
"""
from __future__ import annotations

import torch

Tensor = torch.Tensor


def nearest_indices(points: Tensor, targets: Tensor, counts: Tensor, both: bool = True) -> tuple[Tensor, Tensor | None]:
    """Nearest-neighbour indices between two point sets per image, searched without gradient.

    Batched over the images: each direction is one ``baddbmm`` of the squared distances less the
    searching point's own ``|p|^2`` (which does not change its minimum), ``|q|^2 - 2 p . q``, padded
    targets masked out, and one minimum over the table's last (contiguous) dimension.

    Args:
        points: ``(N, M, 2)`` float.
        targets: ``(N, K, 2)`` of which the first ``counts[n]`` are real in image ``n``.
        counts: ``(N,)`` int64.
        both: also search each target's nearest point (else the second result is ``None``).
    Returns:
        ``to_target`` ``(N, M)`` int64: each point's nearest real target (0 where the image has none),
        and ``to_point`` ``(N, K)`` int64: each real target's nearest point (0 on the padding).
    """
    n, m = points.shape[:2]
    k = targets.shape[1]
    to_target = points.new_zeros(n, m, dtype=torch.long)
    to_point = points.new_zeros(n, k, dtype=torch.long) if both else None
    if not (n and m and k):
        return to_target, to_point
    with torch.no_grad():
        p, q = points.detach(), targets.detach().to(points.dtype)
        valid = torch.arange(k, device=p.device) < counts.to(p.device).unsqueeze(1)  # (N, K)
        q_sq = q.square().sum(-1).masked_fill_(~valid, float("inf")).unsqueeze(1)  # (N, 1, K); padding never wins
        to_target = torch.baddbmm(q_sq, p, q.transpose(1, 2), alpha=-2).min(2).indices
        to_target.masked_fill_((counts == 0).to(p.device).unsqueeze(1), 0)
        if both:
            to_point = torch.baddbmm(p.square().sum(-1).unsqueeze(1), q, p.transpose(1, 2), alpha=-2).min(2).indices
            to_point.masked_fill_(~valid, 0)
    return to_target, to_point


__all__ = ["nearest_indices"]
