"""Every loss term of the paper, each a small function (sections 3.2, 4 and 5).

A training example is a *quadruplet* of images of one body: two poses ``a, b`` seen from two
viewpoints ``0, 1``, stacked in the order ``(a0, a1, b0, b1)`` along a
dimension of size 4. Per-image tensors are shaped ``(B, 4, ...)`` here.

The paper's pieces, each a function here: the reconstruction error (eq. 2,
:func:`reconstruction_loss`), pose consistency (eq. 3, :func:`mix_shape_latents`), viewpoint
consistency's renderings (eq. 4, :func:`viewpoint_scenes`, :func:`viewpoint_reconstruction`) and
translations (eqs. 5, 6, :func:`translation_loss`), the total reconstruction (eq. 7), the background
loss and the smoothness loss (section 5, :func:`background_loss`, :func:`smoothness_loss`).

Beyond the paper (weight 0 in its settings): the other functions here, and the ``own`` cross view of
:func:`viewpoint_scenes`.

These are the functions; the objective's terms are declared once, as the weight fields of
:class:`cerberus_core.train.objective.LossConfig` (name, paper weight, how each is computed from the objective's
inputs, symbol, reference; ``terms_table()`` prints them).
"""
from __future__ import annotations

from collections.abc import Callable

import torch

from cerberus_core.errors import ConfigError
from cerberus_core.parts import pose_parts
from cerberus_core.render.api import part_pixel_counts
from cerberus_core.render.nearest import nearest_indices
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

NearestSearch = Callable[..., tuple[Tensor, "Tensor | None"]]
"""The pulls' nearest-neighbour search, ``(points, targets, counts, both) -> (to_target, to_point)``:
:func:`cerberus_core.render.nearest.nearest_indices` or a renderer backend's kernel for it
(:meth:`Renderer.nearest_indices <cerberus_core.render.interface.Renderer.nearest_indices>`)."""

VIEW_PARTNER: tuple[int, ...] = (1, 0, 3, 2)
"""Index of the image of the same pose from the other viewpoint: a0 <-> a1, b0 <-> b1."""


def background_mask(images: Tensor, background: tuple[float, float, float] | list[float],
                    tol: float = 0.5 / 255) -> Tensor:
    """The background mask ``b`` of the background loss: pixels equal to the background colour.

    Args:
        images: ``(..., 3, H, W)`` in [0, 1] (as the datasets return them).
        background: the dataset's ``scene.background``.
        tol: a pixel is background when every channel is within this of the colour
            (``losses.background_tolerance`` in training).
    Returns:
        ``(..., 1, H, W)`` float32, 1 on background. With the default scene every body pixel is at
        most 0.8 bright, so the mask is exact.
    """
    bg = torch.as_tensor(background, dtype=images.dtype, device=images.device).view(3, 1, 1)
    return ((images - bg).abs() <= tol).all(dim=-3, keepdim=True).to(torch.float32)


def reconstruction_loss(rendered: Tensor, target: Tensor) -> Tensor:
    """Equation 2: squared RGB error per pixel, averaged over the pixel grid ``G``.

    Args:
        rendered, target: ``(..., 3, H, W)`` images.
    Returns:
        ``(...)`` one loss per image (sum over channels, mean over pixels).
    """
    check_shapes("reconstruction_loss", rendered=(rendered, "... 3 H W"), target=(target, "... 3 H W"))
    return (rendered - target).square().sum(dim=-3).mean(dim=(-2, -1))


def mix_shape_latents(latents: Tensor, generator: torch.Generator | None = None) -> tuple[Tensor, Tensor]:
    """Equation 3: draw every element of the shape latent from one of the quadruplet's four latents.

    Args:
        latents: ``(B, 4, S)`` the shape latents ``S^a0, S^a1, S^b0, S^b1``.
        generator: random source for ``Z`` (a CPU generator; uniform over the four images).
    Returns:
        ``mixed`` ``(B, S)`` with ``mixed[b, s] = latents[b, Z[b, s], s]``, and ``Z`` ``(B, S)`` int64.
    """
    check_shapes("mix_shape_latents", latents=(latents, "B 4 S"))
    bsz, _, size = latents.shape
    choice = torch.randint(0, 4, (bsz, size), generator=generator).to(latents.device)
    mixed = latents.gather(1, choice.unsqueeze(1)).squeeze(1)
    return mixed, choice


def keep_own_elements(mixed: Tensor, own: Tensor, mixing: float, generator: torch.Generator | None = None) -> Tensor:
    """Partial pose consistency (beyond the paper): each element is ``mixed``'s with probability ``mixing``, else
    ``own``'s, drawn independently per image and element. ``mixing`` 1 is equation 3, 0 Free Cerberus.

    Args:
        mixed: ``(B, 4, S)`` the quadruplet's mixed latent for each of its four images (:func:`mix_shape_latents`).
        own: ``(B, 4, S)`` each image's own shape latent.
        mixing: probability in ``[0, 1]``.
        generator: random source (a CPU generator).
    Returns:
        ``(B, 4, S)``; gradients reach ``mixed`` where it was taken and ``own`` elsewhere.

    Example:
        >>> own = torch.zeros(1, 4, 1000)
        >>> out = keep_own_elements(torch.ones(1, 4, 1000), own, 0.25, torch.Generator().manual_seed(0))
        >>> 0.2 < out.mean().item() < 0.3
        True
    """
    check_shapes("keep_own_elements", mixed=(mixed, "B 4 S"), own=(own, "B 4 S"))
    if not 0 <= mixing <= 1:
        raise ConfigError.about("losses.pose_mixing", mixing, "keep_own_elements: mixing must be a probability in "
                                "[0, 1]", "`losses.pose_mixing=1` (equation 3)")
    take = torch.rand(own.shape, generator=generator).to(own.device) < mixing
    return torch.where(take, mixed, own)


