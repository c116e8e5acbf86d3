"""Camera conventions, projection and unprojection (cerberus_core.render.camera)."""
from __future__ import annotations

import math

import pytest
import torch

from cerberus_core.render.camera import Camera, default_fov_for

ATOL = 1e-5


def _points_in_view(camera: Camera, n: int = 50, seed: int = 0) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return (torch.rand(camera.batch_size, n, 3, generator=g) - 0.5)  # inside [-0.5, 0.5]^3


@pytest.fixture
def cams() -> Camera:
    return Camera.look_at(torch.tensor([0.0, 73.0, -150.0]), torch.tensor([0.0, 20.0, -35.0]),
                          torch.tensor([2.5, 3.0, 2.0]), fov_y_deg=torch.tensor([30.0, 45.0, 20.0]),
                          image_size=(48, 80))


def test_project_unproject_round_trip_world_frame(cams: Camera) -> None:
    pts = _points_in_view(cams)
    uv, depth = cams.project(pts)
    assert uv.shape == (3, 50, 2) and depth.shape == (3, 50) and (depth > 0).all()
    torch.testing.assert_close(cams.unproject(uv, depth), pts, rtol=0, atol=ATOL)


def test_project_unproject_round_trip_camera_frame(cams: Camera) -> None:
    pts = _points_in_view(cams, seed=1)
    uv, depth = cams.project(pts)
    cam_pts = cams.unproject(uv, depth, to_world=False)
    torch.testing.assert_close(cam_pts, cams.world_to_camera(pts), rtol=0, atol=ATOL)
    torch.testing.assert_close(cam_pts[..., 2], -depth, rtol=0, atol=ATOL)  # depth = -z_cam
    torch.testing.assert_close(cams.camera_to_world(cam_pts), pts, rtol=0, atol=ATOL)


def test_look_at_conventions() -> None:
    d = 2.5
    front, side, top = (Camera.look_at(az, el, d) for az, el in ((0.0, 0.0), (90.0, 0.0), (0.0, 90.0)))
    torch.testing.assert_close(front.center, torch.tensor([[0.0, 0.0, d]]), rtol=0, atol=ATOL)  # az 0: on +Z
    torch.testing.assert_close(side.center, torch.tensor([[d, 0.0, 0.0]]), rtol=0, atol=ATOL)   # az 90: on +X
    torch.testing.assert_close(top.center, torch.tensor([[0.0, d, 0.0]]), rtol=0, atol=ATOL)    # el 90: above
    # Each camera looks at the origin along its -z axis: the origin is at depth d in the image centre.
    for cam in (front, side, top):
        uv, depth = cam.project(torch.zeros(1, 1, 3))
        torch.testing.assert_close(uv, torch.tensor([[[32.0, 32.0]]]), rtol=0, atol=ATOL)
        torch.testing.assert_close(depth, torch.tensor([[d]]), rtol=0, atol=ATOL)
        r = cam.rotation[0]
        torch.testing.assert_close(r @ r.T, torch.eye(3), rtol=0, atol=ATOL)
        assert abs(float(torch.linalg.det(r)) - 1) < ATOL
    torch.testing.assert_close(top.rotation[0, 2], torch.tensor([0.0, 1.0, 0.0]), rtol=0, atol=ATOL)  # looks down -Y
    # az 0: world +X is image right, +Y is image up (v decreases); az 90: world -Z is image right.
    uv, _ = front.project(torch.tensor([[[0.1, 0.0, 0.0], [0.0, 0.1, 0.0]]]))
    assert uv[0, 0, 0] > 32 and abs(uv[0, 0, 1] - 32) < ATOL and uv[0, 1, 1] < 32
    uv, _ = side.project(torch.tensor([[[0.0, 0.0, -0.1]]]))
    assert uv[0, 0, 0] > 32
    # Positive azimuth turns the camera towards +X; positive elevation lifts it towards +Y.
    c = Camera.look_at(30.0, 20.0, d).center[0]
    assert c[0] > 0 and c[1] > 0 and abs(float(c.norm()) - d) < ATOL


