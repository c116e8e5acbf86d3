"""Print the ablation table of docs/results.md from the evaluated runs of ``experiments/ablation/run.sh``.

    python experiments/ablation/table.py runs/ablation > runs/ablation/ablation.md

Reads ``RUNS/plan.txt`` (the variants in order: ``NAME|DATA|TRAIN ARGS``), each run's
``eval/results.json`` (``cerberus eval``) and ``metrics.csv`` (training speed). Prints one Markdown table:
voxel IoU and Hard Human with the paired difference to the first variant (the baseline) over the same
test images, part quality (consistency; the learned parts whose label is the head or a limb, with their
agreement), how many parts are hidden in most test images (when ``cerberus eval`` measured it), depth
across views (the turned-view silhouette IoU and the mean translation disagreement, world units), and
steps per second. A variant that is missing shows ``-``.
"""
from __future__ import annotations

import sys
from pathlib import Path

from cerberus_core.eval.compare import load_evaluation, paired_difference
from cerberus_core.train.logs import TrainingTime, training_time

LIMBS = ("head", "upper_arm", "lower_arm", "thigh", "shin")


def load(run: Path) -> tuple[dict | None, TrainingTime | None]:
    return load_evaluation(run, missing_ok=True), training_time(run / "metrics.csv")


def limb_parts(pq: dict) -> str:
    rows = [r for r in pq.get("parts", []) if r.get("label") and r["label"].split(".")[0] in LIMBS]
    return ", ".join(f"{r['label']} ({r['agreement']:.2f})" for r in sorted(rows, key=lambda r: -r["agreement"])) or "none"


def fmt(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    runs = Path(argv[0])
    plan = [line.split("|") for line in (runs / "plan.txt").read_text().splitlines() if line.strip()]
    loaded = {name: load(runs / name) for name, _, _ in plan}
    base = loaded[plan[0][0]][0]
    print("| variant | voxel IoU | vs baseline (mean ± s.e., images better) | Hard Human | part consistency | "
          "head / limb parts (agreement) | parts hidden in most images | turned-view silhouette IoU | "
          "translation disagreement | steps/s |")
    print("| :--- | ---: | ---: | ---: | ---: | :--- | ---: | ---: | ---: | ---: |")
    for name, _, _ in plan:
        res, trained = loaded[name]
        std = (res or {}).get("standard") or {}
        hard = (res or {}).get("hard") or {}
        pq = (res or {}).get("part_quality") or {}
        vis = (res or {}).get("part_visibility") or {}
        hidden = vis.get("parts_hidden_in_most_images")
        speed = f"{trained.steps / trained.seconds:.2f}" if trained else "-"
        depth = (res or {}).get("depth") or {}
        versus = "-" if res is base else paired_difference(res, base) or "-"
        print(f"| {name} | {fmt(std.get('mean'))} | {versus} | {fmt(hard.get('mean'))} | "
              f"{fmt(pq.get('consistency'))} | {limb_parts(pq) if pq else '-'} | "
              f"{'-' if hidden is None else hidden} | {fmt(depth.get('turned_view_silhouette_iou'))} | "
              f"{fmt(depth.get('mean_translation_disagreement'))} | {speed} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
