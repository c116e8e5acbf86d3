"""Part visibility in the input view: hand-built scenes whose answer is known, and the summary."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from cerberus_core.eval.visibility import PartVisibility, visibility_line, visibility_sentence, visible_pixels
from cerberus_core.parts import PartSet
from cerberus_core.render.api import render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.templates import icosphere

# Camera at azimuth 0 sits on +Z looking at the origin: larger z is nearer.
FRONT = ([0.0, 0.0, 0.3], 0.25)
BEHIND = ([0.0, 0.0, -0.3], 0.12)  # inside FRONT's shadow from the camera
BESIDE = ([0.45, 0.0, 0.0], 0.12)
OFF_SCREEN = ([5.0, 0.0, 0.0], 0.12)


def spheres(centres_radii, batch: int = 2) -> PartSet:
    """``batch`` identical images of spheres, each with its own (non-trivial) local frame."""
    sphere = icosphere(2)
    local = torch.stack([r * sphere.vertices for _, r in centres_radii])  # (P, V, 3)
    p = len(centres_radii)
    angle = torch.linspace(0.3, 1.7, p)
    c, s = torch.cos(angle), torch.sin(angle)
    rot = torch.zeros(p, 3, 3)
    rot[:, 0, 0], rot[:, 0, 2], rot[:, 1, 1], rot[:, 2, 0], rot[:, 2, 2] = c, s, 1.0, -s, c
    trans = torch.tensor([centre for centre, _ in centres_radii])
    return PartSet(local.expand(batch, -1, -1, -1).clone(), sphere.faces, rot.expand(batch, -1, -1, -1).clone(),
                   trans.expand(batch, -1, -1).clone())


def test_part_behind_another_is_hidden_and_part_beside_is_not(renderer):
    recon = spheres([FRONT, BEHIND, BESIDE, OFF_SCREEN])
    camera = Camera.look_at([0.0, 0.0], 0.0, 2.5, fov_y_deg=30.0, image_size=64)  # two images, same view
    counts = visible_pixels(renderer, recon, camera)
    assert counts.shape == (2, 4) and counts.dtype == torch.int64
    front, behind, beside, off = counts[0].tolist()
    assert behind == 0 and off == 0 and front > 200 and beside > 20
    # the counts partition the rendered silhouette
    alpha = render_parts(renderer, recon.posed(), recon.faces, camera).alpha
    assert counts.sum(1).tolist() == alpha.sum((1, 2, 3)).long().tolist()

    # seen from behind (azimuth 180), BEHIND is in front and visible, FRONT still shows around it
    back = visible_pixels(renderer, recon.index(0), Camera.look_at(180.0, 0.0, 2.5, fov_y_deg=30.0, image_size=64))
    assert back[0, 1] > 20 and back[0, 0] > 0

    acc = PartVisibility(num_parts=4, image_size=(64, 64))
    acc.add(counts)
    acc.add(back)
    s = acc.summary()
    assert s["images"] == 3 and s["image_size"] == [64, 64]
    assert s["hidden_fraction"] == pytest.approx([0.0, 2 / 3, 0.0, 1.0])
    assert s["mean_visible_pixels"][3] == 0.0 and s["mean_visible_pixels"][0] > s["mean_visible_pixels"][2] > 0
    assert sum(s["mean_silhouette_share"]) == pytest.approx(1.0)
    assert s["parts_hidden_in_most_images"] == 2 and s["hidden_in_most_images"] == [1, 3]
    assert visibility_line(s) == "parts hidden in most images: 2 of 4 (part 1: 67%, part 3: 100%)"


def test_single_mesh_is_never_hidden_and_summary_edge_cases(renderer):
    recon = spheres([FRONT], batch=3)
    cams = Camera.look_at([0.0, 90.0, 200.0], 20.0, 2.5, fov_y_deg=30.0, image_size=32)
    acc = PartVisibility(num_parts=1, image_size=(32, 32))
    acc.add(visible_pixels(renderer, recon, cams))
    s = acc.summary()
    assert s["hidden_fraction"] == [0.0] and s["mean_silhouette_share"] == [1.0]
    assert visibility_line(s) == "parts hidden in most images: 0 of 1"
    # nothing drawn at all: every part hidden, the share undefined (NaN, written as null in JSON)
    empty = PartVisibility(num_parts=2, image_size=(32, 32))
    empty.add(np.zeros((2, 2), dtype=np.int64))
    e = empty.summary()
    assert e["hidden_fraction"] == [1.0, 1.0] and all(math.isnan(v) for v in e["mean_silhouette_share"])
    # sometimes hidden, never in most images: the line names the most often hidden part
    some = PartVisibility(image_size=(32, 32))  # the parts: the first counts'
    some.add(np.array([[5, 0], [5, 3], [5, 3]]))
    assert visibility_line(some.summary()) == ("parts hidden in most images: 0 of 2 "
                                               "(most often hidden: part 1, in 33% of images)")
    assert PartVisibility(num_parts=2, image_size=(32, 32)).summary() is None  # nothing added: nothing measured
    with pytest.raises(ValueError, match=r"\(B, 2\)"):
        some.add(np.zeros((1, 3)))
    with pytest.raises(ValueError, match="2 reconstructions but 3 cameras"):
        visible_pixels(renderer, spheres([FRONT]), cams)


def test_counts_added_without_an_image_size_summarise_with_a_null_size():
    """The documented direct use (``add`` of :func:`visible_pixels` counts, no ``image_size=``): the summary
    records ``None`` for the size, and the report's sentence leaves the size out."""
    acc = PartVisibility()
    acc.add(np.array([[120, 0], [80, 40]]))
    s = acc.summary()
    assert s["image_size"] is None and s["images"] == 2 and s["hidden_fraction"] == [0.0, 0.5]
    assert visibility_sentence(s).startswith("Part visibility in the input view (renders of the reconstruction, "
                                             "2 images): ")
    sized = PartVisibility(image_size=(32, 48))
    sized.add(np.array([[1, 2]]))
    assert sized.summary()["image_size"] == [32, 48]
    assert visibility_sentence(sized.summary()).startswith("Part visibility in the input view (32x48 renders")
