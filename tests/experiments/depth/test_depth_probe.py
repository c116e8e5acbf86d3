"""experiments/depth/depth_probe.py: does an image carry where the body stands along the view?"""
from __future__ import annotations

import numpy as np
import torch

from tests.support.paths import load_script


def test_surface_centroid_weights_by_area_not_by_vertex():
    module = load_script("experiments/depth/depth_probe.py")
    # A unit square at x in [0, 1] and a tiny triangle far out at x = 10 with many of the vertices: the centroid
    # stays on the square (a vertex mean would not).
    verts = torch.tensor([[0., 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [10, 0, 0], [10.001, 0, 0], [10, 0.001, 0]])
    faces = torch.tensor([[0, 1, 2], [0, 2, 3], [4, 5, 6]])
    centre = module.surface_centroid(verts, faces)
    torch.testing.assert_close(centre, torch.tensor([0.5, 0.5, 0.0]), atol=1e-4, rtol=0)
    batched = module.surface_centroid(torch.stack([verts, verts + 1]), faces)
    torch.testing.assert_close(batched[1], centre + 1, atol=1e-4, rtol=0)


def test_offsets_measure_depth_along_the_view_and_pixels_from_the_origin():
    from cerberus_core.render.camera import Camera

    module = load_script("experiments/depth/depth_probe.py")
    camera = Camera.look_at(torch.tensor([0.0, 0.0]), torch.tensor([15.0, 15.0]), torch.tensor([2.0, 2.0]),
                            fov_y_deg=30.0, image_size=64)
    towards = camera.center[1] / camera.center[1].norm() * 0.05  # 0.05 from the origin towards the camera
    out = module.offsets(camera, torch.stack([torch.zeros(3), towards]))
    torch.testing.assert_close(out[0], torch.zeros(3), atol=1e-5, rtol=0)
    torch.testing.assert_close(out[1], torch.tensor([-0.05, 0.0, 0.0]), atol=1e-4, rtol=0)
    side = module.offsets(camera.index([0]), torch.tensor([[0.1, 0.0, 0.0]]))[0]  # sideways: pixels, no depth
    assert abs(float(side[0])) < 5e-3 and abs(float(side[1])) > 1.0


def test_fit_probe_reads_what_the_image_shows_and_not_noise():
    module = load_script("experiments/depth/depth_probe.py")
    gen = torch.Generator().manual_seed(0)
    n, size = 480, 32
    x0 = torch.randint(0, size - 6, (n,), generator=gen)
    y0 = torch.randint(0, size - 6, (n,), generator=gen)
    images = torch.zeros(n, 1, size, size)
    for k in range(n):  # a bright 6 px square at a random place
        images[k, 0, y0[k]:y0[k] + 6, x0[k]:x0[k] + 6] = 1.0
    noise = torch.randn(n, generator=gen).numpy()
    y = np.column_stack([x0.float().numpy(), noise])
    train, test = slice(0, 400), slice(400, n)
    _, guess, curve = module.fit_probe(images[train], y[train], images[test], epochs=8)
    r2 = module.r2(guess, y[test], y[train].mean(0))
    assert r2[0] > 0.8, r2  # the square's position is in the image
    assert r2[1] < 0.15, r2  # the noise is not
    assert len(curve) == 8
