"""Fitting a reconstruction to its silhouette (cerberus_core.reconstruct.fit): the outline moves onto the mask on both
backends, an image without a silhouette is left as predicted, and bad input is named."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import ConfigError, InputTypeError, ShapeError
from cerberus_core.eval.masks import mask_iou
from cerberus_core.parts import PartSet
from cerberus_core.photo_mask import SILHOUETTE_THRESHOLD, rendered_silhouette
from cerberus_core.reconstruct.fit import FitSettings, fit_silhouette, fit_silhouettes
from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import make_renderer
from cerberus_core.render.templates import icosphere

pytestmark = pytest.mark.usefixtures("one_thread")


def two_balls(offset: float) -> tuple[PartSet, torch.Tensor]:
    """Two parts side by side, the second shifted right by ``offset`` (world units), and the template's dihedral."""
    t = icosphere(1)
    local = 0.1 * t.vertices.expand(1, 2, -1, -1).clone()
    translations = torch.tensor([[[-0.15, 0.0, 0.0], [0.15 + offset, 0.0, 0.0]]])
    return PartSet(local, t.faces, torch.eye(3).expand(1, 2, 3, 3).clone(), translations), t.dihedral


@pytest.mark.parametrize("backend", ["torch", "warp"])
def test_the_fit_moves_the_outline_onto_the_mask(backend):
    renderer = make_renderer(backend)
    camera = SceneSetup().cameras([0.0], 32)
    truth, dihedral = two_balls(0.08)
    target = render_parts(renderer, truth.posed(), truth.faces, camera, antialias=True).alpha[0, 0].numpy()
    guess, _ = two_balls(0.0)
    fitted = fit_silhouette(renderer, guess, camera, torch.as_tensor(target)[None], dihedral,
                            FitSettings(steps=80, lr=0.005, anchor=0.0))
    on = target >= SILHOUETTE_THRESHOLD
    before = float(mask_iou(rendered_silhouette(renderer, guess, camera) >= SILHOUETTE_THRESHOLD, on))
    after = float(mask_iou(rendered_silhouette(renderer, fitted, camera) >= SILHOUETTE_THRESHOLD, on))
    assert after > before + 0.1 and after > 0.9
    moved = (fitted.translations - guess.translations)[0, :, 0]
    assert moved[1] > 0.03 and abs(float(moved[0])) < moved[1] / 3  # the shifted part moved right, the other hardly
    assert torch.equal(fitted.rotations, guess.rotations) and not fitted.local_vertices.requires_grad


def test_fit_silhouettes_leaves_an_image_without_one_as_predicted():
    renderer = make_renderer("torch")
    camera = SceneSetup().cameras([0.0, 0.0], 32)
    one, dihedral = two_balls(0.0)
    both = PartSet(one.local_vertices.repeat(2, 1, 1, 1), one.faces, one.rotations.repeat(2, 1, 1, 1),
                   one.translations.repeat(2, 1, 1))
    target = np.zeros((32, 32))
    target[8:24, 4:28] = 1.0
    fitted = fit_silhouettes(renderer, both, camera, [None, target], dihedral, FitSettings(steps=5))
    assert torch.equal(fitted.local_vertices[0], both.local_vertices[0])
    assert torch.equal(fitted.translations[0], both.translations[0])
    assert not torch.equal(fitted.translations[1], both.translations[1])
    assert fit_silhouettes(renderer, both, camera, [None, None], dihedral) is both
    assert fit_silhouettes(renderer, both, camera, [target, target], dihedral, FitSettings(steps=0)) is both


def test_bad_input_is_named():
    renderer = make_renderer("torch")
    camera = SceneSetup().cameras([0.0], 32)
    parts, dihedral = two_balls(0.0)
    with pytest.raises(ShapeError, match="fit_silhouette: silhouette must be"):
        fit_silhouette(renderer, parts, camera, torch.zeros(1, 1, 16, 16), dihedral)
    with pytest.raises(ShapeError, match="2 silhouettes for 1 reconstructions"):
        fit_silhouettes(renderer, parts, camera, [None, None], dihedral)
    with pytest.raises(ConfigError, match=r"FitSettings\(steps=\.\.\.\)"):
        FitSettings(steps=-1)
    with pytest.raises(InputTypeError, match="FitSettings"):
        fit_silhouette(renderer, parts, camera, torch.zeros(1, 32, 32), dihedral, 100)
