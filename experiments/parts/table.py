"""The parts-that-move screen of docs/results.md ("Parts that move", issue 38): one row per evaluated run, the
allocation columns beside the IoU, each run paired with the first on the same test images.

    python experiments/parts/table.py NAME=RUN [NAME=RUN ...]

Each RUN holds ``eval/results.json`` (``cerberus eval RUN``). Columns: voxel IoU; the paired difference to the
first run (mean ± s.e., images better); Hard Human; spare parts (deleting one costs <= 0.003 IoU); voxel
recall of the lower arms and the shins; the four largest keypoint spreads (px, per part the std over images of
keypoint minus silhouette centroid); the median distance from the forearms' and the shins' projected
centroids to the nearest keypoint (px); the mean translation disagreement between two views of a pose (world
units); the labels among head, thigh, shin and lower arm that a part takes with agreement >= 0.5, left and right
merged; training minutes.
"""
from __future__ import annotations

import csv
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "table1"))
from table import paired  # noqa: E402  (the paired difference of experiments/table1/table.py)

LIMBS = ("head", "thigh", "shin", "lower_arm")


def row(name: str, run: Path, base: dict | None) -> str:
    res = json.loads((run / "eval" / "results.json").read_text())
    seg = (res.get("segments") or {})
    recall = seg.get("recall") or {}
    alloc = res.get("allocation") or {}
    spread = sorted(alloc.get("keypoint_spread") or [], reverse=True)[:4]
    to_kp = alloc.get("segment_to_keypoint") or {}
    depth = res.get("depth") or {}
    quality = res.get("part_quality") or {}
    parts = (quality.get("sides_merged") or quality).get("parts", [])  # left and right merged, as issue 38 counts
    named = sorted({p["label"].split(".")[0] for p in parts if p.get("label", "").split(".")[0] in LIMBS
                    and p["agreement"] >= 0.5})
    metrics = run / "metrics.csv"
    rows = list(csv.DictReader(metrics.open())) if metrics.is_file() else []
    minutes = f"{float(rows[-1]['elapsed_s']) / 60:.0f}" if rows else "-"
    spare = seg.get("spare_count")
    spare = f"{spare} of {len(seg.get('deletion_loss') or []) or '?'}" if spare is not None else "-"
    diff = paired(res, base) if base is not None else None
    versus = "–" if diff is None else f"{diff[0]:+.3f} ± {diff[1]:.3f} ({diff[2]})"

    return (f"| {name} | {res['standard']['mean']:.4f} | {versus} | "
            f"{(res.get('hard') or {}).get('mean', float('nan')):.4f} | {spare} | "
            f"{', '.join(f'{recall[n]:.2f}' for n in ('lower_arm.L', 'lower_arm.R') if n in recall)} / "
            f"{', '.join(f'{recall[n]:.2f}' for n in ('shin.L', 'shin.R') if n in recall)} | "
            f"{' '.join(f'{s:.1f}' for s in spread) or '-'} | "
            f"{', '.join(f'{to_kp[n]:.1f}' for n in ('lower_arm.L', 'lower_arm.R') if n in to_kp)} / "
            f"{', '.join(f'{to_kp[n]:.1f}' for n in ('shin.L', 'shin.R') if n in to_kp)} | "
            f"{depth.get('mean_translation_disagreement', float('nan')):.3f} | {', '.join(named) or '-'} | {minutes} |")


def main(argv: list[str]) -> int:
    if not argv or any("=" not in a for a in argv):
        print(__doc__, file=sys.stderr)
        return 2
    runs = [(a.split("=", 1)[0], Path(a.split("=", 1)[1])) for a in argv]
    base = json.loads((runs[0][1] / "eval" / "results.json").read_text())
    print("| row | IoU | vs first | Hard | spare | lower arm / shin recall | keypoint spread, top 4 (px) | "
          "forearm / shin → keypoint (px) | translation disagreement | merged labels ≥ 0.5 | minutes |")
    print("| --- | ---: | ---: | ---: | ---: | --- | --- | --- | ---: | --- | ---: |")
    for name, run in runs:
        res_path = run / "eval" / "results.json"
        if not res_path.is_file():
            print(f"| {name} | - | not evaluated ({res_path}) |")
            continue
        print(row(name, run, None if run == runs[0][1] else base))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
