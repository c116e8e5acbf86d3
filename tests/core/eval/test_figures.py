"""Pictures with real rendering: sizes, contents, viewpoints."""
from __future__ import annotations

import numpy as np
import pytest
import torch
from PIL import Image

from cerberus_core.errors import ShapeError
from cerberus_core.eval import figures
from cerberus_core.eval.allocation import keypoints
from cerberus_core.parts import PartSet
from cerberus_core.render.camera import Camera
from cerberus_core.viz import GRID_PAD, ROW_LABEL_WIDTH, TITLE_HEIGHT, part_colors
from tests.support.oracle import body_parts

H = 40


def _camera(az=30.0, n=1):
    return Camera.look_at(torch.full((n,), az), 15.0, 2.6, fov_y_deg=30.0, image_size=H)


def test_renders_show_the_body_and_part_colours(renderer, primitive_bodies):
    recon = body_parts(primitive_bodies[1])
    cam = _camera()
    shaded = figures.render_reconstruction(renderer, recon, cam)
    parts = figures.render_reconstruction(renderer, recon, cam, parts=True)
    assert shaded.shape == parts.shape == (1, 3, H, H)
    fg = (shaded[0] < 0.99).any(0)
    assert 0.02 < fg.float().mean() < 0.6  # the figure is in frame, not filling it
    grey = (shaded[0, 0] - shaded[0, 2]).abs()[fg].max()
    assert grey < 1e-5 and (parts[0, 0] - parts[0, 2]).abs()[fg].max() > 0.2
    relit = figures.relit(renderer, recon, cam)
    assert (relit - shaded).abs()[:, :, fg].mean() > 0.02  # another light, other shading, same silhouette
    assert torch.equal((relit[0] < 0.99).any(0), fg)


def test_turntable_views_differ(renderer, primitive_bodies):
    recon = body_parts(primitive_bodies[2])
    views = figures.turntable(renderer, recon, _camera(), n_views=4)
    assert views.shape == (4, 3, H, H)
    first = figures.render_reconstruction(renderer, recon, _camera())[0]
    torch.testing.assert_close(views[0], first, atol=1e-4, rtol=0)
    masks = [(v < 0.99).any(0) for v in views]
    assert all((masks[0] ^ m).float().mean() > 0.01 for m in masks[1:])


def test_new_pose_equals_render_of_donor_when_shapes_agree(renderer, primitive_bodies):
    a = body_parts(primitive_bodies[0], seed=3)
    donor = PartSet(a.local_vertices, a.faces, a.rotations.flip(1), a.translations.flip(1))
    got = figures.reposed(renderer, a, donor, _camera())
    torch.testing.assert_close(got, figures.render_reconstruction(renderer, donor, _camera()))


def test_save_image_pictures_writes_pngs_of_expected_size(tmp_path, renderer, primitive_bodies):
    recon, donor = body_parts(primitive_bodies[0]), body_parts(primitive_bodies[1])
    cam = _camera()
    image = figures.render_reconstruction(renderer, recon, cam)[0]
    paths = figures.save_image_pictures(figures.PictureStyle(renderer, n_views=8, scale=2), image, recon, cam,
                                        tmp_path, "x", pose_donor=donor)
    sizes = {p.name: Image.open(p).size for p in paths}
    for name in ("input", "reconstruction", "parts", "new_lighting", "new_pose"):
        assert sizes[f"x_{name}.png"] == (H, H)
    cell = 2 * H + GRID_PAD
    assert sizes["x_turntable.png"] == (ROW_LABEL_WIDTH + 8 * cell + GRID_PAD, TITLE_HEIGHT + 2 * cell + GRID_PAD)
    assert sizes["x_figure1.png"] == (3 * cell + GRID_PAD, 2 * (TITLE_HEIGHT + cell + GRID_PAD))
    png = np.asarray(Image.open(tmp_path / "x_parts.png"))
    assert len({tuple(p) for p in png.reshape(-1, 3)}) > 10  # coloured parts, not a blank tile


