"""Every backend against the independent numpy reference (reference.py beside it)."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from cerberus_core.render.api import render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.viz import part_colors

from .reference import PinholeCamera, explain_mismatches, render_reference
from .scenes import ellipsoid_parts

TOL = 5e-5
"""Largest allowed difference of images and depths, float32 backend vs float64 reference (measured
with the torch backend: below 1e-6 at almost every pixel, 1.1e-5 at the worst, a grazing normal)."""


def _near_and_degenerate_scene() -> torch.Tensor:
    """(1, 4, 42, 3): a part crossing the near plane of a camera at +Z, one with collapsed
    (zero-area) triangles, one fully behind the camera and one fully outside the image."""
    parts, _ = ellipsoid_parts(1, 4, level=1, seed=3, radius=(0.15, 0.25), spread=0.0)
    parts = parts.clone()
    parts[0, 0] = parts[0, 0] * 0.8 + torch.tensor([0.15, 0.05, 2.3])  # spans depths ~0..0.4, near = 0.05
    parts[0, 1, :7] = parts[0, 1, 0]  # 7 vertices merged: their triangles have zero area
    parts[0, 2] += torch.tensor([0.0, 0.0, 4.0])  # behind the camera
    parts[0, 3] += torch.tensor([3.0, 0.0, 0.0])  # beside the view frustum
    return parts


SCENES = {
    # name: (parts, faces, [(azimuth, elevation)], (height, width))
    "body": (*ellipsoid_parts(1, 3, level=2, seed=11), [(25.0, 10.0), (-140.0, -20.0)], (24, 40)),
    "near+degenerate": (_near_and_degenerate_scene(), ellipsoid_parts(1, 1, level=1)[1], [(0.0, 0.0)], (32, 32)),
}


def _render_both(renderer, parts: torch.Tensor, faces: torch.Tensor, views, size):
    nparts, nverts = parts.shape[1:3]
    colours = part_colors(nparts)
    h, w = size
    az = torch.tensor([v[0] for v in views])
    el = torch.tensor([v[1] for v in views])
    cam = Camera.look_at(az, el, 2.5, fov_y_deg=30.0, image_size=(h, w))
    batch = parts.expand(len(views), -1, -1, -1)
    out = render_parts(renderer, batch, faces, cam, albedo=colours, background=(0.2, 0.3, 0.4))
    verts = parts[0].reshape(-1, 3).double().numpy()
    packed = (faces.numpy()[None] + nverts * np.arange(nparts)[:, None, None]).reshape(-1, 3)
    albedo = np.repeat(colours.double().numpy(), nverts, axis=0)
    refs, clips = [], []
    for a, e in views:
        pc = PinholeCamera.orbit(a, e, 2.5, 30.0, h, w)
        refs.append(render_reference(verts, packed, pc, albedo, background=(0.2, 0.3, 0.4)))
        clips.append(pc.clip(verts))
    return out, refs, clips, packed


@pytest.mark.parametrize("scene", sorted(SCENES))
def test_matches_numpy_reference(renderer, scene: str) -> None:
    parts, faces, views, (h, w) = SCENES[scene]
    out, refs, clips, packed = _render_both(renderer, parts, faces, views, (h, w))
    for b, ref in enumerate(refs):
        fid = out.face_id[b].numpy()
        assert (ref.face_id >= 0).any(), "the reference scene must show something"
        differ = fid != ref.face_id
        rows, cols = np.nonzero(differ)
        explained = explain_mismatches(clips[b], packed, h, w, 0.05, rows, cols, fid[differ], ref.face_id[differ])
        bad = [(int(r), int(c), int(fid[r, c]), int(ref.face_id[r, c]))
               for r, c, e in zip(rows, cols, explained, strict=False) if not e]
        assert not bad, f"{scene} view {b}: face ids differ at (row, col, backend, reference) {bad[:5]}"
        assert differ.sum() <= max(1, 0.01 * h * w), f"{scene} view {b}: {differ.sum()} edge/tie disagreements"
        same = ~differ
        np.testing.assert_allclose(out.depth[b, 0].numpy()[same], ref.depth[same], rtol=0, atol=TOL,
                                   err_msg="depth differs from the reference")
        img = out.image[b].permute(1, 2, 0).numpy()
        np.testing.assert_allclose(img[same], ref.rgb[same], rtol=0, atol=TOL,
                                   err_msg="image differs from the reference")
        np.testing.assert_array_equal(out.alpha[b, 0].numpy()[same], (ref.face_id[same] >= 0).astype(np.float32))
        face_part = np.repeat(np.arange(parts.shape[1]), faces.shape[0])
        expect_part = np.where(fid >= 0, face_part[np.maximum(fid, 0)], -1)
        np.testing.assert_array_equal(out.part_id[b].numpy(), expect_part)


def test_near_plane_and_offscreen_parts_are_not_drawn(renderer) -> None:
    parts, faces, views, size = SCENES["near+degenerate"]
    out, refs, _, _ = _render_both(renderer, parts, faces, views, size)
    shown = set(out.part_id.unique().tolist())
    assert {0, 1} <= shown, "the part crossing the near plane and the part with degenerate faces stay visible"
    assert not {2, 3} & shown, "parts behind the camera or outside the frustum must not be drawn"
    assert torch.isfinite(out.image).all() and torch.isfinite(out.depth).all()
