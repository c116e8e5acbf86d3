"""The per-part depth oracle: what the voxel IoU would be if every part sat at the right depth.

    python experiments/depth/depth_oracle.py RUN DATA [--limit N] [--best-shift] [--json OUT]

Every test pose is seen from several views. For each pose and each learned part, the part's rays
(from each view's camera centre through the keypoint that view predicts for it) are intersected in
the least-squares sense: the *triangulated* part position. Each image's parts are then moved along
their *own* camera rays to the depth of that point, so the input view stays exactly as predicted,
and the moved reconstruction is scored like ``cerberus eval`` (32^3, ``kato``, union of parts):

* **IoU** before and after, and the paired difference (mean ± s.e. over images, images improved);
* **the whole body's depth against the parts'**: the same with one shift per image, every part moved by the mean
  of its parts' depth corrections (*whole body*), and with each part's correction less that mean (*relative*): how
  much of the gain is where the whole body stands and how much is where the parts stand within it;
* with ``--best-shift``, the one shift per image that scores best against the ground truth (a grid of
  ±0.08 world units in steps of 0.01): the most the whole body's depth can give, and how well the
  triangulated shift finds it (correlation); 17 more scorings per image;
* **the moves**: median distance a part moves, and the predicted against the triangulated depth
  (least-squares slope and correlation over every part of every image: slope 1 and correlation 1
  mean the depths are already consistent across views);
* **per part**: the mean absolute depth error (world units);
* **mass against translation**: the depth of each part's vertex mean (where its volume is) beside the depth of its
  translation (where its keypoint is), each against the triangulated depth; with the correlation of the mass's
  offset from the translation (along the view) with the translation's depth error. A strongly negative
  correlation and a mass closer to the triangulated depth than the translation say the vertices shift along the
  ray to make up for a translation at the wrong depth (the vertex offsets, not the depth head, hold the depth);
* **flatness**: the median ratio of each part's smallest to middle extent (principal axes of its
  vertices), for the predicted parts and for the ground-truth body parts: a part much flatter than the
  body's would be a thin sheet, whatever its depth; and the parts' size in their local frames (the
  largest local coordinate, against ``model.vertex_bound``, and the median largest extent).

A large gain says the parts sit right in their input view but not in 3D; a small one does not by itself say
depth is learned: read the whole-body and relative rows, which can cancel (the shipped ``human``: +0.045 and
−0.030; docs/results.md, "One shift per image") (``cerberus eval`` shows the same as the translation disagreement and the
turned-view silhouette IoU of its "Depth across views" section). Single thread; about a minute for
the 208 test images.
"""
from __future__ import annotations

import argparse
import json
import sys
import warnings
from collections import defaultdict

import numpy as np
import torch

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.runner import iterate_batches
from cerberus_core.eval.standard import VoxelScorer
from cerberus_core.parts import PartSet
from cerberus_core.render.camera import triangulate
from cerberus_core.run import Run


def flatness(points: np.ndarray) -> float:
    """Smallest over middle principal extent (standard deviation along the principal axes) of a point set."""
    centred = points - points.mean(0)
    s = np.sort(np.linalg.svd(centred, compute_uv=False))
    return float(s[0] / s[1]) if s[1] > 0 else 0.0


def along_rays(parts: PartSet, centre: torch.Tensor, depth: torch.Tensor, new_depth: torch.Tensor) -> PartSet:
    """One image's parts (batch 1) moved along their own camera rays from ``depth`` to ``new_depth`` ``(N,)``, so
    each keypoint stays where the input view sees it: ``c + (new / old) (T - c)``, ``centre`` ``(3,)`` the camera's."""
    moved = centre + (new_depth / depth).view(-1, 1) * (parts.translations[0] - centre)
    return PartSet(parts.local_vertices, parts.faces, parts.rotations, moved.unsqueeze(0))


