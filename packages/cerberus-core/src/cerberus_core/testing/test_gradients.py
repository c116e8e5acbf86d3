"""Vertex gradients of every backend against central finite differences, away from silhouettes.

The loss weights only pixels whose 3x3 neighbourhood shows one part (``scenes.interior_mask``): there
the rendered image and depth are smooth functions of the vertices, so finite differences are exact
up to the step, while silhouettes (where rasterization is discontinuous and the barycentric renderer
has no gradient by design) stay out. float64 with a 1e-6 step where the backend keeps float64
end to end; float32 with a 1e-3 step otherwise.
"""
from __future__ import annotations

import pytest
import torch

from cerberus_core.render.api import render_parts

from .scenes import body_scene, double_camera, interior_mask

STEP_AND_RTOL = {torch.float64: (1e-6, 1e-4), torch.float32: (1e-3, 1e-2)}
"""Finite-difference step (world units) and allowed relative error per dtype (measured with the torch
backend: worst relative error 2e-9 in float64, 1.2e-3 in float32)."""


@pytest.fixture(scope="module")
def problem(renderer, grad_dtype):
    """A scene, its interior mask and a weighted loss over the masked image and depth."""
    parts, faces, camera = body_scene(2, num_parts=4, image_size=48, seed=5, radius=(0.1, 0.25), dtype=grad_dtype)
    if grad_dtype == torch.float64:
        camera = double_camera(camera)
    with torch.no_grad():
        rest = render_parts(renderer, parts, faces, camera)
    mask = interior_mask(rest.part_id)
    assert mask.sum() > 300, "the gradient scene must show a fair interior area"
    g = torch.Generator().manual_seed(0)
    w_img = torch.rand(rest.image.shape, generator=g, dtype=grad_dtype) * mask
    w_dep = torch.rand(rest.depth.shape, generator=g, dtype=grad_dtype) * mask

    def loss(p: torch.Tensor) -> torch.Tensor:
        out = render_parts(renderer, p, faces, camera)
        return (out.image * w_img).sum() + 0.1 * (out.depth * w_dep).sum()

    p = parts.clone().requires_grad_(True)
    loss(p).backward()
    return parts, loss, p.grad


def _central_difference(loss, parts: torch.Tensor, direction: torch.Tensor, step: float) -> float:
    with torch.no_grad():
        return float((loss(parts + step * direction) - loss(parts - step * direction)) / (2 * step))


def test_gradient_is_finite_and_nonzero(problem) -> None:
    _, _, grad = problem
    assert torch.isfinite(grad).all()
    assert grad.abs().max() > 0


def test_gradient_direction_matches_finite_differences(problem, grad_dtype) -> None:
    parts, loss, grad = problem
    step, rtol = STEP_AND_RTOL[grad_dtype]
    u = grad / grad.norm()
    fd = _central_difference(loss, parts, u, step)
    analytic = float(grad.norm())
    assert abs(fd - analytic) <= rtol * analytic, f"along the gradient: fd {fd}, analytic {analytic}"


def test_single_coordinates_match_finite_differences(problem, grad_dtype) -> None:
    parts, loss, grad = problem
    step, rtol = STEP_AND_RTOL[grad_dtype]
    flat = grad.flatten()
    largest = flat.abs().max()
    top = flat.abs().topk(3).indices
    g = torch.Generator().manual_seed(1)
    strong = torch.nonzero(flat.abs() > 0.05 * largest).squeeze(1)
    picked = strong[torch.randperm(len(strong), generator=g)[:3]]
    zero = torch.nonzero(flat == 0).squeeze(1)
    for i in torch.cat([top, picked]).tolist():
        e = torch.zeros_like(flat)
        e[i] = 1
        fd = _central_difference(loss, parts, e.view_as(parts), step)
        analytic = float(flat[i])
        assert abs(fd - analytic) <= rtol * abs(analytic), f"coordinate {i}: fd {fd}, analytic {analytic}"
    # A vertex the loss does not see has no gradient, and finite differences agree.
    assert len(zero) > 0
    e = torch.zeros_like(flat)
    e[zero[torch.randint(len(zero), (1,), generator=g)]] = 1
    assert abs(_central_difference(loss, parts, e.view_as(parts), step)) <= rtol * float(largest)
