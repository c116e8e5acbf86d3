"""Standard, Hard Human and part-quality evaluation in one pass, on a real (tiny) rendered test set
(cerberus_core.eval.runner)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from cerberus_core.errors import ConfigError, DatasetError
from cerberus_core.eval.diagnostics import diagnostic_names
from cerberus_core.eval.report import markdown_report, write_json
from cerberus_core.eval.runner import batch_result, evaluate_dataset, iterate_batches
from cerberus_core.eval.standard import GroundTruthMemo, VoxelScorer
from tests.support.oracle import IMAGE_SIZE, OracleModel


def test_oracle_scores_one_and_hard_human_uses_canonical_shapes(tiny_dataset, iou_scorer, renderer, tmp_path):
    model = OracleModel(tiny_dataset)
    scorer = VoxelScorer(factory=iou_scorer)
    res = evaluate_dataset(tiny_dataset, model, batch_size=5, scorer=scorer, renderer=renderer, progress=False)
    n = len(tiny_dataset)
    assert res.standard.count == n and res.standard.mean == pytest.approx(1.0)
    assert set(res.standard.per_group) == {it["subject"] for it in tiny_dataset.items}
    # Canonical image of each subject: pose 0, view 0; every other image is scored in the hard test.
    assert res["canonical"] == {s: min(i for i, it in enumerate(tiny_dataset.items) if it["subject"] == s)
                             for s in res.standard.per_group}
    assert res["hard"].count == n - 2
    for rec in res.records:
        if rec["index"] in res["canonical"].values():
            assert "hard_iou" not in rec
        elif rec["pose"] == 0:  # another view of the canonical pose: same transforms, exact
            assert rec["hard_iou"] == pytest.approx(1.0)
        else:  # canonical capsules moved to the new pose's centres but not turned
            assert 0.05 < rec["hard_iou"] < 0.95
    assert res["hard"].mean < res.standard.mean
    # Work done once: one forward per image (+ the canonical ones), one GT mesh and grid per pose.
    poses = len({(it["subject"], it["pose"]) for it in tiny_dataset.items})
    assert model.calls == n + 2
    assert tiny_dataset.gt_calls == poses
    assert scorer.cache.misses == poses
    pq = res["part_quality"]
    assert pq["consistency"] == 1.0 and pq["mean_segmentation_iou"] == pytest.approx(1.0)

    # Visibility: the oracle's parts are the body's capsules, so every image's counts partition the
    # silhouette of the input image itself (rendered over white by the dataset).
    vis = res["part_visibility"]
    assert vis["images"] == n and vis["image_size"] == [IMAGE_SIZE, IMAGE_SIZE] and len(vis["hidden_fraction"]) == 10
    for rec in res.records:
        image = tiny_dataset.images[rec["index"]]
        assert sum(rec["visible_pixels"]) == int((image < 1.0).any(0).sum())
    counts = np.array([rec["visible_pixels"] for rec in res.records])
    assert vis["hidden_fraction"] == pytest.approx((counts == 0).mean(0).tolist())
    assert vis["mean_visible_pixels"] == pytest.approx(counts.mean(0).tolist())
    assert vis["parts_hidden_in_most_images"] == sum(h > 0.5 for h in vis["hidden_fraction"])

    # Body segments: the oracle covers every segment, adds nothing off the body, needs every capsule, and
    # covers in the input view what the ground truth's own render covers.
    seg = res["segments"]
    names = list(pq["gt_parts"])
    assert seg["images"] == n and seg["segments"] == names and seg["segment_labels"] is True
    assert seg["voxel_precision"] == 1.0 and seg["voxel_recall"] == 1.0
    assert set(seg["recall"].values()) == {1.0} and set(seg["off_body_share"].values()) == {None}
    assert seg["spare_count"] == 0 and min(seg["deletion_loss"]) > 0.003
    for k in names:
        assert seg["input_view_coverage"][k] == pytest.approx(seg["gt_render_coverage"][k], abs=0.02)
        assert seg["gt_render_coverage"][k] > 0.5
    rec = res.records[0]
    assert rec["voxel_precision"] == rec["voxel_recall"] == 1.0 and rec["segment_recall"] == [1.0] * len(names)
    assert len(rec["deletion_loss"]) == 10
    assert pq["sides_merged"]["consistency"] == 1.0 and "shin" in pq["sides_merged"]["gt_parts"]

    # Allocation: the oracle's translations are its capsules' vertex centroids, so each segment has a keypoint
    # on its projected centroid and each part's keypoint spreads as its segment's centroid does.
    alloc = res["allocation"]
    assert alloc["images"] == n and list(alloc["segment_to_keypoint"]) == names
    assert max(alloc["segment_to_keypoint"].values()) < 1e-3
    assert alloc["keypoint_spread"] == pytest.approx(list(alloc["segment_spread"].values()), abs=1e-3)
    assert 0 < sum(alloc["unique_coverage"]) <= 1 and len(res.records[0]["unique_coverage"]) == 10
    assert len(res.records[0]["keypoints"]) == 10

    path = write_json(res, tmp_path / "results.json")
    data = json.loads(path.read_text())
    assert data["standard"]["count"] == n and len(data["records"]) == n
    assert data["allocation"]["keypoint_spread"] == alloc["keypoint_spread"]
    assert data["part_visibility"]["hidden_fraction"] == pytest.approx(vis["hidden_fraction"])
    md = markdown_report(data, "Oracle")
    assert "| all | 1.0000 |" in md and "Hard Human" in md and "| head | 1.000 |" in md
    assert "| Images | Hidden in input view | Silhouette share |" in md and "parts hidden in most images:" in md
    assert "### With left and right merged" in md and "| shin | 1.000 |" in md
    assert "## Body segments" in md and "| lower_arm.L | " in md and "| IoU lost when deleted | Spare |" in md
    assert data["segments"]["recall"] == seg["recall"]
    assert "## Allocation" in md and "| Keypoint spread (px) | Alone covers |" in md and "Keypoints: spread" in md


def test_subset_and_switches(tiny_dataset, iou_scorer, renderer):
    model = OracleModel(tiny_dataset)
    res = evaluate_dataset(tiny_dataset, model, indices=[3, 4], skip=("hard", "part_quality"),
                           scorer=VoxelScorer(factory=iou_scorer), renderer=renderer, progress=False)
    assert res.standard.count == 2 and res["hard"] is None and res["part_quality"] is None and res["canonical"] == {}
    assert res["part_visibility"]["images"] == 2 and res["segments"]["images"] == 2
    md = markdown_report(res)
    assert "## Part visibility" in md and "| Learned part | Hidden in input view | Silhouette share | Visible pixels |" in md
    res = evaluate_dataset(tiny_dataset, model, indices=[3], skip=("hard", "part_quality", "visibility", "segments",
                                                                "allocation"),
                           scorer=VoxelScorer(factory=iou_scorer), progress=False)
    assert res["part_visibility"] is None and "visible_pixels" not in res.records[0]
    assert res["segments"] is None and "deletion_loss" not in res.records[0]
    assert res["allocation"] is None and "keypoints" not in res.records[0] and "Allocation" not in markdown_report(res)
    assert "visibility" not in markdown_report(res) and "Body segments" not in markdown_report(res)
    res = evaluate_dataset(tiny_dataset, model, indices=[3], skip=("part_quality", "visibility"),
                           scorer=VoxelScorer(factory=iou_scorer), progress=False)
    assert res["hard"].count == 1  # the canonical image is found outside the subset
    with pytest.raises(ValueError, match="no images"):
        evaluate_dataset(tiny_dataset, model, indices=[], progress=False)


def test_model_output_is_checked(tiny_dataset, iou_scorer):
    with pytest.raises(TypeError, match="PartSet"):
        evaluate_dataset(tiny_dataset, lambda images, camera: images, skip=("hard",),
                         scorer=VoxelScorer(factory=iou_scorer), progress=False)


def test_the_result_answers_in_and_names_a_wrong_entry(tiny_dataset, iou_scorer):
    res = evaluate_dataset(tiny_dataset, OracleModel(tiny_dataset), indices=[3], skip=tuple(diagnostic_names()),
                           scorer=VoxelScorer(factory=iou_scorer), progress=False)
    assert "hard" in res and "allocation" in res and "hrad" not in res and res["hard"] is None
    with pytest.raises(KeyError, match="no entry 'hrad' \\(did you mean 'hard'\\?\\); its entries: hard, canonical"):
        res["hrad"]


def test_a_misspelt_option_is_named_before_anything_runs(tiny_dataset, iou_scorer):
    model = OracleModel(tiny_dataset)
    with pytest.raises(ConfigError, match="unknown config key\\(s\\) \\['skipp'\\] \\(did you mean 'skip'\\?\\); "
                                          "valid keys here: \\['batch_size', 'canonical_view'"):
        evaluate_dataset(tiny_dataset, model, skipp=("hard",), scorer=VoxelScorer(factory=iou_scorer), progress=False)
    assert model.calls == 0


def test_a_batch_without_a_pose_is_named(tiny_dataset, iou_scorer):
    class NoPose:  # the tiny set without its items' pose field
        def __init__(self, ds):
            self.ds = ds

        def __len__(self):
            return len(self.ds)

        def __getitem__(self, i):
            return {k: v for k, v in self.ds[i].items() if k != "pose"}

        def __getattr__(self, name):
            return getattr(self.ds, name)

    with pytest.raises(DatasetError, match="dataset item 3 lacks the field pose; the evaluation needs subject, pose"):
        evaluate_dataset(NoPose(tiny_dataset), OracleModel(tiny_dataset), indices=[3], skip=tuple(diagnostic_names()),
                         scorer=VoxelScorer(factory=iou_scorer), progress=False)


def test_a_batch_keeps_each_scorers_voxels_apart(tiny_dataset, iou_scorer):
    (idx, batch, camera), = iterate_batches(tiny_dataset, [3], 1)
    recon = OracleModel(tiny_dataset)(batch["images"], camera)
    result = batch_result(tiny_dataset, batch, idx, recon, camera, GroundTruthMemo(tiny_dataset.gt_mesh))
    coarse, fine = VoxelScorer(resolution=8, factory=iou_scorer), VoxelScorer(resolution=32, factory=iou_scorer)
    assert result.voxels(0, coarse).gt.shape[0] <= 8 < result.voxels(0, fine).gt.shape[0]
    assert result.voxels(0, coarse) is result.voxels(0, coarse)  # once per batch and scorer


def test_a_limit_spreads_over_the_split_and_keeps_a_pose_whole_for_depth(tiny_dataset, iou_scorer, renderer, capsys):
    """Review of issue 43: ``--limit N`` scored the split's first N images (the animal test split, ordered subject, pose,
    view, gave 2 poses of one species: 0.6453 against the whole split's 0.6997). A limit now spreads over the split
    as the figure's images are (one rule, :func:`spread_evenly`), and keeps whole poses while depth runs, so that each
    pose it measures is measured with all its views; depth's figures say over which images they are, and its
    renders (after the evaluation's own bar) have a bar of their own."""
    from cerberus_core.eval.runner import limited_indices, spread_evenly

    assert len(tiny_dataset) == 12  # 2 subjects x 3 poses x 2 views, in that order
    assert spread_evenly(12, 4) == limited_indices(tiny_dataset, 4) == [0, 4, 7, 11]
    assert limited_indices(tiny_dataset, 4, whole_poses=True) == [0, 1, 10, 11]  # both subjects, first and last pose
    assert limited_indices(tiny_dataset, 5, whole_poses=True) == [0, 1, 10, 11]  # 2 whole poses fit, not 3
    assert limited_indices(tiny_dataset, 1, whole_poses=True) == [0]
    assert limited_indices(tiny_dataset, None) == limited_indices(tiny_dataset, 12) == list(range(12))
    indices = limited_indices(tiny_dataset, 5, whole_poses=True)
    res = evaluate_dataset(tiny_dataset, OracleModel(tiny_dataset), indices=indices, renderer=renderer,
                           skip=("hard", "part_quality", "visibility", "segments", "allocation"),
                           scorer=VoxelScorer(factory=iou_scorer), progress=True)
    assert [r["index"] for r in res.records] == indices
    assert {r["subject"] for r in res.records} == {it["subject"] for it in tiny_dataset.items}
    assert res["depth"]["poses"] == 2 and res["depth"]["images"] == res["depth"]["images_evaluated"] == 4
    assert res["depth"]["note"] is None and "Over 2 test poses seen from several views (all 4 images scored)" in \
        markdown_report(res)
    assert "depth: 100%" in capsys.readouterr().err  # the bar over the poses' renders
    # A pose seen from one view among the images scored has no other view: its image is in no depth figure.
    res = evaluate_dataset(tiny_dataset, OracleModel(tiny_dataset), indices=[0, 1, 2], renderer=renderer,
                           skip=("hard", "part_quality", "visibility", "segments", "allocation"),
                           scorer=VoxelScorer(factory=iou_scorer), progress=False)
    depth = res["depth"]
    assert depth["poses"] == 1 and depth["images"] == 2 and depth["images_evaluated"] == 3 == res.standard.count
    md = markdown_report(res)
    assert "Over 1 test pose seen from several views (2 of the 3 images scored)" in md
    assert "the reconstruction of each of those images covers" in md
    assert "depth" not in capsys.readouterr().err  # progress=False: no bar
    # Review: `--limit 1` scored one view, so no pose had two; the depth section was absent, silently. Now the
    # summary says why (results.json's depth.note), and so do results.md and the printed line.
    res = evaluate_dataset(tiny_dataset, OracleModel(tiny_dataset), indices=[0],  # limited_indices(..., 1, ...)
                           skip=("hard", "part_quality", "visibility", "segments", "allocation"), renderer=renderer,
                           scorer=VoxelScorer(factory=iou_scorer), progress=False)
    depth = res["depth"]
    assert (depth["poses"], depth["images"], depth["images_evaluated"]) == (0, 0, 1)
    assert depth["mean_translation_disagreement"] is None and depth["translation_disagreement"] == []
    assert depth["note"].startswith("no pose has two of its views among the 1 image scored (depth compares the views")
    assert "## Depth across views\n\nNot measured: no pose has two of its views among the 1 image scored" in \
        markdown_report(res)


def test_a_one_part_model_is_consistent_but_its_label_covers_one_part(tiny_dataset, iou_scorer, renderer):
    """Review of issue 43: the one-part NMRr scored "Consistency 1.0000, mean entropy 0.000 bits" (Cerberus 0.8051),
    the best possible; beside the consistency, results.json and results.md now say how many of the ground-truth
    parts the learned parts' labels cover: 1 of 10 for one part, 10 of 10 for the oracle's capsules."""
    from cerberus_core.parts import PartSet

    oracle = OracleModel(tiny_dataset)

    def one_part(images, camera):  # the oracle's reconstruction as one mesh: a single-mesh model's
        recon = oracle(images, camera)
        posed = recon.posed()
        return PartSet.from_posed(posed.reshape(posed.shape[0], 1, -1, 3), _one_mesh_faces(recon))

    skip = ("hard", "visibility", "depth", "segments", "allocation")
    one = evaluate_dataset(tiny_dataset, one_part, indices=[0, 5, 11], skip=skip, renderer=renderer,
                           scorer=VoxelScorer(factory=iou_scorer), progress=False)["part_quality"]
    assert one["consistency"] == 1.0 and one["mean_entropy_bits"] == 0.0
    assert one["gt_parts_covered"] == 1 and len(one["gt_parts"]) == 10
    md = markdown_report(evaluate_dataset(tiny_dataset, oracle, indices=[0, 5, 11], skip=skip, renderer=renderer,
                                          scorer=VoxelScorer(factory=iou_scorer), progress=False))
    assert "the learned parts' labels cover 10 of 10 ground-truth parts" in md
    assert "only meaningful together with that count" in md
    assert "; the labels cover 6 of 6 ground-truth parts." in md  # left and right merged


def _one_mesh_faces(recon):
    """The faces of all of ``recon``'s parts as one mesh (part ``p``'s vertices follow part ``p - 1``'s)."""
    import torch

    v = recon.local_vertices.shape[2]
    return torch.cat([recon.faces + p * v for p in range(recon.num_parts)])


class _OpenTruths:
    """``dataset`` (a :class:`TinyViewDataset`) whose ground truths each lack their first 6 triangles: open meshes."""

    def __init__(self, dataset) -> None:
        self.dataset = dataset

    def __len__(self) -> int:
        return len(self.dataset)

    def __getitem__(self, i: int) -> dict:
        return self.dataset[i]

    def __getattr__(self, name: str):
        return getattr(self.dataset, name)

    def gt_mesh(self, i: int):
        from dataclasses import replace

        body = self.dataset.gt_mesh(i)
        return replace(body, faces=body.faces[6:])


def test_the_ground_truth_open_mesh_policy_reaches_the_metric_and_the_result(tiny_dataset, iou_scorer):
    """``EvalConfig.gt_open_mesh`` (``cerberus eval --gt-open-mesh``): ``evaluate_dataset`` makes its scorer with it,
    the result and results.json record it, results.md says it. Under the default, ``"error"``, an open ground truth
    stops the evaluation with a DatasetError naming the image and the setting that scores it anyway."""
    open_truths, model = _OpenTruths(tiny_dataset), OracleModel(tiny_dataset)
    skip = tuple(diagnostic_names())
    with pytest.raises(DatasetError) as err:
        evaluate_dataset(open_truths, model, indices=[2, 3], skip=skip, progress=False)
    subject = tiny_dataset.items[2]["subject"]
    assert str(err.value).startswith(f"the ground truth of image 2 (subject {subject}, pose 1) is not watertight (")
    assert "`gt_open_mesh=close`" in str(err.value)
    with pytest.warns(UserWarning, match="closed holes with pymeshlab"):  # the metric's, one per mesh closed
        closed = evaluate_dataset(open_truths, model, indices=[2, 3], skip=skip, gt_open_mesh="close", progress=False)
    assert closed.gt_open_mesh == "close" and closed.to_dict()["gt_open_mesh"] == "close"
    assert list(closed.to_dict())[:4] == ["protocol", "resolution", "gt_open_mesh", "standard"]
    assert closed.standard.count == 2 and closed.standard.mean > 0.9 and closed.standard.failed == 0
    assert "union of parts, open ground truths closed with pymeshlab; 2 images" in markdown_report(closed)
    whole = evaluate_dataset(tiny_dataset, model, indices=[2, 3], skip=skip, progress=False)
    assert whole.gt_open_mesh == "error" and "open ground truths" not in markdown_report(whole)
    # a prepared scorer brings its own policy, and the result records the one that scored
    with pytest.warns(UserWarning, match="not watertight"):
        shell = evaluate_dataset(open_truths, model, indices=[2], skip=skip, progress=False,
                                 scorer=VoxelScorer(factory=iou_scorer, gt_open_mesh="warn"))
    assert shell.gt_open_mesh == "warn" and "open ground truths scored as they are" in markdown_report(shell)
    with pytest.raises(ConfigError, match="gt_open_mesh = 'ignore': must be one of 'error', 'close', 'warn'"):
        evaluate_dataset(tiny_dataset, model, gt_open_mesh="ignore", progress=False)
