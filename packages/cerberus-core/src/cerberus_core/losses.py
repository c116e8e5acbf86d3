"""Every loss term of the paper, each a small function (sections 3.2, 4 and 5).

A training example is a *quadruplet* of images of one body: two poses ``a, b`` seen from two
viewpoints ``0, 1``, stacked in the order :data:`QUADRUPLET` = ``(a0, a1, b0, b1)`` along a
dimension of size 4. Per-image tensors are shaped ``(B, 4, ...)`` here.

====================  ==================================================  =========================
term                  definition                                          function
====================  ==================================================  =========================
reconstruction        ``1/|G| sum_xy ||I_xy - R_xy||^2`` (eq. 2)            :func:`reconstruction_loss`
pose consistency      ``S~ = sum_x 1_Z(x) S^x`` (eq. 3)                    :func:`mix_shape_latents`
viewpoint, render     ``L^a0 = (L^{a0->a0} + L^{a0->a1}) / 2`` (eq. 4)     :func:`viewpoint_scenes`,
                                                                          :func:`viewpoint_reconstruction`
viewpoint, transl.    ``1/N sum_i ||T_i^0 - T_i^1||^2``, mean of a, b      :func:`translation_loss`
                      (eqs. 5, 6)
total reconstruction  mean of the four ``L^x`` (eq. 7)                     :func:`viewpoint_reconstruction`
background            ``1/N sum_k sum_xy p^k_xy b_xy``                     :func:`background_loss`
smoothness            ``sum_edges (cos theta + 1)^2`` (Kato et al.)        :func:`smoothness_loss`
====================  ==================================================  =========================

Beyond the paper (weight 0 in its settings): :func:`silhouette_loss`, :func:`silhouette_chamfer`,
:func:`hidden_part_pull` and :func:`reprojection_loss`, and the ``own`` cross view of
:func:`viewpoint_scenes`.

These are the functions; the objective's one table of terms (name, weight, how each is computed from
the objective's inputs, symbol, reference) and the weights' config section, ``LossConfig``, are in
:mod:`cerberus_core.train.objective`.
"""
from __future__ import annotations

from collections.abc import Callable

import torch

from cerberus_core.parts import pose_parts
from cerberus_core.render.nearest import nearest_indices
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

NearestSearch = Callable[..., tuple[Tensor, "Tensor | None"]]
"""The pulls' nearest-neighbour search, ``(points, targets, counts, both) -> (to_target, to_point)``:
:func:`cerberus_core.render.nearest.nearest_indices` or a renderer backend's kernel for it
(:meth:`Renderer.nearest_indices <cerberus_core.render.interface.Renderer.nearest_indices>`)."""

QUADRUPLET: tuple[str, ...] = ("a0", "a1", "b0", "b1")
"""Order of the four images of a training example."""

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
        raise ValueError(f"viewpoint_scenes: cross_view must be 'partner' or 'own', got {cross_view!r}")
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
    fg = foreground.reshape(foreground.shape[0], *foreground.shape[-2:]) > 0.5
    n, height, _ = fg.shape
    check_shapes("silhouette_chamfer", points=(points, "N M 2"), foreground=(fg, "N H W"))
    stride = max(1, -(-points.shape[1] // max_points))
    pts = points[:, ::stride]  # (N, M', 2)
    centres, valid = mask_pixel_centres(fg)  # (N, K, 2), (N, K)
    centres = centres.to(pts.dtype)
    count = valid.sum(1)
    to_pixel, to_vertex = search(pts, centres, count, True)
    pixel_side = (_pair_distance(centres, pts, to_vertex) * valid).sum(1) / count.clamp(min=1)
    vertex_side = _pair_distance(pts, centres, to_pixel).mean(1)
    return torch.where(count > 0, (pixel_side + vertex_side) / height, pts.new_zeros(()))


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