def viewpoint_scenes(local_vertices: Tensor, rotations: Tensor, translations: Tensor,
                     cross_view: str = "partner") -> tuple[Tensor, Tensor]:
    """The posed meshes rendered for equation 4 (all in world coordinates).

    Image ``x`` of the quadruplet contributes its rotated mesh ``R^x V^x`` twice: translated by its
    own translation (rendered from its own viewpoint, compared with image ``x``) and, for the cross
    view (rendered from ``x'``'s viewpoint, compared with image ``x'``, :data:`VIEW_PARTNER`):

    * ``partner`` (the paper): translated by the translation predicted from ``x'``:
      ``a0 -> a1`` is ``R^a0 V^a0 + T^a1``;
    * ``own`` (beyond the paper): translated by its own translation, i.e. image ``x``'s whole 3D
      model seen from ``x'``: ``R^a0 V^a0 + T^a0``, so every part's depth is checked by ``x'``.

    Args:
        local_vertices: ``(B, 4, N, V, 3)`` deformed parts (local frames).
        rotations: ``(B, 4, N, 3, 3)`` world rotations.
        translations: ``(B, 4, N, 3)`` world translations.
        cross_view: ``partner`` or ``own`` (``losses.cross_view`` of the training config).
    Returns:
        ``own`` and ``cross``, both ``(B, 4, N, V, 3)``; ``cross[:, x]`` is to be rendered with the
        camera of image ``VIEW_PARTNER[x]`` and compared with that image.
    """
    own = pose_parts(local_vertices, rotations, translations)
    if cross_view == "own":
        return own, own
    if cross_view != "partner":
        raise ConfigError.about("losses.cross_view", cross_view, "viewpoint_scenes: must be 'partner' or 'own'",
                                "`losses.cross_view=\"partner\"` (the paper's)")
    cross = pose_parts(local_vertices, rotations, translations[:, list(VIEW_PARTNER)])
    return own, cross


def viewpoint_reconstruction(own: Tensor, cross: Tensor | None) -> Tensor:
    """Equations 4 and 7: per-image reconstruction loss averaged over the quadruplet.

    Args:
        own: ``(B, 4)`` ``L^{x->x}`` for ``x`` in ``(a0, a1, b0, b1)``.
        cross: ``(B, 4)`` ``L^{x->x'}`` (the image-``x`` mesh rendered from the partner viewpoint),
            or ``None`` without viewpoint consistency (then ``L^x = L^{x->x}``).
    Returns:
        ``(B,)`` ``L_r' = 1/4 sum_x L^x`` with ``L^x = (L^{x->x} + L^{x->x'}) / 2``.
    """
    per_image = own if cross is None else 0.5 * (own + cross)
    return per_image.mean(dim=1)


def translation_loss(translations: Tensor) -> Tensor:
    """Equations 5 and 6: disagreement of the world translations predicted from the two viewpoints.

    Args:
        translations: ``(B, 4, N, 3)`` world-space part translations of ``(a0, a1, b0, b1)``.
    Returns:
        ``(B,)`` ``(L_t^a + L_t^b) / 2`` with ``L_t^a = 1/N sum_i ||T_i^a0 - T_i^a1||^2``.
    """
    check_shapes("translation_loss", translations=(translations, "B 4 N 3"))
    pose_a = (translations[:, 0] - translations[:, 1]).square().sum(-1).mean(-1)
    pose_b = (translations[:, 2] - translations[:, 3]).square().sum(-1).mean(-1)
    return 0.5 * (pose_a + pose_b)


def body_translation_loss(translations: Tensor) -> Tensor:
    """Disagreement of where the whole body stands, as the two viewpoints of a pose predict it (beyond the paper).

    The body's translation is the mean of its parts' world translations, so the term does not care which part
    is which: a part that takes the image's left limb in one view and the right limb in the other (the
    views' part assignments differ) costs nothing here, where equations 5 and 6 (:func:`translation_loss`)
    charge it in full. What is left is the whole body's position, and in practice its depth: one shift per
    image along the camera's view is most of what a triangulation of the views' keypoints corrects
    (``experiments/depth/depth_oracle.py``, "whole body"). Equation 5 holds this component once
    (``1/N sum_i ||d_i||^2 = ||mean_i d_i||^2 + 1/N sum_i ||d_i - mean d||^2``); ``losses.body_translation: w``
    weighs it ``1 + w`` times.

    Args:
        translations: ``(B, 4, N, 3)`` world-space part translations of ``(a0, a1, b0, b1)``.
    Returns:
        ``(B,)`` ``(||mean_i T_i^a0 - mean_i T_i^a1||^2 + ||mean_i T_i^b0 - mean_i T_i^b1||^2) / 2`` (world units
        squared).

    Example:
        >>> t = torch.zeros(1, 4, 2, 3); t[0, 1, 0, 0] = 1.0; t[0, 1, 1, 0] = -1.0  # a1's parts swapped sides
        >>> body_translation_loss(t).tolist(), translation_loss(t).tolist()
        ([0.0], [0.5])
    """
    check_shapes("body_translation_loss", translations=(translations, "B 4 N 3"))
    body = translations.mean(dim=2)  # (B, 4, 3)
    return 0.5 * ((body[:, 0] - body[:, 1]).square().sum(-1) + (body[:, 2] - body[:, 3]).square().sum(-1))