def test_table2_columns(renderer, primitive_bodies):
    bodies = primitive_bodies[:3]
    ours = PartSet.cat([body_parts(b) for b in bodies])
    cams = Camera.cat([_camera(az) for az in (0.0, 45.0, 90.0)])
    images = figures.render_reconstruction(renderer, ours, cams)
    blob = PartSet.from_posed(torch.as_tensor(bodies[0].vertices)[None].expand(3, -1, -1),
                                         torch.as_tensor(bodies[0].faces))
    titles, rows = figures.table2_rows(renderer, images, cams, ours, {"NMR": blob, "NMRs": blob})
    assert titles == ["Input", "Keypoints", "NMR", "NMRs", "Ours", "Parts", "Turn"]
    assert len(rows) == 3 and all(len(r) == 7 for r in rows)
    torch.testing.assert_close(rows[1][4], images[1])
    # the keypoints: the input, with each part's translation marked in its colour where it projects
    uv = keypoints(ours, cams)
    col, row = (int(x) for x in uv[1, -1].floor())  # the last part is drawn over the others
    assert rows[1][1][:, row, col].tolist() == part_colors(ours.num_parts)[-1].tolist()
    assert (rows[1][1] != images[1]).any(dim=0).sum() <= 5 * ours.num_parts
    with pytest.raises(ShapeError, match="table2_rows: ours has 2 reconstructions for 3 images"):
        figures.table2_rows(renderer, images, cams, ours.index([0, 1]))


@pytest.mark.parametrize("size", [16, 32, 64])
def test_figure_one_titles_stay_inside_their_columns(size):
    """Issue 11: at 32 px the captions ran into each other. Every caption is drawn inside its own
    column: the title band is white where two columns meet, and every caption left some ink."""
    panels = {k: torch.full((3, size, size), 0.5) for k in figures.FIGURE_ONE_TITLES}
    picture = np.asarray(figures.figure_one(panels, scale=1, columns=3).convert("L"))
    cell = size + GRID_PAD
    for row in range(2):
        band = picture[row * (TITLE_HEIGHT + cell + GRID_PAD):][:TITLE_HEIGHT]
        for c in range(3):
            x0 = GRID_PAD + c * cell
            assert (band[:, x0 - GRID_PAD // 2] == 255).all(), f"a caption crosses the left edge of column {c}"
            assert (band[:, x0 + size - 1 + GRID_PAD // 2] == 255).all(), \
                f"a caption crosses the right edge of column {c}"
            assert (band[:, x0:x0 + size] < 128).any(), f"caption {c} of row {row} drew nothing"


def test_voxel_views_show_the_kind_most_voxels_on_a_line_are_front_and_side():
    """Front: seen from +z (x right, y up); side: seen from +x (z to the left, y up). A line of sight
    shows its majority kind, a tie going to missed, then off-body."""
    from cerberus_core.eval.standard import Score, Voxels

    gt = np.zeros((4, 4, 4), bool)
    pred = np.zeros((1, 4, 4, 4), bool)
    gt[1, 1, 1] = pred[0, 1, 1, 1] = True  # a hit
    gt[3, 3, 1] = pred[0, 3, 3, 1] = True  # a hit, in front of ...
    gt[3, 3, 0] = True  # ... a missed voxel on the same front line of sight: a tie, missed
    gt[0, 2, 0:2] = pred[0, 0, 2, 0:2] = True  # two hits and ...
    gt[0, 2, 3] = True  # ... one missed voxel on one front line: hit
    pred[0, 0, 0, 3] = True  # off the body
    views = figures.voxel_views(Voxels(pred, gt, Score(0.5), lambda i: i), 8)
    assert views.shape == (2, 3, 8, 8)
    colours = {tuple(torch.tensor(c).tolist()): k for k, c in figures.VOXEL_COLOURS.items()}

    def at(view, row, col):  # the colour of voxel cell (row, col): 2 x 2 pixels each
        return colours.get(tuple(views[view, :, 2 * row, 2 * col].tolist()), "background")

    front = {(0, 3): "missed", (2, 1): "hit", (1, 0): "hit", (3, 0): "off-body", (0, 0): "background"}
    side = {(0, 3): "missed", (0, 2): "hit", (2, 2): "hit", (1, 0): "missed", (3, 0): "off-body",
            (1, 1): "background"}
    assert {k: at(0, *k) for k in front} == front
    assert {k: at(1, *k) for k in side} == side
    assert torch.equal(views[:, :, 0::2, 0::2], views[:, :, 1::2, 1::2])  # nearest upscaling
    assert figures.voxel_legend(300).size == (300, 16 + GRID_PAD)
