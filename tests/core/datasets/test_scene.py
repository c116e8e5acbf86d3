"""Scene set-up (cerberus_core.datasets.scene): the camera fitted to the body, the light, the stored form."""
from __future__ import annotations

import itertools
from dataclasses import replace

import numpy as np
import pytest
import torch

from cerberus_core.bodies.body import FILL
from cerberus_core.datasets.scene import SceneSetup, evenly_spaced, fit_distance, read_scene
from cerberus_core.errors import DatasetError


@pytest.mark.parametrize("elevation", [10.0, 15.0, 20.0])
def test_fitted_distance_keeps_the_body_cube_in_frame(elevation):
    scene = SceneSetup(elevation=elevation)
    corners = torch.tensor(list(itertools.product((-FILL / 2, FILL / 2), repeat=3)), dtype=torch.float32)
    az = torch.arange(0.0, 360.0, 1.0)
    uv, depth = scene.cameras(az, 64).project(corners.expand(len(az), -1, -1))
    assert bool((depth > 0).all())
    assert float(uv.min()) >= 0 and float(uv.max()) <= 64  # never clipped, from any azimuth
    assert float(uv.min()) < 4 or float(uv.max()) > 60  # and tight: the cube nearly touches the border
    closer = SceneSetup(elevation=elevation, distance=0.9 * scene.distance).cameras(az, 64)
    uv2, _ = closer.project(corners.expand(len(az), -1, -1))
    assert float(uv2.min()) < 0 or float(uv2.max()) > 64


def test_scene_dict_round_trip_and_light_follows_camera():
    scene = SceneSetup(elevation=12.0, fov_y=35.0)
    assert scene.distance == fit_distance(35.0, 12.0)
    back = read_scene(scene.to_dict())
    assert back == scene
    assert back.to_dict() == scene.to_dict()  # one stored form, both ways
    with pytest.raises(ValueError, match="unknown config key.*'scene.elevaton'.*did you mean 'scene.elevation'"):
        read_scene({**scene.to_dict(), "elevaton": 10.0})
    with pytest.raises(ValueError, match="scene.light"):
        read_scene({**scene.to_dict(), "light": {"type": "point"}})
    cam = scene.cameras([0.0, 90.0], 64)
    light = scene.light(cam)
    torch.testing.assert_close(light.direction, torch.nn.functional.normalize(cam.center, dim=-1))
    assert light.ambient[0, 0].item() == pytest.approx(scene.ambient)
    assert light.diffuse[0, 0].item() == pytest.approx(scene.diffuse)
    np.testing.assert_allclose(evenly_spaced(300.0, 4), [300, 30, 120, 210])


def test_view_records_give_the_generators_cameras():
    from cerberus_core.datasets.format import VIEW_DTYPE

    scene = SceneSetup(elevation=20.0, distance=2.5)
    rec = np.zeros(3, VIEW_DTYPE)
    rec["azimuth"], rec["elevation"], rec["distance"], rec["fov_y"] = [0, 45, 200], 20.0, 2.5, scene.fov_y
    stored, rendered = scene.view_cameras(rec, (32, 48)), scene.cameras(rec["azimuth"], (32, 48))
    torch.testing.assert_close(stored.rotation, rendered.rotation)
    torch.testing.assert_close(stored.translation, rendered.translation)
    assert (stored.height, stored.width) == (32, 48)
    with pytest.raises(DatasetError, match="fov_y"):
        scene.view_cameras({"azimuth": [0.0], "elevation": [1.0], "distance": [2.0]}, 32)


@pytest.mark.parametrize("radius", [0.2, 0.4])
def test_framed_distance_fits_a_vertical_cylinder_tightly(radius):
    """``fitted_radius``: the camera is fitted to a vertical cylinder around an upright body instead
    of the cube: nearer, every rim point in frame from any azimuth, and tight."""
    scene = SceneSetup(fitted_radius=radius)
    assert scene.distance < SceneSetup().distance
    th = torch.deg2rad(torch.arange(0.0, 360.0, 3.0))
    rim = torch.stack([radius * torch.cos(th), torch.zeros_like(th), radius * torch.sin(th)], -1)
    pts = torch.cat([rim + torch.tensor([0.0, -FILL / 2, 0.0]), rim + torch.tensor([0.0, FILL / 2, 0.0])])
    az = torch.arange(0.0, 360.0, 5.0)
    uv, _ = scene.cameras(az, 64).project(pts.expand(len(az), -1, -1))
    assert float(uv.min()) >= 0 and float(uv.max()) <= 64
    closer = replace(scene, distance=0.95 * scene.distance).cameras(az, 64)
    uv2, _ = closer.project(pts.expand(len(az), -1, -1))
    assert float(uv2.min()) < 0 or float(uv2.max()) > 64
    assert read_scene(scene.to_dict()) == scene and scene.to_dict()["fitted_radius"] == radius
    assert "fitted_radius" not in SceneSetup().to_dict()  # the paper's set-up keeps its stored form
    with pytest.raises(ValueError, match=r"scene.fitted_radius = 0.0: must be a number > 0"):
        SceneSetup(fitted_radius=0.0)
