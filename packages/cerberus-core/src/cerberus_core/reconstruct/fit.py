"""Fitting a reconstruction to its silhouette: a few steps of gradient descent through the renderer.

The network predicts the parts from the image in one pass; where the image comes with the body's silhouette
(``cerberus reconstruct --mask``, an RGBA cut-out, ``--mask auto``), that silhouette can also be *fitted*:
the parts' vertices and translations move so that their rendered coverage matches it, starting from the
network's prediction and held near it. This is the test-time optimisation many single-image methods end
with (an instance fit of the predicted shape to the observed mask); the network, its rotations and the
part layout are not changed. The silhouette constrains the parts only across the view: depth is whatever
the network predicted, up to the perspective's small effect.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import torch

from cerberus_core.errors import InputTypeError, ShapeError
from cerberus_core.fields import Checked, ranged
from cerberus_core.losses import silhouette_loss, smoothness_loss
from cerberus_core.parts import PartSet
from cerberus_core.render.api import render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

#: ``cerberus reconstruct --fit``'s default steps: on the photo-like test they take the parts' silhouette IoU against the
#: exact mask from 0.760 to 0.924 while the voxel IoU holds (+0.002 +- 0.003; docs/evaluation.md).
FIT_STEPS = 100


@dataclass(frozen=True)
class FitSettings(Checked):
    """How :func:`fit_silhouette` fits; the defaults are the ones measured on the photo-like test
    (docs/evaluation.md, "Fitting the silhouette").

    Attributes:
        steps: gradient steps (0: the parts as given).
        lr: Adam's step size (world units per step, about).
        smoothness: the weight of Kato et al.'s smoothness of the fitted parts.
        anchor: the weight of the pull of each vertex back to the network's (mean squared offset).
    """

    FIX = "{cls}({key}=...)"

    steps: int = ranged(FIT_STEPS, ge=0)
    lr: float = ranged(0.002, ge=0)
    smoothness: float = ranged(1e-4, ge=0)
    anchor: float = ranged(1.0, ge=0)


def fit_silhouette(renderer: Renderer, parts: PartSet, camera: Camera, silhouette: Tensor, dihedral: Tensor,
                   settings: FitSettings = FitSettings()) -> PartSet:
    """Move each part's vertices and translation so that the parts' rendered coverage matches a silhouette.

    Minimises, with Adam from the prediction (offsets ``dV``, ``dT`` start at 0), for every image at once:
    ``mean_pixels (alpha - silhouette)^2 + smoothness * L_s(V + dV) + anchor * mean ||dV||^2`` (:class:`FitSettings`), where ``alpha``
    is the anti-aliased coverage of the parts (:func:`~cerberus_core.render.api.render_parts`, which gives
    gradients at the silhouette's edges), ``L_s`` Kato et al.'s smoothness (:func:`~cerberus_core.losses.
    smoothness_loss`) and the last term holds the shapes near the network's. Rotations are kept.

    Args:
        renderer: a backend with visibility gradients (both shipped backends have them).
        parts: ``(B, P, V, 3)`` the network's reconstruction (:class:`~cerberus_core.parts.PartSet`).
        camera: the ``B`` input cameras.
        silhouette: ``(B, 1, H, W)`` or ``(B, H, W)`` the body's coverage in each input, in [0, 1], at the
            camera's resolution.
        dihedral: ``(E, 4)`` the part template's dihedral quadruples (``Cerberus.dihedral``).
        settings: the steps, step size and the weights above (:class:`FitSettings`).
    Returns:
        A new, detached :class:`~cerberus_core.parts.PartSet` on ``parts``' device.

    Example:
        >>> from cerberus_core.render.backends import make_renderer
        >>> from cerberus_core.render.templates import icosphere
        >>> from cerberus_core.datasets.scene import SceneSetup
        >>> from cerberus_core.eval.masks import mask_iou
        >>> from cerberus_core.photo_mask import rendered_silhouette
        >>> t = icosphere(1); cam = SceneSetup().cameras([0.0], 32); r = make_renderer("torch")
        >>> ball = PartSet.from_posed(0.12 * t.vertices[None, None], t.faces)
        >>> target = render_parts(r, (0.2 * t.vertices + torch.tensor([0.05, 0.0, 0.0]))[None, None], t.faces,
        ...                       cam, antialias=True).alpha
        >>> fitted = fit_silhouette(r, ball, cam, target, t.dihedral, FitSettings(steps=60, lr=0.01, anchor=0.0))
        >>> on = target[0, 0] >= 0.5
        >>> before = mask_iou(rendered_silhouette(r, ball, cam) >= 0.5, on)
        >>> after = mask_iou(rendered_silhouette(r, fitted, cam) >= 0.5, on)
        >>> bool(after > 0.9 > before)
        True
    """
    if not isinstance(settings, FitSettings):
        raise InputTypeError(f"fit_silhouette: settings must be a FitSettings, got {type(settings).__name__}; pass "
                             "`FitSettings(steps=...)`")
    if silhouette.ndim == 3:
        silhouette = silhouette.unsqueeze(1)
    h, w = camera.height, camera.width
    check_shapes("fit_silhouette", silhouette=(silhouette, f"{parts.batch_size} 1 {h} {w}"))
    target = silhouette.to(parts.local_vertices.device, torch.float32).clamp(0, 1)
    base = parts.detach()
    dv = torch.zeros_like(base.local_vertices, requires_grad=True)
    dt = torch.zeros_like(base.translations, requires_grad=True)
    optimiser = torch.optim.Adam([dv, dt], lr=settings.lr)
    dihedral = dihedral.to(dv.device)
    with torch.enable_grad():
        for _ in range(settings.steps):
            moved = PartSet(base.local_vertices + dv, base.faces, base.rotations, base.translations + dt)
            alpha = render_parts(renderer, moved.posed(), moved.faces, camera, antialias=True).alpha
            loss = (silhouette_loss(alpha, target).sum()
                    + settings.smoothness * smoothness_loss(moved.local_vertices, dihedral).sum()
                    + settings.anchor * dv.square().sum(-1).mean(dim=(-2, -1)).sum())
            optimiser.zero_grad(set_to_none=True)
            loss.backward()
            optimiser.step()
    return PartSet(base.local_vertices + dv.detach(), base.faces, base.rotations, base.translations + dt.detach())


def fit_silhouettes(renderer: Renderer, parts: PartSet, camera: Camera, silhouettes: Sequence[np.ndarray | None],
                    dihedral: Tensor, settings: FitSettings = FitSettings()) -> PartSet:
    """:func:`fit_silhouette` for the images that have a silhouette; the others as predicted.

    Args:
        silhouettes: per image ``(H, W)`` in [0, 1] or ``None`` (:attr:`LoadedImage.silhouette
            <cerberus_core.reconstruct.images.LoadedImage.silhouette>`).
        Others as in :func:`fit_silhouette`.
    Returns:
        A new :class:`~cerberus_core.parts.PartSet` (``parts`` itself when nothing is fitted).
    """
    if len(silhouettes) != parts.batch_size:
        raise ShapeError(f"fit_silhouettes: {len(silhouettes)} silhouettes for {parts.batch_size} reconstructions; "
                         "pass one (or None) per image")
    given = [i for i, s in enumerate(silhouettes) if s is not None]
    if settings.steps == 0 or not given:
        return parts
    target = torch.stack([torch.as_tensor(np.asarray(silhouettes[i]), dtype=torch.float32) for i in given])
    fitted = fit_silhouette(renderer, parts.index(given), camera.index(given), target, dihedral, settings)
    local, moved = parts.local_vertices.detach().clone(), parts.translations.detach().clone()
    local[given], moved[given] = fitted.local_vertices, fitted.translations
    return PartSet(local, parts.faces, parts.rotations.detach(), moved)


__all__ = ["FIT_STEPS", "FitSettings", "fit_silhouette", "fit_silhouettes"]
