"""The scene light: one directional light plus ambient light (what the shading consumes)."""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import torch

Tensor = torch.Tensor

#: "New lighting" direction (Figure 1 d; the figures and the viewer) in the camera's frame (+x right,
#: +y up, +z towards the viewer): from the upper left, slightly in front.
NEW_LIGHT_CAMERA_DIRECTION = (-1.0, 1.0, 0.35)


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

    @classmethod
    def camera_relative(cls, camera, direction_cam: Sequence[float], ambient: float = 0.4,
                        diffuse: float = 0.6) -> Light:
        """White light from ``direction_cam`` given in each camera's frame (so it reads the same in
        every view; normalised here)."""
        d = torch.as_tensor(direction_cam, dtype=camera.rotation.dtype, device=camera.device)
        world = (camera.rotation.transpose(-1, -2) @ d).reshape(camera.batch_size, 3)
        return cls.white(world, ambient, diffuse)

    def index(self, idx) -> Light:
        return Light(self.direction[idx], self.ambient[idx], self.diffuse[idx])
