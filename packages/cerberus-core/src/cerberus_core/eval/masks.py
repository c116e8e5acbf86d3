"""Masks: where a scene covers its image (:func:`coverage_masks`), and the toolkit's one rule for how much two
masks overlap and what an empty pair scores (:func:`mask_iou`).

:func:`mask_iou` serves every mask comparison of the evaluation and of a reconstruction: the depth diagnostic's
silhouettes in each view of a pose (:mod:`.depth`) and the rendered silhouette of a reconstruction against the mask
of its photo (:mod:`cerberus_core.photo_mask`). Part quality's segmentation IoU, of areas rather than pixels, keeps
its NaN rule (:func:`~cerberus_core.eval.part_quality.segmentation_iou`). Two empty masks score NaN, not 1: they
have no overlap to score, so a mean over pairs where that can happen is a NaN-aware one (or leaves such pairs out),
and says so. The voxel IoU of ``cerberus-metrics`` (``grid_iou``) is its own package's, which imports nothing of
this one.
"""
from __future__ import annotations

import numpy as np
import torch

from cerberus_core.render.api import render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

BOOL = (torch.bool,)


def mask_iou(a: Tensor | np.ndarray, b: Tensor | np.ndarray) -> Tensor:
    """Intersection over union of two masks, per pair of masks: ``|a and b| / |a or b|``.

    Args:
        a, b: ``(..., H, W)`` bool masks of one shape, torch tensors or NumPy arrays (a soft mask or an alpha
            thresholded first, e.g. ``alpha >= 0.5``).
    Returns:
        ``(...)`` float64 in [0, 1], on the masks' device. NaN where the union is empty (both masks empty): an
        empty mask against an empty mask has no overlap to score, and 1 would credit drawing nothing where there
        is nothing. Average such pairs with :func:`torch.nanmean` or
        :func:`numpy.nanmean`, or leave them out.
    Raises:
        ShapeError: masks that are not bool, or of two shapes.
        DeviceError: masks on different devices.

    Example:
        >>> a = torch.zeros(2, 4, 4, dtype=torch.bool)
        >>> b = torch.zeros(2, 4, 4, dtype=torch.bool)
        >>> a[0, :2], b[0, 1:3] = True, True  # two rows each, one shared: 4 of 12 pixels
        >>> mask_iou(a, b)  # the second pair is empty against empty
        tensor([0.3333,    nan], dtype=torch.float64)
        >>> float(mask_iou(np.eye(3, dtype=bool), np.ones((3, 3), dtype=bool)))  # NumPy masks: 3 of 9 pixels
        0.3333333333333333
    """
    a, b = torch.as_tensor(a), torch.as_tensor(b)
    check_shapes("mask_iou", same_device=True, a=(a, "... H W", BOOL), b=(b, "... H W", BOOL))
    inter, union = (a & b).sum((-2, -1)).double(), (a | b).sum((-2, -1)).double()
    return torch.where(union > 0, inter / union, torch.nan)


def coverage_masks(renderer: Renderer, posed: Tensor, faces: Tensor, cameras: Camera) -> Tensor:
    """Where each of ``B`` scenes covers its camera's image: ``(B, H, W)`` bool, no gradient.

    Args:
        renderer: a backend; posed: ``(B, N, V, 3)`` world-frame vertices of ``N`` meshes per scene (parts, or
        one ground-truth body with ``N = 1``); faces: ``(F, 3)`` shared by every mesh; cameras: ``B`` cameras.
    """
    with torch.no_grad():
        return render_parts(renderer, posed.contiguous(), faces, cameras).part_id >= 0
