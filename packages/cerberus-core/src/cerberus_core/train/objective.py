"""One training objective evaluation: predict, pose, render and combine every loss (sections 3–5).

For a batch of ``B`` quadruplets the model sees ``4 B`` images. With viewpoint consistency on, the
renderer draws ``8 B`` scenes in one call: each image's rotated parts with its own translation from
its own viewpoint, and with its viewpoint partner's translation from the partner's viewpoint
(equation 4). The total loss is

``lambda_r L_r' + lambda_t L_t' + lambda_b L_b + lambda_s L_s``

averaged over the batch (:mod:`cerberus_core.losses` defines every term). Beyond the paper (off in
its settings): ``antialias`` renders with the analytic anti-aliasing op, which gives the image and
the coverage visibility gradients; ``lambda_sil L_sil`` compares the rendered coverage with the
input's foreground (own and partner viewpoint, averaged like equation 4), ``lambda_c L_c`` pulls
the projected part vertices onto the foreground and ``lambda_h L_h`` pulls the parts an image does
not show toward the foreground no part covers (``losses.silhouette``, ``losses.chamfer``,
``losses.hidden``).
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import torch
from torch import nn

from cerberus_core.datasets.readers import background_mask
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.losses import (
    VIEW_PARTNER,
    LossConfig,
    background_loss,
    hidden_part_pull,
    mix_shape_latents,
    reconstruction_loss,
    silhouette_chamfer,
    silhouette_loss,
    smoothness_loss,
    translation_loss,
    viewpoint_reconstruction,
    viewpoint_scenes,
)
from cerberus_core.model.cerberus import Cerberus, Predictions
from cerberus_core.render.api import part_pixel_counts, render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.train.data import QuadrupletBatch

Tensor = torch.Tensor

TERMS = ("recon", "translation", "background", "smoothness", "silhouette", "chamfer", "hidden")
"""Loss terms in logging order (their weights are the fields of the same name in LossConfig)."""


@dataclass
class ObjectiveOutput:
    """Attributes:
        total: scalar loss to minimise (NaN if the predicted geometry was not finite; then nothing
            was rendered).
        terms: detached scalars of every term of :data:`TERMS` and ``total``.
        finite: whether ``total`` is finite.
        renders: ``(B, 4, 3, H, W)`` each image's own-viewpoint rendering (detached), or ``None``.
        parts: ``(B, 4, N, V, 3)`` the world-space parts rendered for each own viewpoint (detached).
    """

    total: Tensor
    terms: dict[str, Tensor]
    finite: bool
    renders: Tensor | None = None
    parts: Tensor | None = None


def unwrap(model: nn.Module) -> Cerberus:
    """The :class:`Cerberus` inside a DistributedDataParallel wrapper (or the model itself)."""
    inner = getattr(model, "module", model)
    if not isinstance(inner, Cerberus):
        raise TypeError(f"expected a Cerberus model, got {type(inner).__name__}")
    return inner


def quadruplet_mixer(generator: torch.Generator | None) -> Callable[[Tensor], Tensor]:
    """Pose consistency for flattened quadruplets: ``(4 B, S)`` own latents → ``(4 B, S)`` where the
    four images of each quadruplet share one mixed latent (equation 3)."""
    def mix(latents: Tensor) -> Tensor:
        quads = latents.view(-1, 4, latents.shape[-1])
        mixed, _ = mix_shape_latents(quads, generator)
        return mixed.unsqueeze(1).expand_as(quads).reshape_as(latents)
    return mix


def partner_cameras(camera: Camera, num_quadruplets: int) -> Camera:
    """For flattened quadruplet cameras ``4 b + k``, the camera of ``4 b + VIEW_PARTNER[k]``."""
    idx = (torch.arange(num_quadruplets).view(-1, 1) * 4 + torch.tensor(VIEW_PARTNER).view(1, 4)).reshape(-1)
    return camera.index(idx.to(camera.device))


def smoothness_term(local_vertices: Tensor, dihedral: Tensor, num_quadruplets: int, once: bool) -> Tensor:
    """``(4 B,)`` smoothness loss per image; ``once``: computed for the first image of each quadruplet
    and repeated (valid when the four share their meshes: pose consistency), a quarter of the work.
    Its mean equals the full computation's bit for bit when the meshes are equal."""
    if not once:
        return smoothness_loss(local_vertices, dihedral)
    first = local_vertices.view(num_quadruplets, 4, *local_vertices.shape[1:])[:, 0]
    return smoothness_loss(first, dihedral).unsqueeze(1).expand(num_quadruplets, 4).reshape(-1)


