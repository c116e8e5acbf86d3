"""Silhouette coverage of a trained model's reconstructions on a test split, in image space.

    python experiments/table1/silhouettes.py runs/table1/animal_cerberus data/animal

Each test image is reconstructed and its posed parts rendered from the image's own camera (Warp
renderer); the predicted mask (alpha) is compared with the true mask (pixels more than 0.02 from the
dataset's background colour in some channel, as the training's background mask). Prints the mean predicted / true silhouette area and the mean silhouette IoU, which
separate "the parts do not cover the body in the image" from "they cover it but sit wrongly in 3D"
when reading a voxel IoU.
"""
from __future__ import annotations

import sys

import torch

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.eval.runner import collate
from cerberus_core.losses import background_mask
from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import make_renderer
from cerberus_core.run import Run

TOLERANCE = 0.02
"""A pixel within this of the background colour in every channel is background (``losses.background_tolerance``)."""


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    run, data = argv
    torch.set_num_threads(1)
    model = Run.load(run).model
    ds = Dataset.open(data).views("test")
    renderer = make_renderer()
    ratios: list[float] = []
    ious: list[float] = []
    for start in range(0, len(ds), 32):
        batch = collate([ds[i] for i in range(start, min(start + 32, len(ds)))])
        cams = ds.cameras(batch)
        with torch.no_grad():
            rec = model.reconstruct(batch["images"], cams)
            out = render_parts(renderer, rec.posed(), rec.faces, cams)
        pred = out.alpha[:, 0] > 0.5
        true = background_mask(batch["images"], ds.scene.background, TOLERANCE)[:, 0] < 0.5
        ratios += (pred.sum((1, 2)).float() / true.sum((1, 2)).clamp(min=1)).tolist()
        ious += ((pred & true).sum((1, 2)).float() / (pred | true).sum((1, 2)).clamp(min=1)).tolist()
    print(f"{run}: predicted / true silhouette area {sum(ratios) / len(ratios):.3f}, "
          f"silhouette IoU {sum(ious) / len(ious):.3f} ({len(ious)} test images)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