def pose_consensus(translations: Tensor) -> Tensor:
    """Each part's translation as the pose's two viewpoints agree on it (beyond the paper).

    ``T~_i^x = (T_i^x + T_i^x') / 2`` for every image ``x`` and its viewpoint partner ``x'``
    (:data:`VIEW_PARTNER`): one 3D point per part and pose. Projected into both cameras and pulled onto
    both images' foregrounds (``losses.consensus_coverage``), it makes the keypoint k-means of
    :func:`silhouette_coverage` a k-means over the pose's visual hull: a part can no longer take the
    image's left limb in one view and the other limb in the other, since the pulls of the two views on
    one point cancel unless both land on the same body limb.

    Args:
        translations: ``(B, 4, N, 3)`` world-space part translations of ``(a0, a1, b0, b1)``.
    Returns:
        ``(B, 4, N, 3)``; rows ``x`` and ``x'`` are equal.

    Example:
        >>> t = torch.zeros(1, 4, 1, 3); t[0, 1, 0, 0] = 2.0
        >>> pose_consensus(t)[0, :, 0, 0].tolist()
        [1.0, 1.0, 0.0, 0.0]
    """
    check_shapes("pose_consensus", translations=(translations, "B 4 N 3"))
    return 0.5 * (translations + translations[:, list(VIEW_PARTNER)])


def part_tips(local_vertices: Tensor, rotations: Tensor, translations: Tensor) -> Tensor:
    """Each part's tip, one world point a part and image (beyond the paper): the part's vertex farthest from its
    local origin (the point its translation puts on its keypoint), the same template vertex in both views of a pose.

    The vertex is chosen per pose and part by the sum of its two views' distances, without gradient, and its local
    position is detached: the tip moves only as the part turns (``rotations``) and moves (``translations``), so a
    pull on it (``losses.consensus_tips``) swings a part along a limb instead of stretching a vertex toward it.
    Where the idea comes from: parts as bones between joints (LASSIE, Watch It Move), whose far end is placed as
    well as their centre; read, not copied.

    Args:
        local_vertices: ``(B, 4, N, V, 3)`` the parts' local vertices of ``(a0, a1, b0, b1)`` (world units).
        rotations: ``(B, 4, N, 3, 3)`` local→world rotations.
        translations: ``(B, 4, N, 3)`` world translations.
    Returns:
        ``(B, 4, N, 3)`` world points.

    Example: a part whose vertex 1 reaches farthest, turned a quarter about z, has its tip at R v_1 + T:
        >>> v = torch.tensor([[0.1, 0.0, 0.0], [0.0, 0.3, 0.0]]).expand(1, 4, 1, 2, 3)
        >>> r = torch.tensor([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).expand(1, 4, 1, 3, 3)
        >>> [round(c, 4) for c in part_tips(v, r, torch.ones(1, 4, 1, 3))[0, 0, 0].tolist()]
        [0.7, 1.0, 1.0]
    """
    check_shapes("part_tips", local_vertices=(local_vertices, "B 4 N V 3"), rotations=(rotations, "B 4 N 3 3"),
                 translations=(translations, "B 4 N 3"))
    local = local_vertices.detach()
    reach = local.norm(dim=-1)  # (B, 4, N, V)
    tip = (reach + reach[:, list(VIEW_PARTNER)]).argmax(-1)  # (B, 4, N): one vertex a pose and part
    point = local.gather(-2, tip[..., None, None].expand(*tip.shape, 1, 3)).squeeze(-2)  # (B, 4, N, 3)
    return pose_parts(point.unsqueeze(-2), rotations, translations).squeeze(-2)


def part_separation(translations: Tensor, min_distance: float = 0.1) -> Tensor:
    """KeypointNet's separation term in 3D (beyond the paper): parts closer than ``min_distance`` push apart.

    ``L = 1/(N (N - 1)) sum_{i != j} max(0, delta^2 - ||T_i - T_j||^2)`` with ``delta = min_distance``
    (Suwajanakorn et al., eq. 6; they use 0.05 on unit-size objects). The bodies here are about 1 world
    unit tall and a part starts 0.12 in radius, so 0.1 separates parts stacked on one centre (the
    shipped model's translations lie 0.01-0.04 apart) and leaves neighbours along a limb alone.

    Args:
        translations: ``(..., N, 3)`` part translations (world units).
        min_distance: ``delta`` (world units).
    Returns:
        ``(...)`` in ``[0, delta^2]``; 0 with a single part.

    Example:
        >>> t = torch.tensor([[0.0, 0.0, 0.0], [0.05, 0.0, 0.0], [1.0, 0.0, 0.0]])
        >>> round(float(part_separation(t)), 6)  # one close pair: 2 (0.01 - 0.0025) / 6
        0.0025
    """
    n = translations.shape[-2]
    if n < 2:
        return translations.new_zeros(translations.shape[:-2])
    gap = (translations.unsqueeze(-2) - translations.unsqueeze(-3)).square().sum(-1)  # (..., N, N)
    push = (min_distance**2 - gap).clamp(min=0)
    others = 1 - torch.eye(n, dtype=translations.dtype, device=translations.device)
    return (push * others).sum(dim=(-2, -1)) / (n * (n - 1))


RELOCATION_SHARE = 0.02
"""The share of a pose's foreground below which (or at which) :func:`relocation_pull` calls a part spare: the
``spare_coverage`` of ``cerberus eval`` (:data:`cerberus_core.eval.allocation.SPARE_COVERAGE`), read here off the
own-view render's front-part map."""


