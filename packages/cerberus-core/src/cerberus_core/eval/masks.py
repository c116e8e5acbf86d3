"""Mask IoU: the toolkit's one rule for how much two masks overlap, and what an empty pair scores.

:func:`mask_iou` serves every mask comparison of the evaluation and of a reconstruction: the depth diagnostic's
silhouettes in each view of a pose (:mod:`.depth`), part quality's segmentation IoU over the cells of its overlap
matrix weighted by area (:mod:`.part_quality`), and the rendered silhouette of a reconstruction against the mask of
its photo (:mod:`cerberus_core.photo_mask`). Two empty masks score NaN, not 1: they have no overlap to score, so a
mean over pairs where that can happen is a NaN-aware one (or leaves such pairs out), and says so. The voxel IoU of
``cerberus-metrics`` (``grid_iou``) is its own package's, which imports nothing of this one.
"""
from __future__ import annotations

import numpy as np
import torch

from cerberus_core.errors import ShapeError
from cerberus_core.shapes import check_shapes

Tensor = torch.Tensor

BOOL = (torch.bool,)
FLOATS = (torch.float32, torch.float64)


def mask_iou(a: Tensor | np.ndarray, b: Tensor | np.ndarray, weights: Tensor | np.ndarray | None = None) -> Tensor:
    """Intersection over union of two masks, per pair of masks: ``|a and b| / |a or b|``.

    Args:
        a, b: ``(..., H, W)`` bool masks of one shape, torch tensors or NumPy arrays (a soft mask or an alpha
            thresholded first, e.g. ``alpha >= 0.5``).
        weights: ``(H, W)`` float >= 0, what each pixel counts for (an area, in any unit: the ratio has none), the
            same for every pair; ``None``: 1 per pixel, the IoU of pixel counts.
    Returns:
        ``(...)`` float64 in [0, 1], on the masks' device. NaN where the union is empty (both masks empty, or only
        pixels of weight 0 under them): an empty mask against an empty mask has no overlap to score, and 1 would
        credit drawing nothing where there is nothing. Average such pairs with :func:`torch.nanmean` or
        :func:`numpy.nanmean`, or leave them out.
    Raises:
        ShapeError: masks that are not bool, of two shapes, or weights of another ``(H, W)`` or below 0.
        DeviceError: masks and weights on different devices.

    Example:
        >>> a = torch.zeros(2, 4, 4, dtype=torch.bool)
        >>> b = torch.zeros(2, 4, 4, dtype=torch.bool)
        >>> a[0, :2], b[0, 1:3] = True, True  # two rows each, one shared: 4 of 12 pixels
        >>> mask_iou(a, b)  # the second pair is empty against empty
        tensor([0.3333,    nan], dtype=torch.float64)
        >>> rows = torch.tensor([[3.0], [1.0], [1.0], [1.0]]).expand(4, 4)  # the first row counts 3 times
        >>> mask_iou(a[0], b[0], weights=rows)  # 4 of (3 + 1 + 1) * 4
        tensor(0.2000, dtype=torch.float64)
        >>> float(mask_iou(np.eye(3, dtype=bool), np.ones((3, 3), dtype=bool)))  # NumPy masks: 3 of 9 pixels
        0.3333333333333333
    """
    a, b = torch.as_tensor(a), torch.as_tensor(b)
    masks = {"a": (a, "... H W", BOOL), "b": (b, "... H W", BOOL)}
    if weights is None:
        check_shapes("mask_iou", same_device=True, **masks)
        inter, union = (a & b).sum((-2, -1)).double(), (a | b).sum((-2, -1)).double()
    else:
        weights = torch.as_tensor(weights)
        check_shapes("mask_iou", same_device=True, **masks, weights=(weights, "H W", FLOATS))
        if bool((weights < 0).any()):
            raise ShapeError(f"mask_iou: weights must be >= 0 (what each pixel counts for), got a minimum of "
                             f"{float(weights.min()):g}; pass areas or counts")
        weights = weights.double()
        inter, union = (weights * (a & b)).sum((-2, -1)), (weights * (a | b)).sum((-2, -1))
    return torch.where(union > 0, inter / union, torch.nan)
