"""Body segments (cerberus_core.eval.segments): recall and off-body voxels per ground-truth segment, the
IoU each learned part is worth, input-view coverage; on constructed grids and real capsule figures."""
from __future__ import annotations

import numpy as np
import pytest
import torch

from cerberus_core.errors import ConfigError, DatasetError
from cerberus_core.eval.segments import (
    SPARE_LOSS,
    BodySegments,
    covered_vertices,
    deletion_losses,
    group_by_body,
    image_segments,
    one_vocabulary,
    segments_line,
)
from cerberus_core.eval.standard import VoxelScorer
from cerberus_core.eval.visibility import input_view_part_id
from cerberus_core.render.api import render
from cerberus_core.render.camera import Camera
from tests.support.oracle import body_parts


def test_deletion_losses_count_the_voxels_only_one_part_covers():
    gt = np.zeros((4, 1, 1), bool)
    gt[:3] = True  # ground truth: voxels 0, 1, 2
    parts = np.zeros((3, 4, 1, 1), bool)
    parts[0, :2] = True  # 0, 1
    parts[1, 1:3] = True  # 1, 2 (voxel 1 shared with part 0)
    parts[2, 3] = True  # 3: off the body
    loss = deletion_losses(parts, gt)
    iou = 3 / 4
    np.testing.assert_allclose(loss, [iou - 2 / 4, iou - 2 / 4, iou - 3 / 3])
    assert loss[2] < 0  # deleting a part wholly off the body raises the IoU
    with pytest.raises(ValueError, match="deletion_losses"):
        deletion_losses(parts[0], gt)


def test_covered_vertices_looks_up_the_pixel_each_vertex_projects_to():
    camera = Camera.look_at(0.0, 0.0, 2.0, fov_y_deg=40.0, image_size=8)
    points = torch.tensor([[[0.0, 0.0, 0.0], [0.3, 0.3, 0.0], [5.0, 0.0, 0.0]]])  # centre, upper right, off-image
    uv, _ = camera.project(points)
    mask = torch.zeros(1, 8, 8, dtype=torch.bool)
    col, row = uv[0, 1].floor().long().tolist()
    mask[0, row, col] = True
    assert covered_vertices(mask, points, camera).tolist() == [[False, True, False]]
    assert covered_vertices(torch.ones_like(mask), points, camera).tolist() == [[True, True, False]]


def _drop(one, names, dropped):
    """A one-image reconstruction without the parts named ``dropped`` (capsule k is part k)."""
    keep = [k for k, n in enumerate(names) if n not in dropped]
    return type(one)(one.local_vertices[:, keep], one.faces, one.rotations[:, keep], one.translations[:, keep])