def relocation_pull(points: Tensor, part_id: Tensor, foreground: Tensor, keypoints: Tensor,
                    spare_share: float = RELOCATION_SHARE) -> Tensor:
    """Relocation of spare parts (beyond the paper): a part that adds almost nothing is pulled to a body end.

    **Spare.** In image ``x`` part ``i`` alone holds the foreground pixels where it is the front part
    (``part_id == i``: the rendered front surface, so a proxy of its unique coverage that counts a part
    hidden behind another as holding nothing there). The decision is made per pose: part ``i`` is spare when
    ``(c_i^x + c_i^x') / (F^x + F^x') <= spare_share``, ``c`` its front pixels on the foreground and ``F`` the
    foreground's pixels, over the image and its viewpoint partner ``x'`` (:data:`VIEW_PARTNER`). Per image,
    a part hidden behind the trunk in one view would count as spare there while it holds an arm in the other
    (and either view alone saying "spare" would tear it off that arm); over the pose, the share is
    ``cerberus eval``'s mean over views, and both views pull the same parts.

    **Targets.** In each image, among the foreground pixels no placed part covers (``part_id`` -1 or a spare
    part: a spare part that has reached a hand but holds too little of the pose keeps the hand as its target
    instead of being sent on; all the foreground where placed parts cover it all), farthest-point sampling from
    the keypoints of the parts that are *not* spare picks one target per spare part: the first is the pixel
    centre farthest from its nearest non-spare keypoint (a hand, a foot, the head's top: the body ends the placed
    parts miss), each next one the farthest from those keypoints and the targets already picked, so several spare
    parts go to several ends. Each spare
    part takes a target by greedy matching of its (detached) pulled point to the nearest free target, so the
    two views of a pose, which pull one agreed point, hand it the body end it is already nearest to. The
    targets are computed without gradient.

    **Loss.** ``L^x = 1/|S| sum_{i in S} ||p_i^x - t_i^x||^2 / H^2`` over the spare parts ``S``, ``p_i^x`` the
    pulled point (in training the pose's agreed translation, :func:`pose_consensus`, projected into image
    ``x``, so the two views' pulls add up only when both targets are the same body end), ``H`` the image
    height (as :func:`reprojection_loss`). 0 for an image with no spare part, no foreground, or no part that
    is not spare (nothing to keep away from; the chamfer and hidden-part pulls bring such parts back).

    Args:
        points: ``(B, 4, N, 2)`` pixels: the point pulled for each part in each image (gradient flows here).
        part_id: ``(B, 4, H, W)`` int: the front part of each pixel of each image's own-view render, -1 where none.
        foreground: ``(B, 4, 1, H, W)`` or ``(B, 4, H, W)``, 1 on the input's body.
        keypoints: ``(B, 4, N, 2)`` pixels: where each part sits in each image (detached; the targets keep away
            from the non-spare ones).
        spare_share: the pose's foreground share at or below which a part is spare.
    Returns:
        ``(B, 4)`` in image heights squared.

    Example:
        >>> fg = torch.zeros(1, 4, 8, 8); fg[..., 4, :] = 1  # a bar along row 4
        >>> part_id = torch.full((1, 4, 8, 8), -1); part_id[..., 4, :6] = 0  # part 0 covers 6 of its 8 pixels
        >>> kp = torch.tensor([3.5, 4.5]).expand(1, 4, 2, 2)  # both keypoints at u = 3.5; part 1 covers nothing
        >>> relocation_pull(kp, part_id, fg, kp)  # part 1 to the uncovered end (7.5, 4.5): 4 px of 8, squared
        tensor([[0.2500, 0.2500, 0.2500, 0.2500]])
    """
    fg = foreground.reshape(*foreground.shape[:2], *foreground.shape[-2:]) > 0.5
    check_shapes("relocation_pull", points=(points, "B 4 N 2"), part_id=(part_id, "B 4 H W"),
                 foreground=(fg, "B 4 H W"), keypoints=(keypoints, "B 4 N 2"))
    bsz, _, n, _ = points.shape
    height, width = fg.shape[-2:]
    partner = list(VIEW_PARTNER)
    with torch.no_grad():
        alone = part_pixel_counts(torch.where(fg, part_id, -1).flatten(0, 1), n).view(bsz, 4, n).float()
        area = fg.flatten(2).sum(-1).float()  # (B, 4)
        pose_area = area + area[:, partner]
        share = (alone + alone[:, partner]) / pose_area.clamp(min=1).unsqueeze(-1)
        spare = ((share <= spare_share) & (pose_area > 0).unsqueeze(-1)).flatten(0, 1)  # (4B, N)
        spare &= (~spare).any(-1, keepdim=True) & fg.flatten(0, 1).flatten(1).any(-1, keepdim=True)
        front = part_id.flatten(0, 1).flatten(1)  # (4B, HW)
        placed = (front >= 0) & ~spare.gather(1, front.clamp(min=0))  # held by a part that is not spare
        free = fg.flatten(0, 1).flatten(1) & ~placed
        free = torch.where(free.any(-1, keepdim=True), free, fg.flatten(0, 1).flatten(1))
        rows, cols = torch.meshgrid(torch.arange(height, device=fg.device), torch.arange(width, device=fg.device),
                                    indexing="ij")
        centres = torch.stack([cols, rows], -1).flatten(0, 1).to(points.dtype) + 0.5  # (HW, 2)
        anchors = keypoints.detach().flatten(0, 1).to(points.dtype)  # (4B, N, 2)
        gap = (centres[:, None] - anchors[:, None]).square().sum(-1)  # (4B, HW, N)
        gap = gap.masked_fill(spare.unsqueeze(1), float("inf")).amin(-1)  # to the nearest non-spare keypoint
        gap = gap.masked_fill(~free, -1.0)  # only free pixels are picked
        wanted = spare.sum(-1)  # (4B,)
        slots = int(wanted.max()) if wanted.numel() else 0
        targets = points.new_zeros(4 * bsz, max(slots, 1), 2)
        for s in range(slots):  # farthest-point sampling, all images at once
            pick = centres[gap.argmax(-1)]  # (4B, 2)
            targets[:, s] = pick
            gap = torch.minimum(gap, (centres - pick[:, None]).square().sum(-1))
        pulled = points.detach().flatten(0, 1)
        cost = (pulled[:, :, None] - targets[:, None]).square().sum(-1)  # (4B, N, slots)
        unused = torch.arange(targets.shape[1], device=fg.device) >= wanted.unsqueeze(-1)  # (4B, slots)
        cost = cost.masked_fill(~spare.unsqueeze(-1) | unused.unsqueeze(1), float("inf"))
        assigned = torch.zeros(4 * bsz, n, dtype=torch.long, device=fg.device)
        image = torch.arange(4 * bsz, device=fg.device)
        for _ in range(slots):  # greedy matching: the closest free (part, target) pair first
            best, flat = cost.flatten(1).min(-1)
            ok = torch.isfinite(best)
            part, slot = flat // cost.shape[-1], flat % cost.shape[-1]
            assigned[image[ok], part[ok]] = slot[ok]
            cost[image[ok], part[ok]] = float("inf")
            cost[image[ok], :, slot[ok]] = float("inf")
    target = targets.gather(1, assigned.unsqueeze(-1).expand(-1, -1, 2))  # (4B, N, 2)
    dist = ((points.flatten(0, 1) - target) / height).square().sum(-1)  # (4B, N)
    weight = spare.to(points.dtype)
    return ((dist * weight).sum(-1) / weight.sum(-1).clamp(min=1)).view(bsz, 4)


