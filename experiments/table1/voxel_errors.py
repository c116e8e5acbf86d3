"""Where a run's voxel IoU goes: voxel precision and recall, and what an oracle depth fix would add.

    python experiments/table1/voxel_errors.py RUN DATA [--images 48]

For an evenly spaced subset of the test images, each reconstruction is voxelized like ``cerberus eval``
(32^3, ``kato`` protocol, union of parts) and compared with the ground truth:

* **precision** |P & G| / |P| (how much of the prediction is on the body) and **recall** |P & G| / |G|
  (how much of the body it covers), and the median volume ratio |P| / |G|;
* **depth oracle**: the best IoU over scalings of the prediction about the camera centre (0.80-1.25).
  Such a scaling keeps the prediction's image exactly and changes only its distance and size, the
  ambiguity one view leaves; the gain is what a perfect depth and size would add;
* **thickness oracle**: the best IoU over stretches of the prediction along the viewing direction
  about its centroid (x0.5-x2.5): what a perfect front-to-back thickness would add;
* **where the wrong voxels lie**: per image the voxels both have, off the body, missed, and the body's; the share of
  the off-body voxels within 1, 1.5 and 2 voxels of the body's solid (distance between voxel centres) and beyond 2
  (a shell one voxel thick is a surface a little too far out everywhere; beyond 2, volume in the wrong place); the
  same for the missed voxels, measured inwards; and the share of the off-body voxels under one, two, or three or
  more parts (each part voxelized alone): where parts overlap at the body's outline, the union takes whichever
  surface reaches furthest out.

A small gain from both oracles with a low precision says the error is in the image plane (limbs in the
wrong place or the wrong width), not in depth. Single thread; about 2 minutes for 48 images.
"""
from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np
import torch
from scipy.ndimage import distance_transform_edt

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.runner import iterate_batches, reconstruct_batch
from cerberus_core.run import Run
from cerberus_metrics.api import prediction_grids, voxelize

SCALES = np.linspace(0.8, 1.25, 10)
STRETCHES = (0.5, 0.7, 0.85, 1.0, 1.2, 1.5, 2.0, 2.5)


def _iou(parts, gt_grid) -> tuple[float, float, float, float]:
    """(IoU, precision, recall, volume ratio) of parts against a ground-truth grid; the voxels of parts
    leaving the grid are dropped (``outside="clamp"``), as ``cerberus eval`` does."""
    return _scores(voxelize(parts, frame=gt_grid.frame, check_self_intersections=False, outside="clamp").occupancy,
                   gt_grid.occupancy)


def _scores(pred: np.ndarray, true: np.ndarray) -> tuple[float, float, float, float]:
    """(IoU, precision, recall, volume ratio) of two occupancy grids on one lattice."""
    inter = float((pred & true).sum())
    return (inter / max(1.0, float((pred | true).sum())), inter / max(1.0, float(pred.sum())),
            inter / max(1.0, float(true.sum())), float(pred.sum()) / max(1.0, float(true.sum())))


def _oracles(parts, gt_grid, centre: np.ndarray, view: np.ndarray) -> tuple[float, float]:
    """Best IoU over scalings about the camera ``centre`` and over stretches along ``view``."""
    mean = np.concatenate([v for v, _ in parts]).mean(0)
    depth = max(_iou([(centre + s * (v - centre), f) for v, f in parts], gt_grid)[0] for s in SCALES)
    thick = max(_iou([(v + (k - 1) * ((v - mean) @ view)[:, None] * view, f) for v, f in parts], gt_grid)[0]
                for k in STRETCHES)
    return depth, thick


def off_body_counts(parts: np.ndarray, body: np.ndarray) -> dict[str, np.ndarray]:
    """One image's wrong voxels, from each part's occupancy ``parts`` ``(P, X, Y, Z)`` bool and the body's ``body``
    ``(X, Y, Z)`` bool on the same lattice: ``counts`` ``(4,)`` (both, off the body, missed, the body's), ``off``
    the off-body voxels' distances to the body's solid, ``missed`` the missed voxels' distances to its outside
    (voxel units), and ``cover`` how many parts cover each off-body voxel.

    >>> body = np.zeros((5, 5, 5), bool); body[1:4, 1:4, 1:4] = True
    >>> parts = np.stack([body.copy(), body.copy()]); parts[0, 0, 2, 2] = parts[1, 0, 2, 2] = True  # one voxel out
    >>> parts[1, 2, 2, 2] = False  # the centre, still covered by part 0
    >>> f = off_body_counts(parts, body)
    >>> f["counts"].tolist(), f["off"].tolist(), f["cover"].tolist()
    ([27, 1, 0, 27], [1.0], [2])
    """
    pred = parts.any(0)
    off, missed = pred & ~body, body & ~pred
    return {"counts": np.array([(pred & body).sum(), off.sum(), missed.sum(), body.sum()]),
            "off": distance_transform_edt(~body)[off], "missed": distance_transform_edt(body)[missed],
            "cover": parts.sum(0)[off]}