def test_a_reconstruction_without_forearms_misses_the_forearms(primitive_bodies, iou_scorer, renderer):
    """The oracle's capsules without the lower arms: only arm voxels are missed, the forearms' recall drops
    (at 32^3 the neighbouring capsules still cover a third of a forearm's voxels) and so does their
    coverage in the input view, while the ground truth's own render still covers them; the IoU of the
    voxels is the standard score; deleting any remaining capsule costs IoU."""
    scorer = VoxelScorer(factory=iou_scorer)
    body = primitive_bodies[0]
    names = body.part_names
    arms = {"lower_arm.L", "lower_arm.R"}
    recon = _drop(body_parts(body), names, arms)
    voxels = scorer.voxels(recon.part_meshes(0), (body.vertices, body.faces))
    assert voxels.score.iou == scorer(recon.part_meshes(0), (body.vertices, body.faces)).iou < 1.0
    assert voxels.parts.shape == (len(names) - 2, *voxels.gt.shape)

    camera = Camera.look_at(0.0, 10.0, 2.6, fov_y_deg=30.0, image_size=64)
    verts = torch.as_tensor(body.vertices)[None]
    predicted = input_view_part_id(renderer, recon, camera) >= 0
    with torch.no_grad():
        own = render(renderer, verts, torch.as_tensor(body.faces), camera).part_id >= 0
    coverage = (covered_vertices(predicted, verts, camera)[0].numpy(), covered_vertices(own, verts, camera)[0].numpy())
    image = image_segments(voxels, body.vertices, body.vertex_parts, len(names), coverage)
    acc = BodySegments(segments=list(names), num_parts=recon.num_parts)
    acc.add(image)
    s = acc.summary()
    assert s["segment_labels"] is True and s["note"] is None
    recall, cover, ceiling = s["recall"], s["input_view_coverage"], s["gt_render_coverage"]
    for name in names:
        if name in arms:
            assert recall[name] < 0.75 and cover[name] < ceiling[name] - 0.2
        elif name.startswith("upper_arm"):  # voxels at the elbow that only the forearm covered
            assert 0.6 < recall[name] < 0.9
        else:
            assert recall[name] == 1.0 and cover[name] == pytest.approx(ceiling[name], abs=0.02)
    assert sum(s["missed_share"][k] for k in names if "arm" in k) == pytest.approx(1.0)
    assert s["voxel_precision"] == 1.0 and s["off_body_share"] == dict.fromkeys(names)  # no off-body voxel
    assert s["voxel_recall"] == pytest.approx(voxels.score.iou)  # precision 1: IoU = recall
    assert sum(s["body_share"].values()) == pytest.approx(1.0)
    assert min(s["deletion_loss"]) > SPARE_LOSS and s["spare_count"] == 0
    rec = image.record()
    assert rec["segment_recall"][names.index("head")] == 1.0 and len(rec["deletion_loss"]) == recon.num_parts
    line = segments_line(s, lowest=2)
    assert line.startswith("voxel recall by body segment: lowest lower_arm.") and "spare learned parts" in line


def test_off_body_voxels_go_to_the_nearest_segment_and_spare_parts_are_counted(primitive_bodies, iou_scorer):
    """The head capsule moved up off the body and a second copy of the torso: the moved head's voxels are
    off-body voxels next to the head (most of them: some above the shoulders are nearer to the torso or
    the upper arms), the head is missed, and the moved head and either torso copy are spare."""
    scorer = VoxelScorer(factory=iou_scorer)
    body = primitive_bodies[1]
    names = body.part_names
    one = body_parts(body)
    head, torso = names.index("head"), names.index("torso")
    keep = [*range(len(names)), torso]
    translations = one.translations[:, keep].clone()
    translations[0, head, 1] += 0.12
    moved = type(one)(one.local_vertices[:, keep], one.faces, one.rotations[:, keep], translations)
    voxels = scorer.voxels(moved.part_meshes(0), (body.vertices, body.faces))
    acc = BodySegments(segments=list(names), num_parts=moved.num_parts)
    acc.add(image_segments(voxels, body.vertices, body.vertex_parts, len(names)))
    s = acc.summary()
    off = {k: v for k, v in s["off_body_share"].items() if v}
    assert off["head"] > 0.8 and sum(off.values()) == pytest.approx(1.0) and s["voxel_precision"] < 1.0
    assert s["recall"]["head"] < s["recall"]["torso"] == 1.0
    # Either torso copy is spare, and so is the moved head: mostly off the body, deleting it raises the IoU.
    assert s["spare_parts"] == [head, torso, len(names)] and s["spare_count"] == 3 and s["deletion_loss"][head] < 0
    assert s["input_view_coverage"] == {} and s["gt_render_coverage"] == {}  # coverage not measured


