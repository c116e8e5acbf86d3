"""Awkward scenes: each gives a defined result or a clear error, never a crash or a silent NaN."""
from __future__ import annotations

import pytest
import torch

from cerberus_core.render.api import render, render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.templates import icosphere

BACKGROUND = (0.1, 0.2, 0.3)


def _camera(batch: int = 2, size: int = 24) -> Camera:
    return Camera.look_at(torch.tensor([0.0, 90.0])[:batch], 0.0, 2.5, fov_y_deg=30.0, image_size=size)


def _render_with_grad(renderer, parts: torch.Tensor, faces: torch.Tensor | None = None, camera: Camera | None = None):
    """Render, back-propagate a loss over image and depth; return the output and the vertex gradient."""
    camera = camera or _camera(parts.shape[0])
    faces = icosphere(2).faces if faces is None else faces
    p = parts.clone().requires_grad_(True)
    out = render_parts(renderer, p, faces, camera, background=BACKGROUND)
    (out.image.square().sum() + out.depth.sum()).backward()
    for name in ("image", "alpha", "depth"):
        assert torch.isfinite(getattr(out, name)).all(), f"{name} has NaN/inf"
    grad = p.grad if p.grad is not None else torch.zeros_like(p)
    assert torch.isfinite(grad).all(), "NaN/inf in the vertex gradients"
    return out, grad


def _sphere(batch: int, radius: float = 0.3, offset=(0.0, 0.0, 0.0)) -> torch.Tensor:
    v = icosphere(2).vertices * radius + torch.tensor(offset)
    return v.expand(batch, 1, -1, -1).clone()


def _assert_background(out) -> None:
    assert (out.face_id == -1).all() and (out.part_id == -1).all()
    assert (out.alpha == 0).all() and (out.depth == 0).all()
    assert torch.allclose(out.image, torch.tensor(BACKGROUND).view(1, 3, 1, 1).expand_as(out.image))


def test_empty_scenes(renderer) -> None:
    out, grad = _render_with_grad(renderer, torch.zeros(2, 0, 162, 3))  # no parts
    _assert_background(out)
    assert out.image.shape == (2, 3, 24, 24) and grad.shape == (2, 0, 162, 3)
    out, _ = _render_with_grad(renderer, torch.zeros(2, 1, 3, 3), faces=torch.zeros(0, 3, dtype=torch.int64))
    _assert_background(out)  # vertices but no faces


@pytest.mark.parametrize("where", ["behind the camera", "outside the image", "crossing the camera"])
def test_invisible_parts_render_background_with_zero_gradient(renderer, where: str) -> None:
    # Camera 0 sits at (0, 0, 2.5) looking down -Z, camera 1 at (2.5, 0, 0) looking down -X.
    offset = {"behind the camera": (4.0, 0.0, 4.0), "outside the image": (0.0, 3.0, 0.0),
              "crossing the camera": None}[where]
    if offset is None:  # a sphere around each camera centre: every triangle reaches behind the near plane
        parts = torch.stack([_sphere(1, 0.04, (0.0, 0.0, 2.5))[0], _sphere(1, 0.04, (2.5, 0.0, 0.0))[0]])
    else:
        parts = _sphere(2, 0.3, offset)
    out, grad = _render_with_grad(renderer, parts)
    _assert_background(out)
    assert (grad == 0).all()


def test_zero_area_triangles(renderer) -> None:
    parts = _sphere(2).clone()
    faces = icosphere(2).faces
    parts[:, 0, faces[:40].flatten()] = parts[:, 0, :1]  # 40 faces' vertices merged into one point
    out, grad = _render_with_grad(renderer, parts)
    assert out.alpha.sum() > 0, "the rest of the sphere is still drawn"
    collapsed = torch.unique(faces[:40].flatten())
    assert not torch.isin(out.face_id, torch.arange(40)).any(), "a zero-area triangle covers no pixel"
    assert grad.abs().sum() > 0 and collapsed.numel() > 3
    point, grad = _render_with_grad(renderer, torch.zeros(2, 1, 162, 3))  # a part collapsed to a point
    _assert_background(point)
    assert (grad == 0).all()


def test_edge_on_part(renderer) -> None:
    parts = _sphere(2).clone()
    parts[..., 2] = 0.0  # flat in z: seen face-on by camera 0 (on +Z), exactly edge-on by camera 1 (on +X)
    out, _ = _render_with_grad(renderer, parts)
    assert out.alpha[0].sum() > 0
    assert out.alpha[1].sum() == 0, "a part seen exactly edge-on covers no pixel centre"


def test_very_large_vertices(renderer) -> None:
    # A huge sphere around both cameras: every pixel sees its inside, far away.
    out, grad = _render_with_grad(renderer, _sphere(2, 1e6))
    assert (out.alpha == 1).all()
    assert ((out.depth > 0.9e6) & (out.depth < 1.1e6)).all()
    # Beyond float32's range for the edge functions: a clear error or a finite result.
    try:
        _render_with_grad(renderer, _sphere(2, 1e20))
    except ValueError as exc:
        assert "1e+08" in str(exc) or "range" in str(exc), exc


