"""A demo scene: a stick figure of 9 deformed sphere parts, for examples, ``cerberus demo`` and the
rendering benchmarks."""
from __future__ import annotations

import torch

from cerberus_core.render.camera import Camera
from cerberus_core.render.templates import icosphere

# A stick figure of 9 ellipsoids: (centre xyz, radii xyz), normalised units.
_FIGURE = [
    ((0.0, 0.33, 0.0), (0.07, 0.08, 0.07)),     # head
    ((0.0, 0.12, 0.0), (0.11, 0.14, 0.07)),     # torso
    ((-0.06, -0.12, 0.0), (0.045, 0.10, 0.045)),  # left thigh
    ((0.06, -0.12, 0.0), (0.045, 0.10, 0.045)),   # right thigh
    ((-0.06, -0.33, 0.02), (0.035, 0.10, 0.035)),  # left shin
    ((0.06, -0.33, -0.02), (0.035, 0.10, 0.035)),  # right shin
    ((-0.17, 0.13, 0.0), (0.03, 0.12, 0.03)),   # left arm
    ((0.17, 0.13, 0.0), (0.03, 0.12, 0.03)),    # right arm
    ((0.0, 0.23, 0.0), (0.035, 0.04, 0.035)),   # neck
]


def demo_scene(batch: int = 4, image_size: int = 128, seed: int = 0):
    """Deformed parts of a stick figure seen from ``batch`` azimuths.

    Returns:
        ``(parts (B, 9, 162, 3), faces (320, 3), camera)``.
    """
    g = torch.Generator().manual_seed(seed)
    t = icosphere(2)
    centres = torch.tensor([c for c, _ in _FIGURE])
    radii = torch.tensor([r for _, r in _FIGURE])
    bump = 1 + 0.08 * torch.sin(3 * t.vertices[:, :1] + torch.rand(len(_FIGURE), 1, 1, generator=g) * 6)
    parts = t.vertices.unsqueeze(0) * bump * radii.unsqueeze(1) + centres.unsqueeze(1)
    parts = parts.unsqueeze(0).expand(batch, -1, -1, -1).contiguous()
    camera = Camera.look_at(torch.linspace(0, 270, batch), 15.0, 2.2, fov_y_deg=30.0, image_size=image_size)
    return parts, t.faces, camera