def rotation_loss(rotations: Tensor) -> Tensor:
    """Equation 6 for rotations (beyond the paper): disagreement of the world rotations predicted from
    the two viewpoints of one pose.

    Args:
        rotations: ``(B, 4, N, 3, 3)`` world-space part rotations of ``(a0, a1, b0, b1)``.
    Returns:
        ``(B,)`` ``(L_R^a + L_R^b) / 2`` with ``L_R^a = 1/N sum_i ||R_i^a0 - R_i^a1||_F^2``, in [0, 8]
        (``||R - R'||_F^2 = 4 (1 - cos theta)`` for the angle ``theta`` between them).
    """
    check_shapes("rotation_loss", rotations=(rotations, "B 4 N 3 3"))
    pose_a = (rotations[:, 0] - rotations[:, 1]).square().sum(dim=(-2, -1)).mean(-1)
    pose_b = (rotations[:, 2] - rotations[:, 3]).square().sum(dim=(-2, -1)).mean(-1)
    return 0.5 * (pose_a + pose_b)


def triangulated_body_depth_loss(depth: Tensor, target: Tensor, weight: Tensor) -> Tensor:
    """Each view's whole-body depth against where the pose's two views triangulate it (beyond the paper).

    ``target`` holds, for every part, the depth in each view of the point its rays from the two viewpoints of
    the pose meet at (:func:`~cerberus_core.render.camera.triangulate` of the two keypoints' rays, detached by
    the caller): what the depth oracle of ``experiments/depth/depth_oracle.py`` moves each part to. Only the
    mean over the parts is compared, one depth per image: where the whole body stands along the view, which is
    most of that oracle's gain for every model, while the parts' depths relative to each other, which the
    triangulation does not improve for a pose-consistent model, are left to the image terms. The target is
    detached: the term asks each view's depth to move, not the two views' keypoint rays to meet.

    Args:
        depth: ``(B, 4, N)`` each image's predicted part depths (world units).
        target: ``(B, 4, N)`` the triangulated points' depths in the same views (no gradient).
        weight: ``(B, 4)`` how well the two rays fix a depth, in ``[0, 1]``: the mean over the parts of
            ``sin^2`` of the angle between the two views' rays (0 for parallel rays: views from the same or the
            opposite side).
    Returns:
        ``(B,)`` the mean over the quadruplet's four images of ``weight · (mean_i d_i - mean_i t_i)^2``.

    Example:
        >>> d = torch.full((1, 4, 3), 2.0); t = d.clone(); t[0, 0] += 0.1  # image a0's body 0.1 too near
        >>> round(triangulated_body_depth_loss(d, t, torch.ones(1, 4)).item(), 6)
        0.0025
    """
    check_shapes("triangulated_body_depth_loss", depth=(depth, "B 4 N"), target=(target, "B 4 N"),
                 weight=(weight, "B 4"))
    return (weight * (depth.mean(-1) - target.mean(-1)).square()).mean(-1)


def reprojection_loss(projected: Tensor, keypoints: Tensor, height: int) -> Tensor:
    """Depth checked in the partner's image: a reprojection form of equation 5 (beyond the paper).

    Part ``i``'s world translation predicted from image ``x``, projected into the camera of its
    viewpoint partner ``x'``, should land on the keypoint ``k_i^{x'}`` that ``x'`` predicts for it.
    Only ``x``'s side learns (the keypoint is detached), and a translation lies on its own camera
    ray through its own keypoint, so the error it corrects is mostly ``x``'s depth: unlike
    :func:`translation_loss` it does not drag the partner's keypoint off its image.

    Args:
        projected: ``(B, 4, N, 2)`` pixels: ``projected[:, x, i]`` is ``pi_{x'}(T_i^x)``.
        keypoints: ``(B, 4, N, 2)`` pixels: ``keypoints[:, x, i]`` is ``k_i^{x'}`` (detached here).
        height: the image height in pixels; distances are in image heights.
    Returns:
        ``(B,)`` ``1/4 sum_x 1/N sum_i ||pi_{x'}(T_i^x) - k_i^{x'}||^2 / H^2``.
    """
    check_shapes("reprojection_loss", projected=(projected, "B 4 N 2"), keypoints=(keypoints, "B 4 N 2"))
    return ((projected - keypoints.detach()) / height).square().sum(-1).mean(dim=(-2, -1))


