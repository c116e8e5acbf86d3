"""The per-part depth oracle: what the voxel IoU would be if every part sat at the right depth.

    python experiments/depth/depth_oracle.py RUN DATA [--limit N] [--json OUT]

Every test pose is seen from several views. For each pose and each learned part, the part's rays
(from each view's camera centre through the keypoint that view predicts for it) are intersected in
the least-squares sense: the *triangulated* part position. Each image's parts are then moved along
their *own* camera rays to the depth of that point, so the input view stays exactly as predicted,
and the moved reconstruction is scored like ``cerberus eval`` (32^3, ``kato``, union of parts):

* **IoU** before and after, and the paired difference (mean ± s.e. over images, images improved);
* **the moves**: median distance a part moves, and the predicted against the triangulated depth
  (least-squares slope and correlation over every part of every image: slope 1 and correlation 1
  mean the depths are already consistent across views);
* **per part**: the mean absolute depth error (world units);
* **flatness**: the median ratio of each part's smallest to middle extent (principal axes of its
  vertices), for the predicted parts and for the ground-truth body parts: a part much flatter than the
  body's would be a thin sheet, whatever its depth; and the parts' size in their local frames (the
  largest local coordinate, against ``model.vertex_bound``, and the median largest extent).

A small gain (<= 0.02) says depth is learned; a large one says the parts sit right in their input
view but not in 3D (``cerberus eval`` shows the same as the translation disagreement and the
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
from cerberus_core.run import Run


def triangulate(origins: torch.Tensor, directions: torch.Tensor) -> torch.Tensor:
    """``(N, 3)`` least-squares intersection of ``K`` rays per point: ``origins`` ``(K, 3)`` (the
    cameras' centres), ``directions`` ``(K, N, 3)`` unit vectors."""
    eye = torch.eye(3, dtype=directions.dtype)
    proj = eye - directions.unsqueeze(-1) * directions.unsqueeze(-2)  # (K, N, 3, 3)
    lhs = proj.sum(0)
    rhs = (proj @ origins.view(-1, 1, 3, 1).to(directions.dtype)).sum(0)
    return torch.linalg.solve(lhs, rhs).squeeze(-1)


def flatness(points: np.ndarray) -> float:
    """Smallest over middle principal extent (standard deviation along the principal axes) of a point set."""
    centred = points - points.mean(0)
    s = np.sort(np.linalg.svd(centred, compute_uv=False))
    return float(s[0] / s[1]) if s[1] > 0 else 0.0


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 2)[2],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run", help="run folder, weights file or shipped model name")
    p.add_argument("data", help="dataset folder with a test split (several views per pose)")
    p.add_argument("--limit", type=int, default=None, help="first N test poses only (default all)")
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
    before, after, moves, d_pred, d_tri = [], [], [], [], []
    errors = defaultdict(list)
    flat_pred, flat_gt, local_max, extents = [], [], [], []
    for views in poses:
        centres = torch.cat([cams[i].center for i in views])  # (K, 3)
        rays = torch.stack([cams[i].unproject(uv[i].unsqueeze(0), torch.ones(1, uv[i].shape[0]))[0] for i in views])
        dirs = torch.nn.functional.normalize(rays - centres.unsqueeze(1), dim=-1)  # (K, N, 3)
        point = triangulate(centres, dirs)  # (N, 3) world
        for k, i in enumerate(views):
            body = dataset.gt_mesh(i)
            gt = (body.vertices, body.faces)
            one = recon[i]
            flat_pred += [flatness(v.numpy()) for v in one.posed()[0]]
            local = one.local_vertices[0]  # (N, V, 3)
            local_max.append(float(local.abs().max()))
            extents += (local.amax(1) - local.amin(1)).amax(-1).tolist()
            labels = np.asarray(body.vertex_parts)
            flat_gt += [flatness(np.asarray(body.vertices)[labels == k]) for k in np.unique(labels)
                        if (labels == k).sum() >= 4]
            _, target = cams[i].project(point.unsqueeze(0))  # (1, N) triangulated depth in this view
            scale = (target[0] / depth[i]).view(-1, 1)  # move along the own ray: c + s (T - c)
            centre = centres[k]
            moved_t = centre + scale * (one.translations[0] - centre)
            moved = PartSet(one.local_vertices, one.faces, one.rotations, moved_t.unsqueeze(0))
            before.append(scorer(one.part_meshes(0), gt).iou)
            after.append(scorer(moved.part_meshes(0), gt).iou)
            moves.extend((moved_t - one.translations[0]).norm(dim=-1).tolist())
            d_pred.extend(depth[i].tolist())
            d_tri.extend(target[0].tolist())
            for n, e in enumerate((depth[i] - target[0]).abs().tolist()):
                errors[n].append(e)
    b, a = np.array(before), np.array(after)
    diff = a - b
    dp, dt = np.array(d_pred), np.array(d_tri)
    slope = float(np.polyfit(dt, dp, 1)[0])
    corr = float(np.corrcoef(dt, dp)[0, 1])
    figures = {"run": str(args.run), "images": len(b), "poses": len(poses), "iou": float(b.mean()),
               "oracle_iou": float(a.mean()), "gain": float(diff.mean()),
               "gain_se": float(diff.std(ddof=1) / np.sqrt(len(diff))) if len(diff) > 1 else 0.0,
               "improved": int((diff > 0).sum()), "median_move": float(np.median(moves)),
               "depth_slope": slope, "depth_correlation": corr,
               "per_part_depth_error": [float(np.mean(errors[n])) for n in sorted(errors)],
               "median_flatness": float(np.median(flat_pred)), "median_flatness_gt_parts": float(np.median(flat_gt)),
               "largest_local_coordinate": max(local_max), "median_largest_extent": float(np.median(extents))}
    print(f"{figures['images']} images of {figures['poses']} poses: voxel IoU {figures['iou']:.4f} -> "
          f"{figures['oracle_iou']:.4f} with each part at its triangulated depth "
          f"({figures['gain']:+.4f} ± {figures['gain_se']:.4f}, better on {figures['improved']} / {figures['images']})")
    print(f"median move {figures['median_move']:.3f} world units; predicted vs triangulated depth: "
          f"slope {slope:.2f}, correlation {corr:.2f}")
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
