"""The parts-that-move screen of docs/results.md ("Parts that move", issue 38): one row per evaluated run, the
allocation columns beside the IoU, each run paired with the first on the same test images.

    python experiments/parts/table.py NAME=RUN [NAME=RUN ...] [--plot PNG]

Each RUN holds ``eval/results.json`` (``cerberus eval RUN``). Columns: voxel IoU; the paired difference to the
first run (mean ± s.e., images better); Hard Human; spare parts (deleting one costs <= 0.003 IoU); voxel
recall of the lower arms and the shins; the four largest keypoint spreads (px, per part the std over images of
keypoint minus silhouette centroid); the median distance from the forearms' and the shins' projected
centroids to the nearest keypoint (px); the mean translation disagreement between two views of a pose (world
units); the labels among head, thigh, shin and lower arm that a part takes with agreement >= 0.5, left and right
merged; training minutes (summed over the sittings of a resumed run). ``--plot PNG`` also draws each run's test
IoU against its Hard Human IoU (the trade between fitting each image and parts that hold across poses).
"""
from __future__ import annotations

import sys
from pathlib import Path

from cerberus_core.eval.compare import load_evaluation, paired_difference
from cerberus_core.train.logs import training_time

LIMBS = ("head", "thigh", "shin", "lower_arm")


def row(name: str, run: Path, base: dict | None) -> str:
    res = load_evaluation(run)
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
    trained = training_time(run / "metrics.csv")
    minutes = f"{trained.seconds / 60:.0f}" if trained else "-"
    spare = seg.get("spare_count")
    spare = f"{spare} of {len(seg.get('deletion_loss') or []) or '?'}" if spare is not None else "-"
    versus = paired_difference(res, base) or "–"

    return (f"| {name} | {res['standard']['mean']:.4f} | {versus} | "
            f"{(res.get('hard') or {}).get('mean', float('nan')):.4f} | {spare} | "
            f"{', '.join(f'{recall[n]:.2f}' for n in ('lower_arm.L', 'lower_arm.R') if n in recall)} / "
            f"{', '.join(f'{recall[n]:.2f}' for n in ('shin.L', 'shin.R') if n in recall)} | "
            f"{' '.join(f'{s:.1f}' for s in spread) or '-'} | "
            f"{', '.join(f'{to_kp[n]:.1f}' for n in ('lower_arm.L', 'lower_arm.R') if n in to_kp)} / "
            f"{', '.join(f'{to_kp[n]:.1f}' for n in ('shin.L', 'shin.R') if n in to_kp)} | "
            f"{depth.get('mean_translation_disagreement', float('nan')):.3f} | {', '.join(named) or '-'} | {minutes} |")


def plot_trade(points: dict[str, tuple[float, float]], path: Path, size: tuple[int, int] = (620, 460)) -> None:
    """Scatter of ``{name: (test IoU, Hard Human IoU)}``, Hard Human up, test IoU across, with PIL."""
    from cerberus_core.viz import chart_frame

    xs, ys = [p[0] for p in points.values()], [p[1] for p in points.values()]
    x0, x1 = (int(min(xs) * 100) - 1) / 100, (int(max(xs) * 100) + 2) / 100  # a 0.01 grid around the data
    y0, y1 = (int(min(ys) * 50) - 1) / 50, (int(max(ys) * 50) + 2) / 50  # a 0.02 grid
    chart = chart_frame(size, margins=(56, 20, 20, 44), x_range=(x0, x1), y_range=(y0, y1))
    chart.grid_x([x0 + k * 0.01 for k in range(round((x1 - x0) / 0.01) + 1)], "{:.2f}".format)
    chart.grid_y([y0 + k * 0.02 for k in range(round((y1 - y0) / 0.02) + 1)], "{:.2f}".format)
    chart.axis_titles(x="test voxel IoU (208 images)", y="Hard Human IoU (one set of parts per subject)")
    for name, (x, y) in points.items():
        px, py = chart.x_px(x), chart.y_px(y)
        chart.draw.ellipse([px - 4, py - 4, px + 4, py + 4], fill=(31, 119, 180))
        chart.draw.text((px + 7, py - 6), name, fill=(0, 0, 0))
    chart.save(path)


def main(argv: list[str]) -> int:
    plot = None
    if "--plot" in argv:
        at = argv.index("--plot")
        plot, argv = (Path(argv[at + 1]) if at + 1 < len(argv) else None), argv[:at] + argv[at + 2:]
        if plot is None:
            print("--plot needs a PNG path", file=sys.stderr)
            return 2
    if not argv or any("=" not in a for a in argv):
        print(__doc__, file=sys.stderr)
        return 2
    runs = [(a.split("=", 1)[0], Path(a.split("=", 1)[1])) for a in argv]
    base = load_evaluation(runs[0][1])
    print("| row | IoU | vs first | Hard | spare | lower arm / shin recall | keypoint spread, top 4 (px) | "
          "forearm / shin → keypoint (px) | translation disagreement | merged labels ≥ 0.5 | minutes |")
    print("| --- | ---: | ---: | ---: | ---: | --- | --- | --- | ---: | --- | ---: |")
    for name, run in runs:
        if load_evaluation(run, missing_ok=True) is None:
            print(f"| {name} | - | not evaluated ({run / 'eval' / 'results.json'}) |")
            continue
        print(row(name, run, None if run == runs[0][1] else base))
    if plot is not None:
        results = {name: r for name, run in runs if (r := load_evaluation(run, missing_ok=True)) is not None}
        plot_trade({name: (r["standard"]["mean"], r["hard"]["mean"]) for name, r in results.items()
                    if (r.get("hard") or {}).get("mean") is not None}, plot)
        print(f"wrote {plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
