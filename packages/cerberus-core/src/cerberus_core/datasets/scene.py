"""The paper's scene set-up for every rendered view of a dataset.

Section 5 of the paper: "We fix the elevation angle and distance to the origin of all viewpoints but
vary the azimuth angles. On scene set-ups, we use a directional light following the direction of the
camera and an ambient light, all in white." Bodies have one uniform albedo and arrive normalised
into ``[-FILL/2, FILL/2]^3`` (:mod:`cerberus_core.bodies.body`).

The camera distance is *fitted*: the smallest distance at which every corner of the cube
``[-FILL/2, FILL/2]^3`` (hence every body) stays inside the frame, with a margin, from every
azimuth at the fixed elevation. Bodies thus fill most of the frame and are never clipped.

:class:`SceneSetup` is the one owner of a dataset's scene: cameras (from azimuths when rendering,
from stored view records when reading: :meth:`SceneSetup.view_cameras`), the light and the
background. The manifest stores it as :meth:`SceneSetup.to_dict`, which :func:`read_scene` reads back
exactly (``read_scene(d).to_dict() == d``) with :func:`cerberus_core.config.build`, like every settings
section; the readers' ``.scene`` and the trainer use the object.
"""
from __future__ import annotations

import itertools
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass
from functools import lru_cache
from typing import Any

import numpy as np
import torch

from cerberus_core.bodies.body import FILL
from cerberus_core.config import build, omit_defaults
from cerberus_core.errors import ConfigError, DatasetError
from cerberus_core.fields import Checked, ranged
from cerberus_core.render.camera import Camera
from cerberus_core.render.light import Light

Tensor = torch.Tensor


def _frame_points(extent: float, radius: float | None) -> np.ndarray:
    """Points whose projections must stay in the frame: the corners of the cube of side ``extent``,
    or (``radius`` given) a vertical cylinder of that radius and height ``extent`` (its rims, every
    5 degrees)."""
    if radius is None:
        return np.array(list(itertools.product((-0.5, 0.5), repeat=3))) * extent  # (8, 3)
    th = np.deg2rad(np.arange(0.0, 360.0, 5.0))
    rim = np.stack([radius * np.cos(th), np.zeros_like(th), radius * np.sin(th)], -1)
    return np.concatenate([rim + [0.0, -extent / 2, 0.0], rim + [0.0, extent / 2, 0.0]])


@lru_cache(maxsize=64)
def fit_distance(fov_y_deg: float, elevation_deg: float, extent: float = FILL, margin: float = 0.04,
                 radius: float | None = None) -> float:
    """Smallest camera distance at which a body-sized volume fits the frame from every azimuth.

    The volume is the cube ``[-extent/2, extent/2]^3`` (the paper-faithful set-up: any body in the
    normalised cube fits, however it is oriented) or, with ``radius``, the vertical cylinder of that
    radius and height ``extent`` (framed to upright bodies: a standing human of height ``extent``
    fills more of the frame). It is seen from azimuths every 2.5 degrees at ``elevation_deg``; every
    point must project inside the square image shrunk by ``margin`` (a fraction of the half-width)
    on each side.

    Args:
        fov_y_deg: vertical (= horizontal, square images) field of view in degrees.
        elevation_deg: camera elevation in degrees.
        extent: side of the cube / height of the cylinder (normalised units).
        margin: fraction of the half image kept free around the volume.
        radius: the cylinder's radius (normalised units); ``None``: the cube.

    Returns:
        The distance in normalised units, rounded up to 1e-3.
    """
    corners = _frame_points(extent, radius)
    az = np.deg2rad(np.arange(0.0, 360.0, 2.5))
    el = math.radians(elevation_deg)
    # Camera axes for each azimuth (look-at the origin, +Y up): forward f points to the origin.
    eye_dir = np.stack([math.cos(el) * np.sin(az), np.full_like(az, math.sin(el)), math.cos(el) * np.cos(az)], -1)
    right = np.stack([np.cos(az), np.zeros_like(az), -np.sin(az)], -1)
    up = np.cross(eye_dir, right)
    limit = math.tan(math.radians(fov_y_deg) / 2) * (1 - margin)

    def fits(dist: float) -> bool:
        rel = corners[None] - dist * eye_dir[:, None]  # (A, P, 3) camera-centred
        depth = -(rel * eye_dir[:, None]).sum(-1)
        x = (rel * right[:, None]).sum(-1) / depth
        y = (rel * up[:, None]).sum(-1) / depth
        return bool((depth > 0).all() and (np.abs(x) <= limit).all() and (np.abs(y) <= limit).all())

    lo, hi = extent * 0.5, extent * 100.0
    if not fits(hi):
        raise ConfigError.about("scene.fov_y", fov_y_deg, "too narrow to frame a body at any distance",
                                "widen `scene.fov_y`")
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if fits(mid) else (mid, hi)
    return math.ceil(hi * 1000) / 1000


