"""The ops that issue 33 rewrote for speed, as they were before it (the reference formulas the
rewrites are held to: values and gradients equal up to rounding; near-ties of a nearest-neighbour
search may pick another index at the same distance)."""
from __future__ import annotations

import torch

from cerberus_core.model.heads import KeypointMaps, TranslationHead


def reference_keypoint_maps(head: TranslationHead, features: torch.Tensor, size: tuple[int, int]):
    """The translation head before issue 33: logits and depth up-sampled with
    ``interpolate(mode="bilinear")``, the expected depth summed on the pixel grid. Returns
    ``(prob, depth_map, uv, depth)``."""
    from kornia.geometry.subpix import spatial_expectation2d

    from cerberus_core.render.camera import pixel_centres

    h, w = features.shape[-2:]
    xs, py = pixel_centres(h, w, features.dtype, features.device)
    gy, gx = torch.meshgrid(0.0 - py, xs, indexing="ij")
    coords = torch.stack([gx, gy, gx.square(), gy.square()], -1)
    logits = head.logits(features) + head.coords(coords).permute(2, 0, 1).unsqueeze(0)
    up = {"size": size, "mode": "bilinear", "align_corners": False}
    logits = torch.nn.functional.interpolate(logits, **up)
    depth_map = torch.nn.functional.interpolate(head.depth(features), **up) + head.depth_offset
    b, n = logits.shape[:2]
    prob = torch.softmax(logits.reshape(b, n, -1), -1).view_as(logits)
    uv = spatial_expectation2d(prob, normalized_coordinates=False) + 0.5
    return prob, depth_map, uv, (prob * depth_map).sum(dim=(-2, -1))


class ReferenceTranslationHead(TranslationHead):
    """A :class:`TranslationHead` computing :func:`reference_keypoint_maps` (same parameters)."""

    def forward(self, features: torch.Tensor, size: tuple[int, int], latent: torch.Tensor | None = None) -> KeypointMaps:
        return KeypointMaps(*reference_keypoint_maps(self, features, size))  # the paper's head: no body depth


def loop_search(points, targets, counts, both=True):
    """The pulls' nearest-neighbour search before issue 33: one ``cdist`` table per image, scanned
    both ways (the contract of :func:`cerberus_core.render.nearest.nearest_indices`)."""
    n, m = points.shape[:2]
    to_target = torch.zeros(n, m, dtype=torch.long)
    to_point = torch.zeros(n, targets.shape[1], dtype=torch.long)
    with torch.no_grad():
        for i, k in enumerate(counts.tolist()):
            if k:
                table = torch.cdist(points[i].detach(), targets[i, :k].detach())
                to_target[i] = table.min(1).indices
                to_point[i, :k] = table.min(0).indices
    return to_target, (to_point if both else None)


def pull_scene(seed=0, n=6, m=150, size=48):
    """Projected points ``(n, m, 2)`` (some outside the image) and foreground masks ``(n, size, size)``
    of various extents (the first empty), for the nearest-neighbour tests."""
    g = torch.Generator().manual_seed(seed)
    fg = torch.zeros(n, size, size, dtype=torch.bool)
    for i in range(1, n):
        r, c = torch.randint(2, size // 2, (2,), generator=g).tolist()
        fg[i, r:r + 4 + 3 * i, c:c + 20 - 2 * i] = True
    points = torch.rand(n, m, 2, generator=g) * (size + 20) - 10
    return points, fg


def chosen_distances(points, targets, counts, found):
    """The distances of the pairs a search ``found``: ``(N, M)`` point to target (0 in an image with no
    target) and ``(N, K)`` target to point (0 on the padding)."""
    to_target, to_point = found
    valid = torch.arange(targets.shape[1]) < counts[:, None]
    near_t = (points - targets.gather(1, to_target[..., None].expand(-1, -1, 2))).norm(dim=-1)
    near_p = (targets - points.gather(1, to_point[..., None].expand(-1, -1, 2))).norm(dim=-1) * valid
    return near_t * (counts > 0)[:, None], near_p


def pulls_with_each_search(pull, searches, points):
    """``[(value, gradient w.r.t. the points)]`` of ``pull(search, points)`` for each search, each on a
    fresh copy of ``points``: what the nearest-neighbour tests compare between two searches."""
    out = []
    for search in searches:
        p = points.clone().requires_grad_(True)
        value = pull(search, p)
        (grad,) = torch.autograd.grad(value.sum(), p)
        out.append((value.detach(), grad))
    return out
