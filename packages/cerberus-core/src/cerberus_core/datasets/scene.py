"""The paper's scene set-up for every rendered view of a dataset.

Section 5 of the paper: "We fix the elevation angle and distance to the origin of all viewpoints but
vary the azimuth angles. On scene set-ups, we use a directional light following the direction of the
camera and an ambient light, all in white." Bodies have one uniform albedo and arrive normalised
into ``[-FILL/2, FILL/2]^3`` (:mod:`cerberus_core.bodies.body`).

The camera distance is *fitted*: the smallest distance at which every corner of the cube
``[-FILL/2, FILL/2]^3`` (hence every body) stays inside the frame, with a margin, from every
azimuth at the fixed elevation. Bodies thus fill most of the frame and are never clipped.
"""
from __future__ import annotations

import itertools
import math
from dataclasses import asdict, dataclass, field
from functools import lru_cache

import numpy as np
import torch

from cerberus_core.render.camera import Camera
from cerberus_core.bodies.body import FILL
from cerberus_core.render.interface import Light

Tensor = torch.Tensor


@lru_cache(maxsize=64)
def fit_distance(fov_y_deg: float, elevation_deg: float, extent: float = FILL, margin: float = 0.04) -> float:
    """Smallest camera distance at which the cube ``[-extent/2, extent/2]^3`` fits the frame.

    The cube is seen from azimuths every 2.5 degrees at ``elevation_deg``; every corner must project
    inside the square image shrunk by ``margin`` (a fraction of the half-width) on each side.

    Args:
        fov_y_deg: vertical (= horizontal, square images) field of view in degrees.
        elevation_deg: camera elevation in degrees.
        extent: side of the cube (normalised units).
        margin: fraction of the half image kept free around the cube.

    Returns:
        The distance in normalised units, rounded up to 1e-3.
    """
    corners = np.array(list(itertools.product((-0.5, 0.5), repeat=3))) * extent  # (8, 3)
    az = np.deg2rad(np.arange(0.0, 360.0, 2.5))
    el = math.radians(elevation_deg)
    # Camera axes for each azimuth (look-at the origin, +Y up): forward f points to the origin.
    eye_dir = np.stack([math.cos(el) * np.sin(az), np.full_like(az, math.sin(el)), math.cos(el) * np.cos(az)], -1)
    right = np.stack([np.cos(az), np.zeros_like(az), -np.sin(az)], -1)
    up = np.cross(eye_dir, right)
    limit = math.tan(math.radians(fov_y_deg) / 2) * (1 - margin)

    def fits(dist: float) -> bool:
        rel = corners[None] - dist * eye_dir[:, None]  # (A, 8, 3) camera-centred
        depth = -(rel * eye_dir[:, None]).sum(-1)
        x = (rel * right[:, None]).sum(-1) / depth
        y = (rel * up[:, None]).sum(-1) / depth
        return bool((depth > 0).all() and (np.abs(x) <= limit).all() and (np.abs(y) <= limit).all())

    lo, hi = extent * 0.5, extent * 100.0
    if not fits(hi):
        raise ValueError(f"fit_distance: field of view {fov_y_deg} deg is too narrow")
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    return math.ceil(hi * 1000) / 1000


@dataclass(frozen=True)
class SceneSetup:
    """Fixed camera and lighting of a dataset; only the azimuth varies per view.

    Attributes:
        elevation: camera elevation in degrees (above the horizon).
        fov_y: vertical field of view in degrees (images are square).
        distance: camera distance to the origin (normalised units); ``None`` fits it with
            :func:`fit_distance` at construction.
        ambient, diffuse: white ambient and directional intensity; the directional light shines
            along each camera's viewing direction (:meth:`Light.following`).
        albedo: uniform RGB body albedo in [0, 1].
        background: RGB background colour in [0, 1]. With the defaults every foreground pixel is at
            most ``albedo * (ambient + diffuse) = 0.8`` so background pixels (exactly 255 in uint8)
            separate from the body exactly.
        near, far: camera clipping distances.
    """

    elevation: float = 15.0
    fov_y: float = 30.0
    distance: float | None = None
    ambient: float = 0.4
    diffuse: float = 0.6
    albedo: tuple[float, float, float] = (0.8, 0.8, 0.8)
    background: tuple[float, float, float] = (1.0, 1.0, 1.0)
    near: float = 0.05
    far: float = 100.0
    fitted_extent: float = field(default=FILL)

    def __post_init__(self) -> None:
        if not 0 < self.fov_y < 180:
            raise ValueError(f"SceneSetup.fov_y must lie in (0, 180) degrees, got {self.fov_y}")
        if not -90 < self.elevation < 90:
            raise ValueError(f"SceneSetup.elevation must lie in (-90, 90) degrees, got {self.elevation}")
        if self.distance is None:
            object.__setattr__(self, "distance", fit_distance(self.fov_y, self.elevation, self.fitted_extent))
        if self.distance <= self.near:
            raise ValueError(f"SceneSetup.distance {self.distance} must exceed the near plane {self.near}")
        object.__setattr__(self, "albedo", tuple(float(a) for a in self.albedo))
        object.__setattr__(self, "background", tuple(float(b) for b in self.background))

    def to_dict(self) -> dict:
        """JSON-ready dict (as stored in the manifest's ``scene``)."""
        d = asdict(self)
        d["albedo"], d["background"] = list(self.albedo), list(self.background)
        d["light"] = {"type": "directional+ambient", "follows_camera": True, "colour": "white"}
        return d

    @classmethod
    def from_dict(cls, d: dict) -> SceneSetup:
        keys = {"elevation", "fov_y", "distance", "ambient", "diffuse", "albedo", "background", "near", "far",
                "fitted_extent"}
        return cls(**{k: (tuple(v) if isinstance(v, list) else v) for k, v in d.items() if k in keys})

    def cameras(self, azimuth_deg: Tensor | np.ndarray | list[float], image_size: int,
                device: torch.device | str | None = None) -> Camera:
        """``B`` cameras at the given azimuths (degrees) with this set-up's elevation, distance and fov."""
        az = torch.as_tensor(np.asarray(azimuth_deg, dtype=np.float32), device=device).reshape(-1)
        return Camera.look_at(az, self.elevation, self.distance, fov_y_deg=self.fov_y, image_size=image_size,
                              near=self.near, far=self.far, device=device)

    def light(self, camera: Camera) -> Light:
        """White directional light along each camera's viewing direction plus white ambient."""
        return Light.following(camera, ambient=self.ambient, diffuse=self.diffuse)


def evenly_spaced(offset_deg: float, n: int) -> np.ndarray:
    """``n`` azimuths ``offset + k * 360 / n`` wrapped to ``[0, 360)`` degrees, float32."""
    return np.mod(offset_deg + np.arange(n) * (360.0 / n), 360.0).astype(np.float32)