def test_data_without_segment_labels_says_so_and_still_counts_spare_parts(primitive_bodies, iou_scorer):
    scorer = VoxelScorer(factory=iou_scorer)
    body = primitive_bodies[0]
    voxels = scorer.voxels(body_parts(body).part_meshes(0), (body.vertices, body.faces))
    acc = BodySegments(segments=["body"], num_parts=len(body.part_names))
    acc.add(image_segments(voxels, body.vertices, np.zeros(len(body.vertices), np.int16), 1))
    s = acc.summary()
    assert s["segment_labels"] is False and s["note"].startswith("no segment labels")
    assert s["recall"] == {} and s["off_body_share"] == {} and s["voxel_recall"] == 1.0 and s["spare_count"] == 0
    assert segments_line(s).startswith("no segment labels") and "spare learned parts" in segments_line(s)
    assert BodySegments(segments=["body"], num_parts=3).summary() is None  # nothing added: nothing measured


def test_views_of_one_pose_share_one_render():
    a, b = object(), object()
    assert group_by_body([a, a, b, a, b]) == [[0, 1, 3], [2, 4]]


def test_adding_by_hand_needs_the_vocabulary_and_update_needs_one(primitive_bodies, iou_scorer):
    scorer = VoxelScorer(factory=iou_scorer)
    body = primitive_bodies[0]
    image = image_segments(scorer.voxels(body_parts(body).part_meshes(0), (body.vertices, body.faces)), body.vertices,
                           body.vertex_parts, len(body.part_names))
    with pytest.raises(ConfigError, match=r"segments: BodySegments.add needs .*`BodySegments\(segments=\[...\]"):
        BodySegments().add(image)
    with pytest.raises(ConfigError, match="num_parts: BodySegments.add needs"):
        BodySegments(segments=list(body.part_names)).add(image)
    assert one_vocabulary(None, 0, body.part_names, "body segments") == list(body.part_names)
    with pytest.raises(DatasetError, match="item 7: ground-truth segments \\['body'\\] differ .*; body segments needs"):
        one_vocabulary(list(body.part_names), 7, ["body"], "body segments")


def test_pooled_voxel_figures_are_labelled_and_the_per_image_means_given(primitive_bodies, iou_scorer):
    """Review of issue 43: results.md showed the voxel precision and recall pooled over all voxels beside per-image
    means elsewhere, unlabelled. Two capsule figures, one without its forearms, one without its shins (a different
    share of a different number of voxels missed): the summary keeps the pooled figures and adds the mean over the
    images of each image's own, and results.md says which is which."""
    from cerberus_core.eval.report import markdown_report

    scorer = VoxelScorer(factory=iou_scorer)
    acc = BodySegments()
    records = []
    for body, dropped in zip(primitive_bodies[:2], ({"lower_arm.L", "lower_arm.R"}, {"shin.L", "shin.R"}), strict=True):
        recon = _drop(body_parts(body), body.part_names, dropped)
        acc.segments, acc.num_parts = list(body.part_names), recon.num_parts
        image = image_segments(scorer.voxels(recon.part_meshes(0), (body.vertices, body.faces)), body.vertices,
                               body.vertex_parts, len(body.part_names))
        acc.add(image)
        records.append(image.record())
    s = acc.summary()
    recalls = [r["voxel_recall"] for r in records]
    assert s["image_mean_voxel_recall"] == pytest.approx(np.mean(recalls))
    assert s["image_mean_voxel_precision"] == pytest.approx(np.mean([r["voxel_precision"] for r in records]))
    hits = sum(im.hit_voxels.sum() for im in acc.images)
    assert s["voxel_recall"] == pytest.approx(hits / sum(im.gt_voxels.sum() for im in acc.images))  # pooled
    assert abs(s["voxel_recall"] - s["image_mean_voxel_recall"]) > 1e-4  # two different averages
    md = markdown_report({"protocol": "kato", "resolution": 32, "records": [], "segments": s,
                          "standard": {"mean": 0.5, "count": 2, "per_group": {}, "clipped": 0, "failed": 0}})
    assert (f"recall {s['voxel_recall']:.4f}, pooled over all voxels" in md
            and f"per image, mean precision {s['image_mean_voxel_precision']:.4f} and recall "
                f"{s['image_mean_voxel_recall']:.4f}" in md)