def test_view_direction_points_to_the_camera(cams: Camera) -> None:
    torch.testing.assert_close(cams.view_direction(), torch.nn.functional.normalize(cams.center, dim=-1),
                               rtol=0, atol=ATOL)


def test_ndc_pixel_conversions() -> None:
    cam = Camera.look_at(0.0, 0.0, 2.0, image_size=(4, 8))
    corners = torch.tensor([[-1.0, 1.0], [1.0, -1.0], [0.0, 0.0]])
    torch.testing.assert_close(cam.ndc_to_pixel(corners), torch.tensor([[0.0, 0.0], [8.0, 4.0], [4.0, 2.0]]))
    # Pixel (row 0, col 0) has its centre at (u, v) = (0.5, 0.5).
    torch.testing.assert_close(cam.pixel_to_ndc(torch.tensor([0.5, 0.5])), torch.tensor([-1 + 1 / 8, 1 - 1 / 4]))
    uv = torch.rand(10, 2) * torch.tensor([8.0, 4.0])
    torch.testing.assert_close(cam.ndc_to_pixel(cam.pixel_to_ndc(uv)), uv)


def test_clip_space_follows_opengl() -> None:
    cam = Camera.look_at(0.0, 0.0, 3.0, fov_y_deg=60.0, image_size=(40, 80), near=0.5, far=10.0)
    pts = torch.tensor([[[0.0, 0.0, 2.5], [0.0, 0.0, -7.0], [0.4, 0.3, 0.0]]])  # depths 0.5, 10, 3
    clip = cam.world_to_clip(pts)
    torch.testing.assert_close(clip[0, :, 3], torch.tensor([0.5, 10.0, 3.0]))  # w = depth
    torch.testing.assert_close(clip[0, :2, 2] / clip[0, :2, 3], torch.tensor([-1.0, 1.0]))  # near -> -1, far -> 1
    f = 1 / math.tan(math.radians(30.0))
    torch.testing.assert_close(clip[0, 2, :2], torch.tensor([0.4 * f / 2, 0.3 * f]))  # aspect 2


def test_batching_helpers(cams: Camera) -> None:
    sub = cams.index([2, 0])
    torch.testing.assert_close(sub.rotation, cams.rotation[[2, 0]])
    both = Camera.cat([sub, cams])
    assert both.batch_size == 5 and (both.height, both.width) == (48, 80)
    assert cams.to("cpu").batch_size == 3
    torch.testing.assert_close(cams.rotation_to_world(cams.rotation), torch.eye(3).expand(3, 3, 3), rtol=0, atol=ATOL)
    with pytest.raises(ValueError, match="share image size"):
        Camera.cat([cams, Camera.look_at(0.0, 0.0, 2.0, image_size=32)])


@pytest.mark.parametrize("kwargs, message", [
    (dict(fov_y_deg=0.0), "fov_y_deg"), (dict(fov_y_deg=180.0), "fov_y_deg"), (dict(image_size=0), "image size"),
    (dict(near=1.0, far=0.5), "near < far"), (dict(distance=-1.0), "distance must be positive"),
])
def test_invalid_cameras_are_clear_errors(kwargs: dict, message: str) -> None:
    args = dict(azimuth_deg=0.0, elevation_deg=0.0, distance=2.0) | kwargs
    with pytest.raises(ValueError, match=message):
        Camera.look_at(**args)