@dataclass(frozen=True)
class SceneSetup(Checked):
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
        fitted_extent: side of the cube (or height of the cylinder) the distance is fitted to.
        fitted_radius: ``None`` (default, the paper-faithful set-up): fit the distance to the cube
            ``[-fitted_extent/2, fitted_extent/2]^3``, which any normalised body fits; a radius
            (normalised units): fit it to the vertical cylinder of that radius, *framed to the
            body* (a standing human fills most of the frame's height; a body reaching further
            out than the cylinder from the axis may touch the frame's edge). Omitted from
            :meth:`to_dict` when ``None``, so older manifests keep their hash.
    """

    elevation: float = ranged(15.0, gt=-90, lt=90)
    fov_y: float = ranged(30.0, gt=0, lt=180)
    distance: float | None = None
    ambient: float = ranged(0.4, ge=0)
    diffuse: float = ranged(0.6, ge=0)
    albedo: tuple[float, float, float] = (0.8, 0.8, 0.8)
    background: tuple[float, float, float] = (1.0, 1.0, 1.0)
    near: float = ranged(0.05, gt=0)
    far: float = 100.0
    fitted_extent: float = ranged(FILL, gt=0)
    fitted_radius: float | None = ranged(None, gt=0, integer=False)

    SECTION = "scene"

    def validate(self) -> None:
        """Fits a missing ``distance`` (:func:`fit_distance`), then checks the clipping planes around it and
        the colours."""
        if self.distance is None:
            object.__setattr__(self, "distance", fit_distance(self.fov_y, self.elevation, self.fitted_extent,
                                                               radius=self.fitted_radius))
        if self.distance <= self.near:
            raise ConfigError(f"scene.distance {self.distance} must exceed the near plane {self.near}", key="scene.distance", value=self.distance)
        if self.far <= self.distance:
            raise ConfigError(f"scene.far {self.far} must exceed the distance {self.distance} (the body sits "
                              "at the origin)", key="scene.far", value=self.far)
        object.__setattr__(self, "albedo", tuple(float(a) for a in self.albedo))
        object.__setattr__(self, "background", tuple(float(b) for b in self.background))
        for name in ("albedo", "background"):
            if not all(0.0 <= c <= 1.0 for c in getattr(self, name)):
                raise ConfigError(f"scene.{name} {list(getattr(self, name))}: RGB values must lie in [0, 1]", key=f"scene.{name}", value=getattr(self, name))

    LIGHT = {"type": "directional+ambient", "follows_camera": True, "colour": "white"}
    """The only light there is (stored in the manifest for readers of the JSON): white directional
    along each camera's viewing direction plus white ambient (:meth:`light`)."""

    def to_dict(self) -> dict:
        """JSON-ready dict (as stored in the manifest's ``scene`` and ``config.scene``)."""
        d = asdict(self)
        d["albedo"], d["background"] = list(self.albedo), list(self.background)
        d = omit_defaults(d, {"fitted_radius": None})
        d["light"] = dict(self.LIGHT)
        return d

    def cameras(self, azimuth_deg: Tensor | np.ndarray | list[float], image_size: int,
                device: torch.device | str | None = None) -> Camera:
        """``B`` cameras at the given azimuths (degrees) with this set-up's elevation, distance and fov
        (how the generator renders)."""
        az = torch.as_tensor(np.ascontiguousarray(np.asarray(azimuth_deg, dtype=np.float32)), device=device).reshape(-1)
        return Camera.look_at(az, self.elevation, self.distance, fov_y_deg=self.fov_y, image_size=image_size,
                              near=self.near, far=self.far, device=device)

    VIEW_KEYS = ("azimuth", "elevation", "distance", "fov_y")
    """What a view record holds about its camera (degrees, degrees, normalised units, degrees)."""

    def view_cameras(self, views: Mapping | np.ndarray, image_size: int | tuple[int, int], *,
                     slot: int | None = None, device: torch.device | str | None = None) -> Camera:
        """Cameras of stored view records (how readers and the trainer see a dataset's images).

        Args:
            views: anything indexable by :attr:`VIEW_KEYS`, each of any shape: a (collated) batch of
                dataset items (``(B, 4)`` quadruplets, ``(B,)`` views, unbatched) or
                :data:`~cerberus_core.datasets.format.VIEW_DTYPE` records.
            image_size: square size or ``(H, W)`` in pixels (the training resolution may differ
                from the dataset's).
            slot: take ``[..., slot]`` of each field first (quadruplets: image slot 0..3 of
                ``a0, a1, b0, b1`` → ``B`` cameras); ``None`` → every view, flattened row-major
                (``B * 4`` cameras matching ``batch["images"].flatten(0, 1)``).
            device: where the cameras live (default: the device of ``views["azimuth"]``).

        Returns:
            :class:`Camera` with this set-up's clipping planes.
        """
        if device is None:
            az = views["azimuth"]
            device = az.device if isinstance(az, Tensor) else None

        def flat(key: str) -> Tensor:
            try:
                value = views[key]
            except (KeyError, ValueError, IndexError):
                raise DatasetError(f"view records lack {key!r}; every view needs {', '.join(self.VIEW_KEYS)}") from None
            if isinstance(value, (np.ndarray, np.generic)):
                value = np.array(value, dtype=np.float32)  # a copy: memory-mapped records are read-only
            t = torch.as_tensor(value).to(device=device, dtype=torch.float32)
            if slot is not None:
                t = t[..., slot]
            return t.reshape(-1)

        return Camera.look_at(flat("azimuth"), flat("elevation"), flat("distance"), fov_y_deg=flat("fov_y"),
                              image_size=image_size, near=self.near, far=self.far, device=device)

    def light(self, camera: Camera) -> Light:
        """White directional light along each camera's viewing direction plus white ambient."""
        return Light.following(camera, ambient=self.ambient, diffuse=self.diffuse)


def evenly_spaced(offset_deg: float, n: int) -> np.ndarray:
    """``n`` azimuths ``offset + k * 360 / n`` wrapped to ``[0, 360)`` degrees, float32."""
    return np.mod(offset_deg + np.arange(n) * (360.0 / n), 360.0).astype(np.float32)


def read_scene(record: Any, key: str = "scene") -> SceneSetup:
    """The set-up of a :meth:`SceneSetup.to_dict` record (a manifest's ``scene``, a model file's recorded one;
    missing keys take the defaults), read by :func:`cerberus_core.config.build` like any settings section.

    Args:
        key: where the record sits, for messages (``scene``, ``config.scene``).
    Raises:
        ConfigError: not a mapping, an unknown key, a value of the wrong type (a number that is a string, NaN,
            an RGB that is not 3 numbers), a value out of range, or a light other than :attr:`SceneSetup.LIGHT`.
    """
    if isinstance(record, Mapping) and "light" in record:  # written for readers of the JSON; only one is known
        if record["light"] != SceneSetup.LIGHT:
            raise ConfigError.about(f"{key}.light", record["light"], f"only {SceneSetup.LIGHT} is supported")
        record = {k: v for k, v in record.items() if k != "light"}
    return build(SceneSetup, record, f"{key}.")
