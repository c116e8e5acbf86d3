"""How much of the frame the bodies of a dataset fill, and how many views fall apart.

Prints, per dataset folder and split: the body's height in pixels (median, 10th percentile, and
the fraction of views at least 70% of the frame height), the share of pixels on the body, the
fraction of views whose silhouette touches the frame's edge (clipped), and the fraction whose
foreground falls into several 8-connected pieces (aliased limbs). Used for docs/results.md:

    python experiments/data/framing.py data/human data/human_framed --split test
"""
from __future__ import annotations

import argparse

import numpy as np
from scipy import ndimage

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.losses import background_mask


def stats(root: str, split: str, tol: float) -> dict[str, float]:
    ds = Dataset.open(root).views(split=split)
    heights, cover, clipped, pieces = [], [], [], []
    for i in range(len(ds)):
        item = ds[i]
        fg = 1 - background_mask(item["images"], ds.scene.background, tol)[0].numpy()
        size = fg.shape[0]
        rows = np.nonzero(fg.any(1))[0]
        heights.append((rows.max() - rows.min() + 1) / size if len(rows) else 0.0)
        cover.append(fg.mean())
        clipped.append(bool(fg[0].any() or fg[-1].any() or fg[:, 0].any() or fg[:, -1].any()))
        pieces.append(ndimage.label(fg, structure=np.ones((3, 3)))[1] > 1)
    h = np.array(heights)
    return {"views": len(ds), "height_median_px": float(np.median(h) * size), "height_p10_px": float(np.percentile(h, 10) * size),
            "frac_height_ge_70pct": float((h >= 0.7).mean()), "cover": float(np.mean(cover)),
            "clipped": float(np.mean(clipped)), "several_pieces": float(np.mean(pieces)), "size": size}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("roots", nargs="+", help="dataset folders")
    ap.add_argument("--split", default="test")
    ap.add_argument("--tol", type=float, default=0.02, help="background tolerance (losses.background_tolerance)")
    args = ap.parse_args()
    print("| dataset | views | px | body height median (px) | 10th pct | >= 70% of frame | pixels on body | clipped | several pieces |")
    print("|---|---|---|---|---|---|---|---|---|")
    for root in args.roots:
        s = stats(root, args.split, args.tol)
        print(f"| {root} | {s['views']} | {s['size']} | {s['height_median_px']:.1f} | {s['height_p10_px']:.1f} | "
              f"{s['frac_height_ge_70pct']:.0%} | {s['cover']:.1%} | {s['clipped']:.1%} | {s['several_pieces']:.1%} |")


if __name__ == "__main__":
    main()