def quadruplet_objective(model: nn.Module, renderer: Renderer, batch: QuadrupletBatch, scene: SceneSetup,
                         losses: LossConfig, generator: torch.Generator | None = None, *,
                         smoothness_once: bool = False, antialias: bool = False) -> ObjectiveOutput:
    """Evaluate the training objective on a batch of quadruplets.

    Args:
        model: a :class:`Cerberus` (possibly wrapped in DistributedDataParallel; it is called
            through the wrapper so gradients synchronise).
        renderer: the renderer backend.
        batch: ``B`` quadruplets and their ``4 B`` cameras.
        scene: albedo, light and background used to render like the dataset.
        losses: weights and switches.
        generator: random source of the pose-consistency draws.
        smoothness_once: with pose consistency, compute the smoothness loss on one image per
            quadruplet (its four images decode the same mixed latent, so their meshes are equal);
            the loss value is the same, gradients equal up to rounding (``speed.smoothness_once``).
        antialias: render with :meth:`Renderer.antialias` (``render.antialias``): visibility
            gradients for the reconstruction and silhouette terms.
    """
    core = unwrap(model)
    bsz = batch.num_quadruplets
    images = batch.images.flatten(0, 1)  # (4B, 3, H, W)
    mix = quadruplet_mixer(generator) if losses.pose_consistency else None
    pred: Predictions = model(images, mix)
    r_world, t_world, _, _ = core.world_pose(pred, batch.camera)
    n, v = pred.local_vertices.shape[1:3]
    local = pred.local_vertices.view(bsz, 4, n, v, 3)
    rot = r_world.view(bsz, 4, n, 3, 3)
    trans = t_world.view(bsz, 4, n, 3)

    if not all(bool(torch.isfinite(t.detach()).all()) for t in (local, rot, trans)):
        nan = images.new_tensor(float("nan"))
        return ObjectiveOutput(nan, {k: nan for k in (*TERMS, "total")}, False)

    mask = background_mask(images, scene.background, losses.background_tolerance)  # (4B, 1, H, W)
    targets = batch.images
    bg_colour = scene.background
    if losses.render_background == "black":
        targets = (batch.images * (1 - mask.view(bsz, 4, 1, *mask.shape[-2:])))
        bg_colour = (0.0, 0.0, 0.0)

    own, cross = viewpoint_scenes(local, rot, trans)
    style = dict(albedo=scene.albedo, background=bg_colour, antialias=antialias)
    if losses.viewpoint_consistency:
        cameras = Camera.cat([batch.camera, partner_cameras(batch.camera, bsz)])
        verts = torch.cat([own.flatten(0, 1), cross.flatten(0, 1)])
        out = render_parts(renderer, verts, core.faces, cameras, scene.light(cameras), **style)
        rendered_own, rendered_cross = out.image.view(2, bsz, 4, *out.image.shape[1:]).unbind(0)
        alpha_own, alpha_cross = out.alpha.view(2, bsz, 4, *out.alpha.shape[1:]).unbind(0)
        loss_cross = reconstruction_loss(rendered_cross, targets[:, list(VIEW_PARTNER)])
    else:
        out = render_parts(renderer, own.flatten(0, 1), core.faces, batch.camera, scene.light(batch.camera), **style)
        rendered_own, loss_cross = out.image.view(bsz, 4, *out.image.shape[1:]), None
        alpha_own, alpha_cross = out.alpha.view(bsz, 4, *out.alpha.shape[1:]), None
    loss_own = reconstruction_loss(rendered_own, targets)
    foreground = (1 - mask).view(bsz, 4, *mask.shape[1:])  # (B, 4, 1, H, W)
    sil_own = silhouette_loss(alpha_own, foreground)
    sil_cross = None if alpha_cross is None else silhouette_loss(alpha_cross, foreground[:, list(VIEW_PARTNER)])
    uv = None
    if losses.chamfer != 0 or losses.hidden != 0:
        uv, _ = batch.camera.project(own.flatten(0, 1).flatten(1, 2))  # (4B, N V, 2) pixels
    # Both are Python loops over images: not computed when off.
    chamfer = silhouette_chamfer(uv, foreground.flatten(0, 1)) if losses.chamfer != 0 else images.new_zeros(4 * bsz)
    if losses.hidden != 0:
        part_id = out.part_id[:4 * bsz]  # (4B, H, W) own viewpoints, -1 where no part
        uncovered = foreground.flatten(0, 1)[:, 0] * (part_id < 0)
        hidden = hidden_part_pull(uv.view(4 * bsz, n, v, 2), part_pixel_counts(part_id, n) > 0, uncovered)
    else:
        hidden = images.new_zeros(4 * bsz)

    values = {
        "recon": viewpoint_reconstruction(loss_own, loss_cross).mean(),
        "translation": translation_loss(trans).mean(),
        "background": background_loss(pred.maps.prob, mask).mean(),
        "smoothness": smoothness_term(pred.local_vertices, core.dihedral, bsz,
                                      smoothness_once and losses.pose_consistency).mean(),
        "silhouette": viewpoint_reconstruction(sil_own, sil_cross).mean(),
        "chamfer": chamfer.mean(),
        "hidden": hidden.mean(),
    }
    total = sum(getattr(losses, k) * values[k] for k in TERMS if getattr(losses, k) != 0)
    total = total if isinstance(total, Tensor) else images.new_zeros(())
    terms = {k: t.detach() for k, t in values.items()} | {"total": total.detach()}
    return ObjectiveOutput(total, terms, bool(torch.isfinite(total.detach())), rendered_own.detach(), own.detach())