def test_default_fov_fits_the_unit_cube() -> None:
    fov = default_fov_for(2.5)
    corners = torch.tensor([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
    cam = Camera.look_at(torch.arange(0.0, 360.0, 30.0), 35.0, 2.5, fov_y_deg=fov, image_size=64)
    uv, _ = cam.project(corners.expand(cam.batch_size, -1, -1))
    assert ((uv >= 0) & (uv <= 64)).all()
    assert 0 < fov < 90


@pytest.mark.parametrize("pole", [90.0, -90.0])
def test_look_at_is_continuous_at_the_poles(pole: float) -> None:
    """Elevation exactly +-90 gives (almost) the rotation of elevations approaching it at azimuth 0."""
    exact = Camera.look_at(0.0, pole, 2.0).rotation
    near = Camera.look_at(0.0, pole - math.copysign(1e-3, pole), 2.0).rotation
    assert torch.allclose(exact, near, atol=1e-4)



def test_spherical_inverts_look_at_and_orbit_turns_the_azimuth() -> None:
    cam = Camera.look_at(torch.tensor([-120.0, 0.0, 75.0]), torch.tensor([10.0, -20.0, 45.0]), 2.5)
    az, el, dist = cam.spherical()
    torch.testing.assert_close(az, torch.tensor([-120.0, 0.0, 75.0]), atol=1e-4, rtol=0)
    torch.testing.assert_close(el, torch.tensor([10.0, -20.0, 45.0]), atol=1e-4, rtol=0)
    torch.testing.assert_close(dist, torch.full((3,), 2.5))
    turned = cam.index([1]).orbit([90.0, -30.0])
    assert turned.batch_size == 2
    torch.testing.assert_close(turned.spherical()[0], torch.tensor([90.0, -30.0]), atol=1e-4, rtol=0)
    torch.testing.assert_close(turned.spherical()[1], torch.full((2,), -20.0), atol=1e-4, rtol=0)
    with pytest.raises(ValueError, match="one camera"):
        cam.orbit([10.0])


def test_the_transforms_take_points_of_another_float_dtype():
    """Issue 34 campaign: float64 vertices with a (float32) camera were a matmul dtype error in render()."""
    cam = Camera.look_at(30.0, 10.0, 2.5, image_size=16)
    points = torch.tensor([[[0.1, 0.2, 0.3], [-0.2, 0.0, 0.1]]])
    clip64 = cam.world_to_clip(points.double())
    assert clip64.dtype == torch.float64
    torch.testing.assert_close(clip64.float(), cam.world_to_clip(points))
    torch.testing.assert_close(cam.camera_to_world(cam.world_to_camera(points.double())), points.double())


def test_triangulate_finds_the_common_point_of_rays_with_batch_dimensions_and_stays_finite_on_parallel_rays():
    from cerberus_core.render.camera import triangulate

    g = torch.Generator().manual_seed(0)
    points = torch.randn(2, 5, 3, generator=g, dtype=torch.float64) * 0.3  # (batch 2, 5 points)
    origins = torch.randn(2, 3, 3, generator=g, dtype=torch.float64) * 2 + 3  # 3 cameras per batch element
    dirs = torch.nn.functional.normalize(points.unsqueeze(1) - origins.unsqueeze(2), dim=-1)  # (2, 3, 5, 3)
    torch.testing.assert_close(triangulate(origins, dirs, ridge=0.0), points)
    # two rays that miss each other: the midpoint of their closest points, (0, 0, 0.5) here
    o = torch.tensor([[0.0, 0.0, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    d = torch.tensor([[[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]]], dtype=torch.float64)
    torch.testing.assert_close(triangulate(o, d, ridge=0.0), torch.tensor([[0.0, 0.0, 0.5]], dtype=torch.float64))
    # the same ray twice: no intersection along it, yet a finite point on the ray (the ridge's pick)
    same = torch.tensor([[0.0, 0.0, 3.0], [0.0, 0.0, 3.0]])
    down = torch.tensor([[[0.0, 0.6, -0.8]], [[0.0, 0.6, -0.8]]])
    p = triangulate(same, down)
    assert torch.isfinite(p).all()
    assert torch.linalg.cross(p[0] - same[0], down[0, 0]).norm() < 1e-3


def test_rays_are_unit_directions_from_the_centre_through_their_pixels():
    cam = Camera.look_at(torch.tensor([30.0, -100.0]), 15.0, 2.0, fov_y_deg=30.0, image_size=64)
    uv = torch.tensor([[[10.5, 20.5], [32.0, 32.0]], [[60.0, 5.0], [1.0, 63.0]]])
    rays = cam.rays(uv)
    torch.testing.assert_close(rays.norm(dim=-1), torch.ones(2, 2))
    points = cam.center.unsqueeze(1) + 1.7 * rays  # any point along a ray projects back onto its pixel
    torch.testing.assert_close(cam.project(points)[0], uv, atol=1e-4, rtol=0)
