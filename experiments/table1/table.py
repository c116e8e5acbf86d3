"""Print Table 1 of docs/results.md from the evaluated runs of ``experiments/table1/run.sh``.

    python experiments/table1/table.py runs/table1 > runs/table1/table1.md

Reads ``RUNS/<dataset>_<variant>/eval/results.json`` (written by ``cerberus eval``) and
``RUNS/<dataset>_<variant>/metrics.csv`` (training time), and prints Markdown: the paper's Table 1
layout (voxel IoU, 32^3, kato protocol) with the paper's numbers beside ours, then part quality and
training cost. A run that is missing shows ``-``.
"""
from __future__ import annotations

import csv
import sys
from pathlib import Path

from cerberus_core.eval.compare import load_evaluation, paired_difference
from cerberus_core.eval.markdown import markdown_table
from cerberus_core.eval.report import comparison_table
from cerberus_core.plumbing.metrics_csv import TrainingTime, training_time

VARIANTS = {"nmrr": "NMRr", "free_cerberus": "Free Cerberus", "cerberus": "Cerberus"}
PAPER = {  # Deng, Kornblith & Hinton, Table 1: voxel IoU on Human, Hard Human, Animal
    "NMRr": {"Human": 0.3084, "Hard Human": None, "Animal": 0.3201},
    "Free Cerberus": {"Human": 0.5099, "Hard Human": 0.4365, "Animal": 0.4196},
    "Cerberus": {"Human": 0.4970, "Hard Human": 0.4728, "Animal": 0.4255},
}


def load(runs: Path, dataset: str, variant: str) -> tuple[dict | None, list[dict], TrainingTime | None]:
    """The run's ``results.json`` (or None), its ``metrics.csv`` rows (or []) and its training steps and time
    summed over the sittings (:func:`~cerberus_core.plumbing.metrics_csv.training_time`; None without a log)."""
    run = runs / f"{dataset}_{variant}"
    results = load_evaluation(run, missing_ok=True)
    log = run / "metrics.csv"
    rows = list(csv.DictReader(log.open())) if log.is_file() else []
    return results, rows, training_time(log)


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    runs = Path(argv[0])
    ours: dict[str, dict[str, float | None]] = {}
    quality, cost = [], []
    for variant, label in VARIANTS.items():
        human, human_log, human_time = load(runs, "human", variant)
        animal, animal_log, animal_time = load(runs, "animal", variant)
        hard = (human or {}).get("hard") or {}
        ours[label] = {"Human": (human or {}).get("standard", {}).get("mean"),
                       "Hard Human": hard.get("mean") if variant != "nmrr" else None,
                       "Animal": (animal or {}).get("standard", {}).get("mean")}
        for name, res in (("Human", human), ("Animal", animal)):
            pq = (res or {}).get("part_quality") or {}
            one_part = len(pq.get("parts", [])) == 1  # consistency is trivially 1 for a single mesh
            quality.append([f"{label}, {name}", None if one_part else pq.get("consistency"),
                            None if one_part else pq.get("mean_entropy_bits"), pq.get("mean_segmentation_iou"),
                            len(pq.get("unused_parts", []) or []) if pq else None])
        for name, log, trained in (("Human", human_log, human_time), ("Animal", animal_log, animal_time)):
            if trained:
                tail = log[-max(1, len(log) // 20):]  # last 5% of the logged steps
                recon = sum(float(r["recon"]) for r in tail) / len(tail)
                cost.append([f"{label}, {name}", f"{trained.steps:,}", f"{trained.seconds / 60:.1f}",
                             f"{trained.steps / trained.seconds:.2f}", recon])
            else:
                cost.append([f"{label}, {name}", None, None, None, None])
    res = {(ds, v): load(runs, ds, v)[0] for ds in ("human", "animal") for v in VARIANTS}
    comparisons = [
        ("Human: Cerberus - NMRr", paired_difference(res["human", "cerberus"], res["human", "nmrr"])),
        ("Human: Free Cerberus - Cerberus", paired_difference(res["human", "free_cerberus"], res["human", "cerberus"])),
        ("Hard Human: Cerberus - Free Cerberus", paired_difference(res["human", "cerberus"],
                                                                   res["human", "free_cerberus"], "hard_iou")),
        ("Cerberus: Human - Hard Human", paired_difference(res["human", "cerberus"], res["human", "cerberus"],
                                                           "iou", "hard_iou")),
        ("Free Cerberus: Human - Hard Human", paired_difference(res["human", "free_cerberus"],
                                                                res["human", "free_cerberus"], "iou", "hard_iou")),
        ("Animal: Cerberus - NMRr", paired_difference(res["animal", "cerberus"], res["animal", "nmrr"])),
        ("Animal: Free Cerberus - Cerberus", paired_difference(res["animal", "free_cerberus"],
                                                               res["animal", "cerberus"])),
    ]
    columns = ["Human", "Hard Human", "Animal"]
    print("### Voxel IoU (32^3, kato protocol, union of parts), ours\n")
    print(comparison_table(ours, columns))
    print("\n### The paper's Table 1\n")
    print(comparison_table(PAPER, columns))
    print("\n### Paired differences over the same test images (one training run each)\n")
    print(markdown_table(["Difference", "mean IoU difference", "standard error", "images where positive"],
                         [[name, *((c.mean, c.sem, f"{c.better} / {c.n}") if c else (None, None, None))]
                          for name, c in comparisons], digits=4))
    print("\n### Part quality against the ground-truth parts (never seen in training)\n")
    print("Consistency and entropy are left out for NMRr: one mesh is trivially consistent.\n")
    print(markdown_table(["Run", "consistency", "entropy (bits)", "mean segmentation IoU", "unused parts"],
                         quality, digits=3))
    print("\n### Training\n")
    print(markdown_table(["Run", "steps", "wall time (min)", "steps/s", "final recon MSE"], cost, digits=4))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