@pytest.mark.parametrize("bad", [float("nan"), float("inf"), -float("inf")])
def test_non_finite_vertices_are_a_clear_error(renderer, bad: float) -> None:
    parts = _sphere(2)
    parts[1, 0, 7, 2] = bad
    with pytest.raises(ValueError, match=r"vertex 7 of scene 1 is NaN or inf"):
        render_parts(renderer, parts, icosphere(2).faces, _camera())


def test_gradients_stay_finite_on_a_busy_scene(renderer) -> None:
    """Overlapping parts, grazing and near-plane triangles together in one batch."""
    parts = torch.cat([_sphere(2, 0.3), _sphere(2, 0.25, (0.1, 0.05, 0.2)), _sphere(2, 0.3, (0.0, 0.0, 2.3)),
                       _sphere(2, 0.2, (0.0, 0.2, -0.4))], dim=1)
    out, grad = _render_with_grad(renderer, parts)
    assert set(out.part_id.unique().tolist()) >= {-1, 0, 1, 2}
    assert grad.abs().sum() > 0


def test_single_mesh_render_matches_render_parts(renderer) -> None:
    """``render`` on one packed mesh and ``render_parts`` on its parts agree exactly."""
    parts = torch.cat([_sphere(2, 0.3), _sphere(2, 0.2, (0.2, 0.1, 0.3))], dim=1)
    faces = icosphere(2).faces
    cam = _camera()
    a = render_parts(renderer, parts, faces, cam)
    b = render(renderer, parts.reshape(2, -1, 3), torch.cat([faces, faces + 162]), cam)
    assert torch.equal(a.face_id, b.face_id) and torch.equal(a.image, b.image)


def test_bad_inputs_are_typed_errors_from_the_op_before_the_backend(renderer):
    """Each op of cerberus_core.render.ops checks shapes, dtypes and devices once, for every backend (the
    backends do not check again): ShapeError / DeviceError naming the op and the tensor; rasterize and
    vertex_normals also the face indices (MeshError)."""
    from cerberus_core.errors import DeviceError, MeshError, ShapeError
    from cerberus_core.render import ops
    from cerberus_core.render.light import Light

    cam = _camera(1, 8)
    sphere = icosphere(1)
    v = 0.3 * sphere.vertices[None]
    clip, faces = cam.world_to_clip(v), sphere.faces
    with pytest.raises(ShapeError, match=r"rasterize: clip must be \(B, V, 4\)"):
        ops.rasterize(renderer, clip[..., :3], faces, (8, 8), cam.near)
    with pytest.raises(ShapeError, match="rasterize: clip must be float32 or float64, got float16"):
        ops.rasterize(renderer, clip.half(), faces, (8, 8), cam.near)
    with pytest.raises(ShapeError, match=r"rasterize: faces must be \(F, 3\)"):
        ops.rasterize(renderer, clip, faces.view(-1), (8, 8), cam.near)
    with pytest.raises(ValueError, match="image size must be positive"):
        ops.rasterize(renderer, clip, faces, (0, 8), cam.near)
    with pytest.raises(DeviceError, match="rasterize: clip, faces must be on one device, got cpu, meta"):
        ops.rasterize(renderer, clip, faces.to("meta"), (8, 8), cam.near)
    for bad in (faces + v.shape[1], faces - 1):  # faces outside the vertices: refused before a kernel reads them
        with pytest.raises(MeshError, match="rasterize: faces index vertices outside 0..41"):
            ops.rasterize(renderer, clip, bad, (8, 8), cam.near)
        with pytest.raises(MeshError, match="vertex_normals: faces index vertices outside 0..41"):
            ops.vertex_normals(renderer, v, bad)
    face_id = ops.rasterize(renderer, clip, faces, (8, 8), cam.near)
    normals = ops.vertex_normals(renderer, v, faces)
    albedo, light = torch.full_like(v, 0.8), Light.following(cam)
    with pytest.raises(ShapeError, match="shade: normals must be"):
        ops.shade(renderer, clip, faces, face_id, normals[:, :-1], albedo, light)
    with pytest.raises(ShapeError, match="shade: light.ambient must be"):
        ops.shade(renderer, clip, faces, face_id, normals, albedo,
                  Light(light.direction, light.ambient[:, :2], light.diffuse))
    with pytest.raises(ShapeError, match="shade: face_id must be"):
        ops.shade(renderer, clip, faces, face_id[0], normals, albedo, light)
    with pytest.raises(ShapeError, match=r"vertex_normals: vertices must be \(B, V, 3\)"):
        ops.vertex_normals(renderer, v[0], faces)
    with pytest.raises(ShapeError, match="antialias: face_id must be int64"):
        ops.antialias(renderer, torch.zeros(1, 8, 8, 4), clip, faces, face_id.int())
