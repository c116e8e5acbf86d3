"""The scene light: one directional light plus ambient light (what the shading consumes)."""
from __future__ import annotations

from dataclasses import dataclass

import torch

Tensor = torch.Tensor


@dataclass
class Light:
    """One directional light plus ambient light, in world coordinates.

    Attributes:
        direction: ``(B, 3)`` unit vectors pointing *towards* the light.
        ambient: ``(B, 3)`` ambient RGB intensity.
        diffuse: ``(B, 3)`` directional RGB intensity.

    A surface point with unit normal ``n`` and albedo ``a`` gets the colour
    ``a * (ambient + diffuse * max(0, n · direction))``.
    """

    direction: Tensor
    ambient: Tensor
    diffuse: Tensor

    @classmethod
    def white(cls, direction: Tensor, ambient: float = 0.4, diffuse: float = 0.6) -> Light:
        """White light from ``direction`` ``(B, 3)`` (normalised here)."""
        d = torch.nn.functional.normalize(direction, dim=-1)
        b = d.shape[0]
        ones = torch.ones(b, 3, dtype=d.dtype, device=d.device)
        return cls(d, ones * ambient, ones * diffuse)

    @classmethod
    def following(cls, camera, ambient: float = 0.4, diffuse: float = 0.6) -> Light:
        """White light shining along each camera's viewing direction (the paper's set-up)."""
        return cls.white(camera.view_direction(), ambient, diffuse)

    def index(self, idx) -> Light:
        return Light(self.direction[idx], self.ambient[idx], self.diffuse[idx])