def background_loss(prob: Tensor, mask: Tensor) -> Tensor:
    """``L_b = 1/N sum_k sum_xy p^k_xy b_xy``: probability mass the parts put on the background.

    Args:
        prob: ``(..., N, H, W)`` probability maps (each sums to 1).
        mask: ``(..., 1, H, W)`` background mask ``b`` of the input image
            (:func:`background_mask`).
    Returns:
        ``(...)`` in [0, 1].
    """
    return (prob * mask).sum(dim=(-2, -1)).mean(dim=-1)


def dihedral_cosines(vertices: Tensor, dihedral: Tensor, eps: float = 1e-6) -> Tensor:
    """Cosine of the angle between the two faces meeting at each interior edge.

    Following Kato et al. (neural_renderer / mesh_reconstruction): for an edge ``a-b`` shared by the
    faces ``(a, b, c)`` and ``(a, b, d)``, the angle ``theta`` is the one between the vectors from the
    edge line to ``c`` and to ``d``, each perpendicular to the edge. A flat pair has ``theta = pi``
    (``cos = -1``); a pair folded shut has ``theta = 0`` (``cos = 1``).

    Args:
        vertices: ``(..., V, 3)``.
        dihedral: ``(E, 4)`` int64 ``(a, b, c, d)`` per edge (``MeshTemplate.dihedral``).
        eps: keeps the normalisations finite on degenerate faces.
    Returns:
        ``(..., E)`` ``cos theta``.
    """
    a, b, c, d = (vertices[..., dihedral[:, i], :] for i in range(4))
    edge = torch.nn.functional.normalize(b - a, dim=-1, eps=eps)

    def perpendicular(p: Tensor) -> Tensor:
        v = p - a
        return v - (v * edge).sum(-1, keepdim=True) * edge

    pc, pd = perpendicular(c), perpendicular(d)
    num = (pc * pd).sum(-1)
    den = pc.norm(dim=-1) * pd.norm(dim=-1) + eps
    return num / den


def smoothness_loss(vertices: Tensor, dihedral: Tensor, eps: float = 1e-6) -> Tensor:
    """``L_s = sum_edges (cos theta + 1)^2`` (Kato et al.): 0 for a flat surface, 4 per folded edge.

    Args:
        vertices: ``(..., P, V, 3)`` ``P`` part meshes sharing one template (``P`` may be 1).
        dihedral: ``(E, 4)`` the template's dihedral quadruples.
    Returns:
        ``(...)`` the sum over every part's edges.
    """
    cos = dihedral_cosines(vertices, dihedral, eps)
    return (cos + 1).square().sum(dim=(-2, -1))


# ------------------------------------------------------------------ beyond the paper (off by default)
def silhouette_loss(alpha: Tensor, foreground: Tensor) -> Tensor:
    """Squared error between the rendered coverage and the input's foreground mask.

    Needs a renderer with visibility gradients (``render_parts(..., antialias=True)``): with the
    paper's renderer ``alpha`` is a hard 0/1 mask without gradient and this term is a constant.

    Args:
        alpha: ``(..., 1, H, W)`` rendered coverage in [0, 1].
        foreground: ``(..., 1, H, W)`` 1 on the input's body pixels (``1 - b``).
    Returns:
        ``(...)`` mean over pixels.
    """
    check_shapes("silhouette_loss", alpha=(alpha, "... 1 H W"), foreground=(foreground, "... 1 H W"))
    return (alpha - foreground).square().mean(dim=(-3, -2, -1))


def mask_pixel_centres(mask: Tensor) -> tuple[Tensor, Tensor]:
    """The centres of each image's mask pixels, padded to one length.

    Args:
        mask: ``(N, H, W)`` bool.
    Returns:
        ``centres`` ``(N, K, 2)`` as ``(u, v)`` pixels (``col + 0.5, row + 0.5``), ``K`` the largest
        count of any image (at least 1), in row-major order per image; and ``valid`` ``(N, K)`` bool,
        False on the padding (whose centres are 0).
    """
    n = mask.shape[0]
    img, rows, cols = torch.nonzero(mask, as_tuple=True)  # sorted by image, then row-major
    counts = torch.bincount(img, minlength=n)
    k = max(1, int(counts.max())) if n else 1
    slot = torch.arange(img.numel(), device=mask.device) - (torch.cumsum(counts, 0) - counts)[img]
    centres = torch.zeros(n, k, 2, device=mask.device)
    centres[img, slot] = torch.stack([cols, rows], -1).float() + 0.5
    valid = torch.zeros(n, k, dtype=torch.bool, device=mask.device)
    valid[img, slot] = True
    return centres, valid


def _pair_distance(points: Tensor, targets: Tensor, index: Tensor) -> Tensor:
    """``|points[n, i] - targets[n, index[n, i]]|`` ``(N, I)``: differentiable in both, exactly the
    distance to the chosen target (the gradient of a minimum reaches only its argument)."""
    chosen = targets.gather(1, index.unsqueeze(-1).expand(*index.shape, targets.shape[-1]))
    return (points - chosen).norm(dim=-1)


