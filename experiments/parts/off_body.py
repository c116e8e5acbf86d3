"""Where a model's wrong voxels lie: how far off the body, and under how many parts.

    python experiments/parts/off_body.py RUN DATA [--images N]

``cerberus eval`` gives the voxel precision and recall; this says what kind of error they are. On every
``N``-th test image (evenly spaced, ``N`` images in all), scored like ``cerberus eval`` (32³, ``kato``, each part
voxelized alone and the parts OR-ed):

* per image, the voxels both have, the prediction's off the body, the body's missed, and the body's;
* **off the body**: the share of those voxels within 1, 1.5 and 2 voxels of the body's solid (Euclidean distance
  between voxel centres), and beyond 2: a shell one voxel thick is a surface a little too far out everywhere,
  while voxels beyond 2 are volume in the wrong place;
* **missed**: the same, measured inwards from the outside of the body;
* the share of the off-body voxels that one, two, or three or more parts cover: voxels under several parts are
  where the parts' surfaces overlap at the body's outline.

One thread; about a minute for 120 images.
"""
from __future__ import annotations

import argparse
import sys
import warnings

import numpy as np
import torch
from scipy.ndimage import distance_transform_edt

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.runner import iterate_batches
from cerberus_core.run import Run


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
    p.add_argument("run", help="run folder, weights file or shipped model name")
    p.add_argument("data", help="dataset folder with a test split")
    p.add_argument("--images", type=int, default=120, help="test images, evenly spaced (default 120)")
    args = p.parse_args(argv)
    from cerberus_metrics.api import prediction_grids

    torch.set_num_threads(1)
    warnings.simplefilter("ignore")  # mesh-quality warnings on predicted parts, as in cerberus eval
    model = Run.load(args.run).model.eval()
    test = Dataset.open(args.data).views("test")
    chosen = list(range(0, len(test), max(1, len(test) // args.images)))[:args.images]
    counts, off, missed, cover = np.zeros(4), [], [], []
    for idx, batch, camera in iterate_batches(test, chosen, 16):
        with torch.no_grad():
            parts = model.pose(model(batch["images"]), camera)
        for b, i in enumerate(idx):
            body = test.gt_mesh(i)
            grids, truth = prediction_grids(parts.part_meshes(b), (np.asarray(body.vertices), np.asarray(body.faces)),
                                            "kato", 32, None, "clamp")
            f = off_body_counts(grids.occupancy, truth.occupancy)
            counts += f["counts"]
            off.append(f["off"])
            missed.append(f["missed"])
            cover.append(f["cover"])
    off, missed, cover = np.concatenate(off), np.concatenate(missed), np.concatenate(cover)
    both, out, miss, gt = counts / len(chosen)
    print(f"{args.run}: {len(chosen)} test images; per image {both:.0f} voxels both have, {out:.0f} off the body, "
          f"{miss:.0f} missed, of the body's {gt:.0f}")
    print(f"  off the body within 1 / 1.5 / 2 voxels of it: {(off <= 1).mean():.2f} / {(off <= 1.5).mean():.2f} / "
          f"{(off <= 2).mean():.2f}; beyond 2: {(off > 2).mean():.2f}")
    print(f"  missed within 1 / 1.5 voxels of its outside: {(missed <= 1).mean():.2f} / {(missed <= 1.5).mean():.2f}; "
          f"beyond 2: {(missed > 2).mean():.2f}")
    print(f"  off-body voxels under 1 / 2 / 3+ parts: {(cover == 1).mean():.2f} / {(cover == 2).mean():.2f} / "
          f"{(cover >= 3).mean():.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