def main(argv: list[str]) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0], epilog=__doc__.split("\n\n", 2)[2],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("run", help="run folder (or checkpoint)")
    p.add_argument("data", help="dataset folder with a test split")
    p.add_argument("--images", type=int, default=48, help="test images, evenly spaced (default 48)")
    args = p.parse_args(argv)
    if args.images < 1:
        p.error(f"--images {args.images}: must be at least 1")
    torch.set_num_threads(1)
    warnings.simplefilter("ignore")  # mesh-quality warnings on predicted parts, as in cerberus eval
    model = Run.load(args.run).model
    dataset = Dataset.open(args.data).views("test")
    indices = list(range(0, len(dataset), max(1, len(dataset) // args.images)))[:args.images]
    rows, counts, off, missed, cover = [], np.zeros(4), [], [], []
    for batch_idx, batch, camera in iterate_batches(dataset, indices, 16):
        recon = reconstruct_batch(model.reconstruct, batch["images"], camera, "cpu")
        for b, i in enumerate(batch_idx):
            body = dataset.gt_mesh(i)
            parts = [(np.asarray(v, np.float64), np.asarray(f)) for v, f in recon.index(b).part_meshes(0)]
            rot = camera.rotation[b].double().numpy()
            centre = -rot.T @ camera.translation[b].double().numpy()
            # each part voxelized once, in the ground truth's frame: the union scores it, the parts place its errors
            # (the options of cerberus eval's scorer, VoxelIoUScorer: the ground truth strict, the parts clamped)
            grids, gt_grid = prediction_grids(parts, (body.vertices, body.faces), "kato", 32, None, "clamp", False,
                                              gt_open_mesh="error", quiet_pred=True)
            rows.append((*_scores(grids.union().occupancy, gt_grid.occupancy),
                         *_oracles(parts, gt_grid, centre, rot.T @ np.array([0.0, 0.0, 1.0]))))
            f = off_body_counts(grids.occupancy, gt_grid.occupancy)
            counts += f["counts"]
            off.append(f["off"])
            missed.append(f["missed"])
            cover.append(f["cover"])
    a = np.array(rows)
    print(f"{args.run}: {len(a)} test images: IoU {a[:, 0].mean():.4f}, precision {a[:, 1].mean():.4f}, "
          f"recall {a[:, 2].mean():.4f}, volume ratio {np.median(a[:, 3]):.3f} (median); "
          f"depth oracle {a[:, 4].mean():.4f} ({a[:, 4].mean() - a[:, 0].mean():+.4f}), "
          f"thickness oracle {a[:, 5].mean():.4f} ({a[:, 5].mean() - a[:, 0].mean():+.4f})")
    off, missed, cover = np.concatenate(off), np.concatenate(missed), np.concatenate(cover)
    both, out, miss, gt = counts / len(a)
    print(f"  per image {both:.0f} voxels both have, {out:.0f} off the body, {miss:.0f} missed, of the body's {gt:.0f}")
    print(f"  off the body within 1 / 1.5 / 2 voxels of it: {(off <= 1).mean():.2f} / {(off <= 1.5).mean():.2f} / "
          f"{(off <= 2).mean():.2f}; beyond 2: {(off > 2).mean():.2f}")
    print(f"  missed within 1 / 1.5 voxels of its outside: {(missed <= 1).mean():.2f} / {(missed <= 1.5).mean():.2f}; "
          f"beyond 2: {(missed > 2).mean():.2f}")
    print(f"  off-body voxels under 1 / 2 / 3+ parts: {(cover == 1).mean():.2f} / {(cover == 2).mean():.2f} / "
          f"{(cover >= 3).mean():.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
