"""How the flat-silhouette test depends on what counts as the body (issue 41).

    python experiments/photo/flat_tolerance.py RUN DATA

Scores RUN's standard voxel IoU on DATA's test split shown flat (each body filled with its mean grey) for
several masks: every pixel off the background by more than a tolerance (0.5/255: every pixel not exactly
the background, the flat look's own; 0.02: the training's background mask; 0.05; 0.1), and the flat grey
blended with the anti-aliased coverage read back from the render (``body_coverage``) instead of a hard mask.
"""
from __future__ import annotations

import sys

import torch

from cerberus_core import Run
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.looks import body_coverage, body_mask
from cerberus_core.eval.runner import evaluate_dataset


def flat(images: torch.Tensor, background, tol: float, soft: bool) -> torch.Tensor:
    m = body_mask(images, background, tol)
    w = m.float()
    grey = (images * w).sum((1, 2, 3), keepdim=True) / (3 * w.sum((1, 2, 3), keepdim=True)).clamp(min=1)
    if soft:
        a = body_coverage(images, background, tol)
        return a * grey + (1 - a) * torch.as_tensor(background).view(3, 1, 1)
    return torch.where(m, grey.expand_as(images), images)


def main(argv: list[str]) -> int:
    if len(argv) != 2:
        print(__doc__, file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    run = Run.load(argv[0])
    views = Dataset.open(argv[1]).views("test")
    bg = views.scene.background
    for tol, soft in [(0.5 / 255, False), (0.02, False), (0.05, False), (0.1, False), (0.5 / 255, True)]:
        result = evaluate_dataset(views, lambda im, cam, t=tol, s=soft: run.model.reconstruct(flat(im, bg, t, s), cam),
                                  skip=("hard", "part_quality", "visibility", "depth", "segments", "allocation"),
                                  progress=False)
        print(f"tolerance {tol:.4f}{', coverage-blended edge' if soft else ''}: voxel IoU {result.standard.mean:.4f}",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
