"""How concentrated each part's keypoint probability map is (issue 38: is the keypoint a body-wide average?).

For each model, every 8th test view of DATA: the root mean square distance of a part's probability map from its own
keypoint, ``sqrt(sum_xy p_xy ||(x, y) - (u, v)||^2)`` in pixels of the input (KeypointNet's variance, the square
root), its median over the views per part, and the mean of the variance over parts and views in image heights
squared. A map spread over the whole standing body would read about 11 px (0.03).

    python experiments/parts/map_spread.py data/human_large human runs/parts/cpu
"""
from __future__ import annotations

import argparse

import torch

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.run import Run


def spread(prob: torch.Tensor, uv: torch.Tensor) -> torch.Tensor:
    """``(B, N, H, W)`` maps and ``(B, N, 2)`` keypoints (pixels) -> ``(B, N)`` mean squared distance (pixels^2)."""
    h, w = prob.shape[-2:]
    xs = torch.arange(w, dtype=prob.dtype) + 0.5
    ys = torch.arange(h, dtype=prob.dtype) + 0.5
    across = (prob.sum(-2) * (xs - uv[..., 0:1]).square()).sum(-1)
    down = (prob.sum(-1) * (ys - uv[..., 1:2]).square()).sum(-1)
    return across + down


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("data", help="a dataset folder with a test split")
    parser.add_argument("models", nargs="+", help="shipped model names or run folders")
    args = parser.parse_args()
    torch.set_num_threads(1)
    views = Dataset.open(args.data).views("test")
    images = torch.stack([views[i]["images"] for i in range(0, len(views), 8)])
    for name in args.models:
        with torch.no_grad():
            maps = Run.load(name).model(images).maps
        var = spread(maps.prob, maps.uv)  # (B, N) px^2
        rms = var.median(0).values.sqrt()
        h = images.shape[-2]
        print(f"{name}: {len(images)} views, variance {float((var / h**2).mean()):.4f} image heights^2, "
              f"rms per part (median, px): {' '.join(f'{x:.1f}' for x in rms.tolist())}")


if __name__ == "__main__":
    main()
