"""cerberus_core.eval.masks: the one mask IoU, with NaN for an empty pair."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from cerberus_core.errors import ShapeError
from cerberus_core.eval.masks import mask_iou


def test_mask_iou_counts_pixels_per_pair_and_an_empty_pair_is_nan():
    a = torch.zeros(2, 4, 4, dtype=torch.bool)
    b = torch.zeros(2, 4, 4, dtype=torch.bool)
    a[0, :2] = True
    b[0, 1:3] = True  # 4 shared pixels of 12
    iou = mask_iou(a, b)
    assert iou.shape == (2,) and iou.dtype == torch.float64
    assert float(iou[0]) == pytest.approx(4 / 12) and bool(iou[1].isnan())  # both empty: nothing to score
    assert float(mask_iou(a[0], a[0])) == 1.0 and float(mask_iou(a[0], ~a[0])) == 0.0
    assert float(mask_iou(a[1], b[0])) == 0.0  # empty against a mask: no overlap


def test_numpy_masks():
    a, b = np.zeros((4, 4), bool), np.zeros((4, 4), bool)
    a[:2], b[1:3] = True, True
    assert float(mask_iou(a, b)) == pytest.approx(1 / 3)
    assert np.isnan(float(mask_iou(a & ~a, b & ~b)))


def test_bad_masks_are_named():
    a = torch.zeros(4, 4, dtype=torch.bool)
    with pytest.raises(ShapeError, match="a must be bool"):
        mask_iou(a.float(), a)
    with pytest.raises(ShapeError, match=r"b must be \(\.\.\., H, W\)"):
        mask_iou(a, torch.zeros(4, 5, dtype=torch.bool))