GRID = np.round(np.arange(-0.08, 0.0801, 0.01), 2)
"""The single depth shifts ``--best-shift`` tries (world units)."""


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 2)[2],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run", help="run folder, weights file or shipped model name")
    p.add_argument("data", help="dataset folder with a test split (several views per pose)")
    p.add_argument("--limit", type=int, default=None, help="first N test poses only (default all)")
    p.add_argument("--best-shift", action="store_true",
                   help="also search the best single depth shift per image against the ground truth")
    p.add_argument("--json", default=None, help="also write the figures as JSON here")
    args = p.parse_args(argv)
    torch.set_num_threads(1)
    warnings.simplefilter("ignore")  # mesh-quality warnings on predicted parts, as in cerberus eval
    run = Run.load(args.run)
    model = run.model.eval()
    dataset = Dataset.open(args.data).views("test")
    rec = dataset.records
    by_pose: dict[tuple[int, int], list[int]] = defaultdict(list)
    for i in range(len(dataset)):
        by_pose[(int(rec["subject"][i]), int(rec["pose"][i]))].append(i)
    poses = [v for v in by_pose.values() if len(v) >= 2][:args.limit]
    indices = [i for v in poses for i in v]
    uv, depth, recon, cams = {}, {}, {}, {}
    with torch.no_grad():
        for batch_idx, batch, camera in iterate_batches(dataset, indices, 16):
            pred = model(batch["images"])
            parts = model.pose(pred, camera)
            for b, i in enumerate(batch_idx):
                uv[i], depth[i] = pred.maps.uv[b], pred.maps.depth[b]
                recon[i], cams[i] = parts.index(b), camera.index([b])
    scorer = VoxelScorer()
    before, after, moves, d_pred, d_tri, d_mass = [], [], [], [], [], []
    errors = defaultdict(list)
    whole, relative, shifts, best, best_shift = [], [], [], [], []
    flat_pred, flat_gt, local_max, extents = [], [], [], []
    for views in poses:
        centres = torch.cat([cams[i].center for i in views])  # (K, 3)
        dirs = torch.stack([cams[i].rays(uv[i].unsqueeze(0))[0] for i in views])  # (K, N, 3)
        point = triangulate(centres, dirs)  # (N, 3) world
        for k, i in enumerate(views):
            body = dataset.gt_mesh(i)
            gt = (body.vertices, body.faces)
            one = recon[i]
            posed = one.posed()[0]  # (N, V, 3) world
            flat_pred += [flatness(v.numpy()) for v in posed]
            d_mass.extend(cams[i].project(posed.mean(1).unsqueeze(0))[1][0].tolist())
            local = one.local_vertices[0]  # (N, V, 3)
            local_max.append(float(local.abs().max()))
            extents += (local.amax(1) - local.amin(1)).amax(-1).tolist()
            labels = np.asarray(body.vertex_parts)
            flat_gt += [flatness(np.asarray(body.vertices)[labels == k]) for k in np.unique(labels)
                        if (labels == k).sum() >= 4]
            _, target = cams[i].project(point.unsqueeze(0))  # (1, N) triangulated depth in this view
            target, centre, d = target[0], centres[k], depth[i]
            shift = (target - d).mean()
            moved = along_rays(one, centre, d, target)
            before.append(scorer(one.part_meshes(0), gt).iou)
            after.append(scorer(moved.part_meshes(0), gt).iou)
            whole.append(scorer(along_rays(one, centre, d, d + shift).part_meshes(0), gt).iou)
            relative.append(scorer(along_rays(one, centre, d, target - shift).part_meshes(0), gt).iou)
            shifts.append(float(shift))
            if args.best_shift:
                ious = [scorer(along_rays(one, centre, d, d + float(g)).part_meshes(0), gt).iou for g in GRID]
                best.append(max(ious))
                best_shift.append(float(GRID[int(np.argmax(ious))]))
            moves.extend((moved.translations[0] - one.translations[0]).norm(dim=-1).tolist())
            d_pred.extend(depth[i].tolist())
            d_tri.extend(target.tolist())
            for n, e in enumerate((d - target).abs().tolist()):
                errors[n].append(e)
    b = np.array(before)

    def paired(x: list[float]) -> dict:  # the mean IoU of a variant and its paired difference to the prediction
        dx = np.array(x) - b
        return {"iou": float(np.mean(x)), "gain": float(dx.mean()),
                "gain_se": float(dx.std(ddof=1) / np.sqrt(len(dx))) if len(dx) > 1 else 0.0, "improved": int((dx > 0).sum())}
    dp, dt = np.array(d_pred), np.array(d_tri)
    slope = float(np.polyfit(dt, dp, 1)[0])
    corr = float(np.corrcoef(dt, dp)[0, 1])
    dm = np.array(d_mass)
    oracle = paired(after)
    figures = {"run": str(args.run), "images": len(b), "poses": len(poses), "iou": float(b.mean()),
               "oracle_iou": oracle["iou"], "gain": oracle["gain"], "gain_se": oracle["gain_se"],
               "improved": oracle["improved"], "median_move": float(np.median(moves)),
               "depth_slope": slope, "depth_correlation": corr,
               "whole_body": {**paired(whole), "mean_abs_shift": float(np.abs(shifts).mean())},
               "relative": paired(relative),
               "per_part_depth_error": [float(np.mean(errors[n])) for n in sorted(errors)],
               "translation_depth_error": float(np.abs(dp - dt).mean()), "mass_depth_error": float(np.abs(dm - dt).mean()),
               "median_mass_offset": float(np.median(np.abs(dm - dp))),
               "mass_offset_vs_depth_error": float(np.corrcoef(dm - dp, dp - dt)[0, 1]),
               "median_flatness": float(np.median(flat_pred)), "median_flatness_gt_parts": float(np.median(flat_gt)),
               "largest_local_coordinate": max(local_max), "median_largest_extent": float(np.median(extents))}
    print(f"{figures['images']} images of {figures['poses']} poses: voxel IoU {figures['iou']:.4f} -> "
          f"{figures['oracle_iou']:.4f} with each part at its triangulated depth "
          f"({figures['gain']:+.4f} ± {figures['gain_se']:.4f}, better on {figures['improved']} / {figures['images']})")
    for key, what in (("whole_body", "one shift per image (the whole body)"),
                      ("relative", "each part's own correction less that shift")):
        f = figures[key]
        print(f"  {what}: {f['iou']:.4f} ({f['gain']:+.4f} ± {f['gain_se']:.4f}, better on {f['improved']})")
    print(f"  mean |whole-body shift| {figures['whole_body']['mean_abs_shift']:.4f} world units")
    if args.best_shift:
        bs = np.array(best_shift)
        figures["best_shift"] = {**paired(best), "mean_abs_shift": float(np.abs(bs).mean()),
                                 "correlation_with_triangulated": float(np.corrcoef(bs, shifts)[0, 1])}
        f = figures["best_shift"]
        print(f"  the best shift per image against the ground truth: {f['iou']:.4f} ({f['gain']:+.4f} ± "
              f"{f['gain_se']:.4f}), mean |shift| {f['mean_abs_shift']:.4f}, correlation with the triangulated "
              f"shift {f['correlation_with_triangulated']:.2f}")
    print(f"median move {figures['median_move']:.3f} world units; predicted vs triangulated depth: "
          f"slope {slope:.2f}, correlation {corr:.2f}")
    print(f"mean |depth error| of the translations {figures['translation_depth_error']:.3f}, of the parts' vertex means "
          f"{figures['mass_depth_error']:.3f}; median |mass - translation| along the view "
          f"{figures['median_mass_offset']:.3f}, its correlation with the translation's error "
          f"{figures['mass_offset_vs_depth_error']:+.2f}")
    print("per-part mean |depth error|: " + ", ".join(f"{n}: {e:.3f}" for n, e in
                                                      enumerate(figures["per_part_depth_error"])))
    print(f"flatness (smallest / middle extent, median): predicted parts {figures['median_flatness']:.2f}, "
          f"ground-truth body parts {figures['median_flatness_gt_parts']:.2f}; local frames: largest |coordinate| "
          f"{figures['largest_local_coordinate']:.3f}, median largest part extent {figures['median_largest_extent']:.3f}")
    if args.json:
        with open(args.json, "w", encoding="utf-8") as fh:
            json.dump(figures, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