def silhouette_chamfer(points: Tensor, foreground: Tensor, max_points: int = 512,
                       search: NearestSearch = nearest_indices) -> Tensor:
    """Long-range pull of the parts onto the input's silhouette, in the image plane.

    A symmetric 2D chamfer distance between the projected part vertices and the foreground pixel
    centres: every foreground pixel pulls its nearest vertex (so limbs nobody covers attract a part),
    and every vertex is pulled to its nearest foreground pixel (so parts over the background, or
    hidden ones wandering outside, come back). Unlike the rendering loss it reaches every vertex,
    visible or not, at any distance. Distances are in units of the image height, not squared, so the
    pull has the same strength near and far.

    The nearest neighbours are searched without gradient (``search``: :data:`NearestSearch`), and the
    distances are then recomputed, with gradient, for the chosen pairs only, batched over images (the gradient of a minimum reaches only its argument, so the value and the
    gradient are those of ``min(cdist)``, up to rounding).

    Args:
        points: ``(N, M, 2)`` projected vertices in pixels (:meth:`Camera.project`), all parts.
        foreground: ``(N, 1, H, W)`` or ``(N, H, W)`` foreground mask (1 on the body).
        max_points: vertices used per image (evenly strided), bounding the cost.
        search: the nearest-neighbour search (training passes its renderer backend's kernel).
    Returns:
        ``(N,)``; 0 for an image with no foreground pixel.
    """
    fg, pts, centres, valid = _points_and_pixels("silhouette_chamfer", points, foreground, max_points)
    count = valid.sum(1)
    to_pixel, to_vertex = search(pts, centres, count, True)
    pixel_side = (_pair_distance(centres, pts, to_vertex) * valid).sum(1) / count.clamp(min=1)
    vertex_side = _pair_distance(pts, centres, to_pixel).mean(1)
    return torch.where(count > 0, (pixel_side + vertex_side) / fg.shape[1], pts.new_zeros(()))


