"""Backends against closed-form answers: a sphere's projected area, its nearest depth, its shading."""
from __future__ import annotations

import math

import pytest
import torch

from cerberus_core.render.api import render
from cerberus_core.render.camera import Camera
from cerberus_core.render.light import Light
from cerberus_core.render.templates import icosphere

RADIUS, DISTANCE, FOV, SIZE, LEVEL = 0.5, 2.5, 30.0, 129, 4  # odd size: the centre pixel is on the axis
VIEWS = [(0.0, 0.0), (37.0, 25.0), (200.0, -60.0)]


def _inradius(level: int) -> float:
    """Smallest distance from the centre of the unit icosphere to a face plane."""
    t = icosphere(level)
    v, f = t.vertices.double(), t.faces
    n = torch.nn.functional.normalize(torch.linalg.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]]), dim=-1)
    return float((n * v[f[:, 0]]).sum(-1).abs().min())


def _disc_area_pixels(radius: float) -> float:
    """Pixel area of the silhouette of a sphere centred on the optical axis: a disc of NDC radius
    ``f r / sqrt(d^2 - r^2)`` (the tangent cone's cross-section)."""
    f = 1.0 / math.tan(math.radians(FOV) / 2)
    rho = f * radius / math.sqrt(DISTANCE**2 - radius**2) * SIZE / 2
    return math.pi * rho**2


def _render_sphere(renderer, light: tuple[float, float] = (0.4, 0.6), albedo=(0.8, 0.8, 0.8)):
    """The sphere centred at the origin seen from every view, lit by (ambient, diffuse) following the camera."""
    t = icosphere(LEVEL, radius=RADIUS)
    az = torch.tensor([v[0] for v in VIEWS])
    el = torch.tensor([v[1] for v in VIEWS])
    cam = Camera.look_at(az, el, DISTANCE, fov_y_deg=FOV, image_size=SIZE)
    verts = t.vertices.unsqueeze(0).expand(len(VIEWS), -1, -1)
    return render(renderer, verts, t.faces, cam, Light.following(cam, *light), albedo=albedo)


@pytest.fixture(scope="module")
def sphere_inradius() -> float:
    return RADIUS * _inradius(LEVEL)


@pytest.fixture(scope="module")
def sphere(renderer):
    """The sphere rendered once per backend with the default light."""
    return _render_sphere(renderer)


def test_alpha_coverage_is_the_projected_disc(sphere, sphere_inradius: float) -> None:
    out = sphere
    hi, lo = _disc_area_pixels(RADIUS), _disc_area_pixels(sphere_inradius)  # the mesh lies between
    pixels = math.sqrt(hi / math.pi)
    slack = 2 * pixels ** (2 / 3)  # lattice-count error of a disc of radius R pixels is O(R^(2/3))
    for b, count in enumerate(out.alpha.sum((1, 2, 3)).tolist()):
        assert lo - slack <= count <= hi + slack, f"view {VIEWS[b]}: {count} pixels, expected {lo:.0f}..{hi:.0f}"


def test_depth_at_the_centre_is_distance_minus_radius(sphere, sphere_inradius: float) -> None:
    out = sphere
    centre = out.depth[:, 0, SIZE // 2, SIZE // 2]
    # The axis meets the inscribed mesh between the inscribed and the circumscribed sphere.
    assert (centre >= DISTANCE - RADIUS - 1e-5).all() and (centre <= DISTANCE - sphere_inradius + 1e-5).all(), centre
    assert (out.depth[:, 0, 0, 0] == 0).all(), "background depth is 0"


def test_light_following_the_camera_lights_the_centre_fully(renderer) -> None:
    albedo, ambient, diffuse = torch.tensor([0.9, 0.5, 0.2]), 0.3, 0.5
    out = _render_sphere(renderer, (ambient, diffuse), albedo=albedo)
    full = albedo * (ambient + diffuse)
    centre = out.image[:, :, SIZE // 2, SIZE // 2]
    # Interpolated normals deviate from the view axis by the tessellation only: cos >= 0.999.
    assert torch.all(centre <= full + 1e-6) and torch.all(centre >= albedo * (ambient + 0.999 * diffuse)), centre
    # Towards the silhouette the surface turns away from the light: darker, but never below ambient.
    row = out.image[:, :, SIZE // 2]
    inside = out.alpha[:, 0, SIZE // 2] > 0
    edge = inside.float().argmax(-1)  # first covered column from the left
    for b in range(len(VIEWS)):
        rim = row[b, :, edge[b]]
        assert torch.all(rim < centre[b] - 0.05) and torch.all(rim >= albedo * ambient - 1e-6), (rim, centre[b])
