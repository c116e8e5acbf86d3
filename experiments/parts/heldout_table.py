"""Bodies in poses the generator never made (docs/results.md, "Parts that move"): evaluations of the same
`--size heldout_poses` images, paired per image with the first, with the voxel IoU of each held-out family.

    python experiments/parts/heldout_table.py NAME=EVALDIR [NAME=EVALDIR ...]

Each EVALDIR is a `cerberus eval MODEL --data data/human_heldout --out EVALDIR` folder (its results.json). Columns:
voxel IoU (images); the paired difference to the first (mean ± s.e. of the per-image differences, images
better); Hard Human and its paired difference; the mean IoU of each family (`bodies/human_heldout.py`) and of
the canonical views.
"""
from __future__ import annotations

import sys

import numpy as np

from cerberus_core.bodies.human_heldout import FAMILIES, family_of, is_heldout_id
from cerberus_core.eval.compare import load_evaluation, paired_difference


def _values(res: dict, key: str) -> np.ndarray:
    """``(N,)`` one per record, NaN where the record has none."""
    return np.array([np.nan if r.get(key) is None else r[key] for r in res["records"]], dtype=float)


def main(argv: list[str]) -> None:
    if not argv or any("=" not in a for a in argv):
        raise SystemExit("usage: heldout_table.py NAME=EVALDIR [NAME=EVALDIR ...] (EVALDIR: a `cerberus eval --out` folder)")
    runs = [a.split("=", 1) for a in argv]
    res = {name: load_evaluation(folder) for name, folder in runs}
    first = runs[0][0]
    keys = [(r["subject"], r["pose"], r["view"]) for r in res[first]["records"]]
    for name, folder in runs:
        if [(r["subject"], r["pose"], r["view"]) for r in res[name]["records"]] != keys:
            raise SystemExit(f"{folder} scores other images than {runs[0][1]}: evaluate both on the same --data")
    family = np.array([family_of(p) if is_heldout_id(p) else "canonical" for _, p, _ in keys])
    groups = [*FAMILIES, "canonical"]
    print(f"| model | IoU | vs {first} | Hard Human | vs {first} | " + " | ".join(groups) + " |")
    print("| --- |" + " ---: |" * (4 + len(groups)))
    for name, _ in runs:
        iou, hard = _values(res[name], "iou"), _values(res[name], "hard_iou")
        cells = [name, f"{np.nanmean(iou):.4f}",
                 "–" if name == first else str(paired_difference(res[name], res[first], "iou") or "-"),
                 f"{np.nanmean(hard):.4f}",
                 "–" if name == first else str(paired_difference(res[name], res[first], "hard_iou") or "-")]
        cells += [f"{np.nanmean(iou[family == g]):.3f}" for g in groups]
        print("| " + " | ".join(cells) + " |")


if __name__ == "__main__":
    main(sys.argv[1:])