def _points_and_pixels(what: str, points: Tensor, foreground: Tensor,
                       max_points: int) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """The common start of the image-plane pulls: ``fg`` ``(N, H, W)`` bool, the points evenly strided
    to at most ``max_points`` per image ``(N, M', 2)``, and the foreground pixel centres ``(N, K, 2)``
    (in the points' dtype) with their ``valid`` flags ``(N, K)`` (:func:`mask_pixel_centres`)."""
    fg = foreground.reshape(foreground.shape[0], *foreground.shape[-2:]) > 0.5
    check_shapes(what, points=(points, "N M 2"), foreground=(fg, "N H W"))
    stride = max(1, -(-points.shape[1] // max_points))
    pts = points[:, ::stride]
    centres, valid = mask_pixel_centres(fg)
    return fg, pts, centres.to(pts.dtype), valid


def thinness_weights(foreground: Tensor) -> Tensor:
    """Per-pixel weights ``1 / d^2`` of a foreground mask, ``d`` the pixel's depth inside it.

    ``d`` is the number of 3x3 erosions the pixel survives (its chessboard distance, in pixels, to the
    nearest background pixel or the image border; 1 on the silhouette's edge). A cross-section ``w``
    pixels wide weighs ``2 (1 + 1/4 + ... + 1/(w/2)^2)``: 2 for a limb two pixels wide, 2.9 for a trunk
    ten wide, never more than ``pi^2 / 3 = 3.3`` (unweighted: 2 and 10), so per unit length a thin
    limb counts about as much as the trunk. Computed without gradient (the mask is data).

    Args:
        foreground: ``(N, 1, H, W)`` or ``(N, H, W)``, 1 on the body.
    Returns:
        ``(N, H, W)`` float32: ``1 / d^2`` on the foreground, 0 elsewhere.
    """
    fg = (foreground.reshape(-1, 1, *foreground.shape[-2:]) > 0.5).float()
    depth = torch.zeros_like(fg)
    with torch.no_grad():
        left = fg
        while bool(left.any()):  # at most half the image's smaller side
            depth += left
            padded = torch.nn.functional.pad(left, (1, 1, 1, 1), value=0.0)  # outside the image is background
            left = -torch.nn.functional.max_pool2d(-padded, 3, stride=1)  # erosion
    return torch.where(depth > 0, depth.clamp(min=1) ** -2, depth)[:, 0]


def silhouette_coverage(points: Tensor, foreground: Tensor, max_points: int = 512,
                        search: NearestSearch = nearest_indices) -> Tensor:
    """Coverage weighted toward thin structures: every foreground pixel pulls its nearest point.

    ``L = sum_p w_p min_j |p - x_j| / sum_p w_p / H`` over the foreground pixel centres ``p`` of the
    input, ``w_p`` their :func:`thinness_weights` (``1 / d^2``), ``x_j`` the points, ``H`` the image
    height. The pixel side of :func:`silhouette_chamfer` with each pixel weighted by how thin the
    structure it lies on is: per unit length, a forearm two pixels wide nobody covers pulls about as
    hard as a trunk ten pixels wide (2 against 2.9, where unweighted it would be 2 against 10).
    With the projected part vertices as points, the pixel pulls the nearest part's nearest vertex; with
    the parts' keypoints (one point per part), it is a weighted k-means of the keypoints over the
    silhouette: parts stacked on the trunk split its pixels and spread out, and an uncovered limb pulls
    the keypoint of the nearest part onto it (moving the part rather than stretching it). The nearest
    points are searched without gradient (``search``: :data:`NearestSearch`), the distances recomputed
    with it.

    Args:
        points: ``(N, M, 2)`` in pixels: projected vertices (:meth:`Camera.project`) or keypoints.
        foreground: ``(N, 1, H, W)`` or ``(N, H, W)`` foreground mask (1 on the body).
        max_points: points used per image (evenly strided), bounding the cost.
        search: the nearest-neighbour search, as in :func:`silhouette_chamfer`.
    Returns:
        ``(N,)`` in image heights; 0 for an image with no foreground pixel.
    """
    fg, pts, centres, valid = _points_and_pixels("silhouette_coverage", points, foreground, max_points)
    count = valid.sum(1)
    _, to_point = search(pts, centres, count, True)
    rows, cols = (centres[..., 1] - 0.5).long(), (centres[..., 0] - 0.5).long()  # padding reads pixel (0, 0)
    weight = thinness_weights(fg).to(pts.dtype)[torch.arange(fg.shape[0], device=fg.device)[:, None], rows, cols]
    weight = weight * valid
    pulled = (_pair_distance(centres, pts, to_point) * weight).sum(1) / weight.sum(1).clamp(min=1e-12)
    return torch.where(count > 0, pulled / fg.shape[1], pts.new_zeros(()))


def hidden_part_pull(points: Tensor, visible: Tensor, uncovered: Tensor,
                     search: NearestSearch = nearest_indices) -> Tensor:
    """Long-range pull of the parts an image does not show toward the foreground no part covers.

    A part wholly hidden in its input view (behind other parts, or off the image) gets no gradient
    from the rendering terms. This term moves it, in the image plane, toward the input's foreground
    pixels that no part covers yet (in practice the limbs the other parts miss), where the
    rendering terms take over. Each of the part's projected vertices is pulled to its nearest such
    pixel; distances are in units of the image height, not squared, as in
    :func:`silhouette_chamfer` (and computed the same way, for the hidden parts only).

    Args:
        points: ``(N, P, V, 2)`` projected vertices in pixels (:meth:`Camera.project`), per part.
        visible: ``(N, P)`` bool, whether the part covers at least one pixel of its input view.
        uncovered: ``(N, 1, H, W)`` or ``(N, H, W)``, 1 on foreground pixels that no part covers.
        search: the nearest-neighbour search, as in :func:`silhouette_chamfer`.
    Returns:
        ``(N,)`` the mean over the image's hidden parts of their mean vertex distance; 0 for an image
        where every part shows or no foreground pixel is uncovered.
    """
    free = uncovered.reshape(uncovered.shape[0], *uncovered.shape[-2:]) > 0.5
    n, height, _ = free.shape
    check_shapes("hidden_part_pull", points=(points, "N P V 2"), visible=(visible, "N P"), uncovered=(free, "N H W"))
    has_free = free.flatten(1).any(1)
    image, part = torch.nonzero(~visible.bool() & has_free[:, None], as_tuple=True)  # the pulled parts
    out = points.new_zeros(n)
    if image.numel() == 0:
        return out
    centres, valid = mask_pixel_centres(free[image])  # (H, K, 2) each pulled part's targets
    centres = centres.to(points.dtype)
    pts = points[image, part]  # (H, V, 2)
    nearest, _ = search(pts, centres, valid.sum(1), False)  # (H, V)
    per_part = _pair_distance(pts, centres, nearest).mean(1)  # (H,)
    hidden = torch.bincount(image, minlength=n).to(points.dtype)
    return out.index_add(0, image, per_part) / hidden.clamp(min=1) / height


def part_overlap(parts: Tensor, eps: float = 1e-6) -> Tensor:
    """How much the parts occupy the same volume, each part taken as the Gaussian of its vertices.

    Part ``j`` is the centre ``mu_j`` and covariance ``C_j`` of its vertices, and its occupancy the bump
    ``g_j(x) = exp(-(x - mu_j)^T C_j^-1 (x - mu_j) / 2)`` (1 at its centre). The share of part ``i``
    inside part ``j`` is ``g_j``'s mean under the Gaussian ``N(mu_i, C_i)``, in closed form
    ``c_ij = sqrt(det C_j / det(C_i + C_j)) exp(-d^T (C_i + C_j)^-1 d / 2)``, ``d = mu_i - mu_j``, and
    ``L = 1/(P (P - 1)) sum_{i != j} c_ij``. ``c_ij`` is about 1 for a small part inside a large one,
    ``2^(-3/2) = 0.35`` for two equal parts on one centre, 0.02 for two equal spheres that touch, and
    falls to 0 as parts separate, so its gradient pushes parts that pile onto one region apart while
    parts meeting at a joint pay little. (It can also be lowered by shrinking a part; the rendering
    terms keep the parts' size.)

    Args:
        parts: ``(..., P, V, 3)`` the parts' vertices (world units, one frame).
        eps: added to each covariance's diagonal (world units squared), keeping flat parts finite.
    Returns:
        ``(...)`` in [0, 1]; 0 with a single part.
    """
    p, v = parts.shape[-3:-1]
    if p < 2:
        return parts.new_zeros(parts.shape[:-3])
    centre = parts.mean(-2)  # (..., P, 3)
    spread = parts - centre.unsqueeze(-2)
    eye = torch.eye(3, dtype=parts.dtype, device=parts.device)
    cov = spread.transpose(-1, -2) @ spread / v + eps * eye  # (..., P, 3, 3)
    pair_cov = cov.unsqueeze(-3) + cov.unsqueeze(-4)  # [..., i, j] = C_i + C_j
    d = centre.unsqueeze(-2) - centre.unsqueeze(-3)  # [..., i, j] = mu_i - mu_j
    quad = (d * torch.linalg.solve(pair_cov, d.unsqueeze(-1)).squeeze(-1)).sum(-1)
    log_share = 0.5 * (torch.linalg.slogdet(cov).logabsdet.unsqueeze(-2) - torch.linalg.slogdet(pair_cov).logabsdet)
    share = torch.exp(log_share - 0.5 * quad)  # (..., P, P)
    others = 1 - torch.eye(p, dtype=parts.dtype, device=parts.device)
    return (share * others).sum(dim=(-2, -1)) / (p * (p - 1))
