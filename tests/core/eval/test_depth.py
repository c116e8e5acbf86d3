"""cerberus_core.eval.depth: depth across the views of a test pose."""
from __future__ import annotations

import pytest
import torch

from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.eval import depth
from cerberus_core.eval.depth import DepthAccumulator, _PoseViews, translation_disagreement, turned_view_ious
from cerberus_core.parts import PartSet
from cerberus_core.render.backends import make_renderer
from cerberus_core.render.templates import icosphere


def test_translation_disagreement_is_the_mean_pairwise_distance_per_part():
    t = torch.zeros(3, 2, 3)
    t[1, 0, 0] = 0.3  # part 0: one view off by 0.3 -> pairs (0,1) 0.3, (0,2) 0, (1,2) 0.3
    torch.testing.assert_close(translation_disagreement(t), torch.tensor([0.2, 0.0]))
    with pytest.raises(ValueError, match="at least 2 views"):
        translation_disagreement(t[:1])


def _scene(shift: float):
    """A sphere 'body' at the origin seen from 3 views; each view's reconstruction is the same
    sphere, view 0's moved by ``shift`` along its own camera ray (its input view nearly unchanged)."""
    scene = SceneSetup(distance=2.5)
    cams = scene.cameras(torch.tensor([0.0, 90.0, 200.0]), 32)
    sphere = icosphere(2, radius=0.35)
    local = sphere.vertices.unsqueeze(0).unsqueeze(0).expand(3, 1, -1, 3)
    trans = torch.zeros(3, 1, 3)
    ray = torch.nn.functional.normalize(-cams.center[0], dim=0)
    trans[0, 0] = shift * ray
    parts = PartSet(local, sphere.faces, torch.eye(3).expand(3, 1, 3, 3), trans)
    return parts, cams, (sphere.vertices, sphere.faces)


def test_turned_view_iou_sees_a_depth_error_the_input_view_cannot():
    renderer = make_renderer("torch")
    parts, cams, body = _scene(0.0)
    right = turned_view_ious(renderer, parts, cams, body)
    assert right.shape == (3, 3) and bool((right > 0.97).all())
    parts, cams, body = _scene(0.6)  # view 0's sphere slides 0.6 toward its camera
    wrong = turned_view_ious(renderer, parts, cams, body)
    assert wrong[0, 1] < 0.5 and wrong[0, 2] < 0.8  # the other views see it off the body
    assert wrong[1, 2] > 0.97 and wrong[2, 1] > 0.97  # the consistent views still agree
    off = ~torch.eye(3, dtype=torch.bool)
    assert float(wrong.diagonal().mean() - wrong[off].mean()) > float(right.diagonal().mean() - right[off].mean())


def test_the_summary_means_leave_out_an_empty_pair(monkeypatch):
    """A pair of silhouettes both empty (a body and a reconstruction out of the camera) has no IoU (NaN): the
    summary's means leave it out instead of counting it as a perfect 1 or turning the figure into NaN."""
    parts, cams, body = _scene(0.0)
    acc = DepthAccumulator(make_renderer("torch"))
    acc.poses[("subject", 0)] = _PoseViews([parts.index([k]) for k in range(3)], [cams.index([k]) for k in range(3)],
                                           body)
    nan = float("nan")
    ious = torch.tensor([[0.9, nan, 0.5], [0.7, 0.8, 0.6], [nan, 0.4, 1.0]], dtype=torch.float64)
    monkeypatch.setattr(depth, "turned_view_ious", lambda *args: ious)
    s = acc.summary()
    assert s["input_view_silhouette_iou"] == pytest.approx(0.9)
    assert s["turned_view_silhouette_iou"] == pytest.approx((0.5 + 0.7 + 0.6 + 0.4) / 4)


def test_the_summary_says_how_many_images_it_measured_of_how_many_and_why_none():
    """Review of the `--limit` work: depth is over the images whose pose has another view among those scored, which
    can be fewer than those scored, and with one image a pose none at all; the depth section was then absent
    without a word. The summary now counts the images fed (``images_evaluated``) beside those measured, and says
    why (``note``) when no pose has two views; results.md and the printed line say both."""
    from cerberus_core.eval.report import markdown_report

    parts, cams, body = _scene(0.0)
    acc = DepthAccumulator(make_renderer("torch"))
    acc.poses[("subject", 0)] = _PoseViews([parts.index([k]) for k in range(3)], [cams.index([k]) for k in range(3)],
                                           body)
    acc.poses[("subject", 1)] = _PoseViews([parts.index([0])], [cams.index([0])], body)  # one view: not measured
    s = acc.summary()
    assert (s["poses"], s["images"], s["images_evaluated"], s["note"]) == (1, 3, 4, None)
    assert depth.depth_line(s).startswith("over 1 test pose seen from several views (3 of the 4 images scored), ")
    del acc.poses[("subject", 1)]
    assert "(all 3 images scored)" in depth.depth_line(acc.summary())

    lone = DepthAccumulator(make_renderer("torch"))
    assert lone.summary() is None  # nothing fed: nothing to say
    lone.poses[("subject", 1)] = _PoseViews([parts.index([0])], [cams.index([0])], body)
    s = lone.summary()
    assert (s["poses"], s["images"], s["images_evaluated"]) == (0, 0, 1) and s["translation_disagreement"] == []
    figures = ("mean_translation_disagreement", "input_view_silhouette_iou", "turned_view_silhouette_iou")
    assert all(s[key] is None for key in figures)
    assert s["note"] == ("no pose has two of its views among the 1 image scored (depth compares the views of each "
                         "pose): score more images (a larger limit), or a split that shows each pose from several "
                         "views")
    assert depth.depth_line(s) == f"not measured: {s['note']}"
    result = {"protocol": "kato", "resolution": 32, "seconds": 1.0, "records": [], "hard": None, "depth": s,
              "standard": {"mean": 0.5, "count": 1, "per_group": {"a": 0.5}, "clipped": 0, "failed": 0}}
    md = markdown_report(result)
    assert f"## Depth across views\n\nNot measured: {s['note']}.\n" in md and "Translation disagreement" not in md
    old = {"poses": 2, "images": 16, "translation_disagreement": [0.1], "mean_translation_disagreement": 0.1,
           "input_view_silhouette_iou": 0.8, "turned_view_silhouette_iou": 0.6}  # a results.json of before
    assert depth.depth_line(old).startswith("over 2 test poses seen from several views (16 images), ")
