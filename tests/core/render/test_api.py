"""The user-facing render API (cerberus_core.render.api) with the torch backend: validation, output
layout, albedo forms and compositing."""
from __future__ import annotations

import pytest
import torch

from cerberus_core.render.api import pack_parts, render, render_parts
from cerberus_core.render.light import Light
from cerberus_core.render.templates import icosphere
from tests.support.scenes import two_sphere_scene


@pytest.fixture
def scene():
    return two_sphere_scene()


def test_output_layout(renderer, scene) -> None:
    parts, faces, cam = scene
    out = render_parts(renderer, parts, faces, cam)
    assert out.image.shape == (2, 3, 32, 48) and out.alpha.shape == (2, 1, 32, 48) and out.depth.shape == (2, 1, 32, 48)
    assert out.face_id.shape == out.part_id.shape == (2, 32, 48)
    assert out.face_id.dtype == out.part_id.dtype == torch.int64
    fg = out.face_id >= 0
    assert torch.equal(out.alpha[:, 0] == 1, fg) and torch.equal(out.alpha[:, 0] == 0, ~fg)
    assert torch.equal(out.part_id, torch.where(fg, out.face_id // faces.shape[0], -1))
    assert set(out.part_id.unique().tolist()) == {-1, 0, 1}
    assert (out.depth[:, 0][fg] > 2.0).all() and (out.depth[:, 0][~fg] == 0).all()
    assert out.image.min() >= 0 and out.image.max() <= 1


def test_background_is_composited_only_off_the_surface(renderer, scene) -> None:
    parts, faces, cam = scene
    black = render_parts(renderer, parts, faces, cam)
    grey = render_parts(renderer, parts, faces, cam, background=(0.5, 0.25, 1.0))
    diff = grey.image - black.image
    per_pixel = diff.permute(1, 0, 2, 3)  # (3, B, H, W)
    assert (per_pixel[:, black.alpha[:, 0] == 0] == torch.tensor([[0.5], [0.25], [1.0]])).all()
    assert (per_pixel[:, black.alpha[:, 0] == 1] == 0).all()


def test_albedo_forms_agree(renderer, scene) -> None:
    parts, faces, cam = scene
    colours = torch.tensor([[1.0, 0.2, 0.2], [0.2, 0.2, 1.0]])
    per_part = render_parts(renderer, parts, faces, cam, albedo=colours).image
    per_scene = render_parts(renderer, parts, faces, cam, albedo=colours.expand(2, 2, 3)).image
    per_vertex = render_parts(renderer, parts, faces, cam, albedo=colours.view(1, 2, 1, 3).expand(2, 2, 162, 3)).image
    assert torch.equal(per_part, per_scene) and torch.allclose(per_part, per_vertex, atol=1e-6)
    grey = render_parts(renderer, parts, faces, cam, albedo=(0.5, 0.5, 0.5)).image
    assert torch.allclose(render_parts(renderer, parts, faces, cam, albedo=(1.0, 1.0, 1.0)).image, 2 * grey, atol=1e-6)
    with pytest.raises(ValueError, match="albedo"):
        render_parts(renderer, parts, faces, cam, albedo=torch.ones(5, 3))


def test_default_light_follows_the_camera(renderer, scene) -> None:
    parts, faces, cam = scene
    a = render_parts(renderer, parts, faces, cam)
    b = render_parts(renderer, parts, faces, cam, Light.following(cam))
    assert torch.equal(a.image, b.image)
    light = Light.white(torch.tensor([[0.0, 0.0, 5.0], [3.0, 0.0, 4.0]]))
    torch.testing.assert_close(light.direction.norm(dim=-1), torch.ones(2))
    assert torch.equal(light.index([1]).direction, light.direction[1:])


def test_pack_parts_offsets_faces() -> None:
    t = icosphere(1)
    parts = torch.randn(2, 3, 42, 3)
    verts, faces, face_part = pack_parts(parts, t.faces)
    assert verts.shape == (2, 126, 3) and faces.shape == (240, 3)
    assert torch.equal(faces[80:160], t.faces + 42) and torch.equal(face_part, torch.arange(3).repeat_interleave(80))


@pytest.mark.parametrize("mutate, message", [
    (lambda v, f, c: (v[0], f, c), r"vertices must be \(B, V, 3\)"),
    (lambda v, f, c: (v, f.float(), c), "faces must be int32 or int64, got float32"),
    (lambda v, f, c: (v, f[:, :2], c), r"faces must be \(F, 3\)"),
    (lambda v, f, c: (v, f + 1000, c), "faces index vertices outside"),
    (lambda v, f, c: (v, f, c.index([0])), "2 scenes but 1 cameras"),
])
def test_bad_input_is_a_clear_error(renderer, scene, mutate, message: str) -> None:
    parts, faces, cam = scene
    verts, packed, _ = pack_parts(parts, faces)
    with pytest.raises(ValueError, match=message):
        render(renderer, *mutate(verts, packed, cam))


def test_a_list_of_vertices_is_named_not_an_attribute_error(renderer, scene) -> None:
    """The campaign's re-run on the merged main: ``render(ctx, vertices.tolist(), ...)`` was an AttributeError
    ('list' object has no attribute 'device') before the op could name it."""
    from cerberus_core.errors import InputTypeError

    parts, faces, cam = scene
    verts, packed, _ = pack_parts(parts, faces)
    with pytest.raises(InputTypeError, match="vertices is a list, not a tensor"):
        render(renderer, verts.tolist(), packed, cam)


def test_parts_need_four_dimensions(renderer, scene) -> None:
    parts, faces, cam = scene
    with pytest.raises(ValueError, match=r"part_vertices must be \(B, P, V, 3\)"):
        render_parts(renderer, parts[0], faces, cam)


def test_light_batch_must_match(renderer, scene) -> None:
    parts, faces, cam = scene
    with pytest.raises(ValueError, match=r"shade: light.direction must be \(B, 3\), got \(1, 3\)"):
        render_parts(renderer, parts, faces, cam, Light.following(cam.index([0])))


def test_part_pixel_counts_counts_front_pixels_per_part_and_image():
    from cerberus_core.render.api import part_pixel_counts

    part_id = torch.tensor([[[-1, 0], [2, 2]],
                            [[-1, -1], [-1, 1]]])  # (2, 2, 2): -1 where no part
    assert part_pixel_counts(part_id, 3).tolist() == [[1, 0, 2], [0, 1, 0]]


@pytest.mark.parametrize("options, message", [
    ({"background": (1.0, 1.0)}, r"render: background must be \(3\), got \(2,\)"),
    ({"face_part": torch.zeros(3, dtype=torch.long)}, r"face_part must be \(F\), got \(3,\) \(with F="),
], ids=["background", "face-part"])
def test_optional_tensors_of_the_wrong_shape_are_named(renderer, scene, options, message) -> None:
    """Issue 34 campaign: a two-colour background was a reshape RuntimeError, a short face_part an IndexError."""
    parts, faces, cam = scene
    verts, packed, _ = pack_parts(parts, faces)
    with pytest.raises(ValueError, match=message):
        render(renderer, verts, packed, cam, **options)
