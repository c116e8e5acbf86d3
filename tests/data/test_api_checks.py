"""The Python API checks what the CLI checks (issue 26): image dtype and range for the model, the limit of
Run.evaluate, what a dataset's kind and scene differ from the model's, and occupancy grids for grid_iou."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from cerberus_core import Run


@pytest.fixture(scope="module")
def human():
    return Run.load("human")


def test_reconstruct_refuses_images_that_are_not_float32_in_0_1(human):
    cam = human.scene.cameras(torch.zeros(1), 64)
    with pytest.raises(ValueError, match=r"uint8 \(0-255\); pass images.float\(\) / 255"):
        human.model.reconstruct(torch.zeros(1, 3, 64, 64, dtype=torch.uint8), cam)
    with pytest.raises(ValueError, match="float64"):
        human.model.reconstruct(torch.zeros(1, 3, 64, 64, dtype=torch.float64), cam)
    with pytest.raises(ValueError, match="above 1"):
        human.model.reconstruct(torch.full((1, 3, 64, 64), 200.0), cam)
    human.model.eval()
    with torch.no_grad():
        assert human.model.reconstruct(torch.rand(1, 3, 64, 64), cam).batch_size == 1


@pytest.mark.parametrize("limit", [0, -1, 2.5, True])
def test_evaluate_refuses_a_limit_the_cli_refuses(limit):
    from cerberus_core.run import EvalSettings

    with pytest.raises(ValueError, match=r"limit = .*: must be an integer >= 1 \(EvalSettings\(limit=...\)\)"):
        EvalSettings(limit=limit)


def test_domain_notes_name_another_kind_of_body_and_another_camera(human, pairs_dataset):
    notes = human.domain_notes(pairs_dataset)
    assert any("trained on human bodies" in n and "primitives bodies" in n for n in notes)
    assert any("differs from the model's training scenes" in n for n in notes)


def test_grid_iou_refuses_a_float_grid():
    from cerberus_metrics import grid_iou
    from cerberus_metrics.io import MeshInputError

    occupied = np.zeros((4, 4, 4), bool)
    occupied[:2] = True
    assert grid_iou(occupied, occupied.astype(np.uint8)) == 1.0  # 0/1 integers are occupancy
    with pytest.raises(MeshInputError, match="float64 grid, not occupancy"):
        grid_iou(np.full((4, 4, 4), 0.5), occupied)
