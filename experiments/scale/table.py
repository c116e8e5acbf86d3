"""The data-scale table of docs/results.md ("Learning at scale"): test IoU, IoU on the run's own
training images, their gap, and paired differences between runs scored on the same test images.

    python experiments/scale/table.py NAME=RUN [NAME=RUN ...] [--pair A-B ...]

Each RUN holds ``eval/results.json`` (``cerberus eval RUN --data TEST``: the unseen test subjects)
and, if it was measured, ``eval_train/results.json`` (``cerberus eval RUN --data TRAIN --split train
--limit K``: the first K of its own training images); ``metrics.csv`` gives the training time
(summed over the sittings of a resumed run).
``--pair A-B`` prints ``A − B`` per test image (mean ± s.e., images where A is better), e.g.
``--pair cer_s200-nmr_s200`` for the Cerberus − NMRr margin.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from cerberus_core.eval.compare import load_evaluation, paired_difference
from cerberus_core.train.logs import training_time


def summary(run: Path) -> dict:
    test, train = load_evaluation(run / "eval", missing_ok=True), load_evaluation(run / "eval_train", missing_ok=True)
    trained = training_time(run / "metrics.csv")
    pq = (test or {}).get("part_quality") or {}
    vis = (test or {}).get("part_visibility") or {}
    limbs = ", ".join(f"{p['label']} ({p['agreement']:.2f})" for p in pq.get("parts", [])
                      if p.get("label", "").split(".")[0] in ("head", "shin", "thigh", "upper_arm", "lower_arm")
                      and p["agreement"] >= 0.3)
    return {"test": test and test["standard"]["mean"], "hard": test and (test.get("hard") or {}).get("mean"),
            "train": train and train["standard"]["mean"], "train_n": train and train["standard"]["count"],
            "steps": trained and trained.steps, "minutes": trained and trained.seconds / 60,
            "limbs": limbs or "-", "hidden": vis.get("parts_hidden_in_most_images"), "results": test}


def fmt(x: float | None, digits: int = 3) -> str:
    return "-" if x is None else f"{x:.{digits}f}"


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", metavar="NAME=RUN")
    ap.add_argument("--pair", action="append", default=[], metavar="A-B")
    args = ap.parse_args(argv)
    runs = {}
    for item in args.runs:
        name, _, path = item.partition("=")
        runs[name] = summary(Path(path))
    print("| run | test IoU | Hard Human | own training images (n) | gap | steps | minutes | head / limb parts "
          "(agreement) | parts hidden in most images |")
    print("| :--- | ---: | ---: | ---: | ---: | ---: | ---: | :--- | ---: |")
    for name, s in runs.items():
        gap = None if s["test"] is None or s["train"] is None else s["train"] - s["test"]
        print(f"| {name} | {fmt(s['test'], 4)} | {fmt(s['hard'], 4)} | {fmt(s['train'], 4)} ({s['train_n'] or '-'}) | "
              f"{fmt(gap)} | {s['steps'] or '-'} | {fmt(s['minutes'], 0)} | {s['limbs']} | {s['hidden'] if s['hidden'] is not None else '-'} |")
    for pair in args.pair:
        a, _, b = pair.partition("-")
        d = paired_difference(runs[a]["results"], runs[b]["results"])
        print(f"\n{a} − {b}: " + ("-" if d is None else f"{d.mean:+.3f} ± {d.sem:.3f} ({d.better} / {d.n} images)"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
