"""The learning curve of docs/results.md ("Learning at scale"): test IoU and IoU on the run's own
training images at every kept checkpoint of one or more runs, as a table and a plot.

    python experiments/scale/curve.py NAME=RUN [NAME=RUN ...] --test TEST_DATA --train TRAIN_DATA \\
        [--train-limit 416] [--plot docs/images/results/learning_curve.png] [--pair A-B]

A RUN trained with ``train.keep_every`` (the ``cpu_long`` preset keeps one every 5,000 steps) holds
``checkpoints/step_XXXXXXX.pt``; each is scored with ``cerberus eval CKPT --data TEST_DATA`` (the
unseen test subjects) and ``cerberus eval CKPT --data TRAIN_DATA --split train --limit K`` (K of its own
training images, whole poses spread evenly over the split: docs/evaluation.md), into
``RUN/curve/step_XXXXXXX/{test,train}``; scores already there are reused, so the script can run while a
training goes on and again when it ends. Part quality, the
Hard Human test and the 3D viewer are skipped: the curve needs the IoU only. ``--pair A-B`` prints
``A − B`` on the test images at every step both runs kept (mean ± s.e., images where A is better).
"""
from __future__ import annotations

import argparse
import subprocess
import sys
from pathlib import Path

from cerberus_core.eval.compare import load_evaluation, paired_difference


def score(ckpt: Path, data: str, out: Path, extra: list[str]) -> float:
    """Mean voxel IoU of ``ckpt`` on ``data`` (evaluated once, then read from ``out``)."""
    results = out / "results.json"
    if not results.is_file():
        cmd = ["cerberus", "eval", str(ckpt), "--data", data, "--out", str(out), "--no-part-quality", "--no-hard",
               "--viewer-images", "0", "--figure-images", "1", *extra]
        done = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        if done.returncode != 0:
            raise SystemExit(f"{' '.join(cmd)} failed:\n{done.stderr[-2000:]}")
    return load_evaluation(results)["standard"]["mean"]


def curve(run: Path, test: str, train: str, limit: int) -> list[tuple[int, float, float]]:
    """``[(step, test IoU, train IoU)]`` over the run's kept checkpoints, in step order."""
    rows = []
    for ckpt in sorted((run / "checkpoints").glob("step_*.pt")):
        step = int(ckpt.stem.split("_")[1])
        folder = run / "curve" / ckpt.stem
        rows.append((step, score(ckpt, test, folder / "test", []),
                     score(ckpt, train, folder / "train", ["--split", "train", "--limit", str(limit)])))
    return rows


def plot(curves: dict[str, list[tuple[int, float, float]]], path: Path, size: tuple[int, int] = (760, 420)) -> None:
    """Test IoU (solid, dots) and own-training-image IoU (thin, squares) against the step, with PIL."""
    from cerberus_core.viz import chart_frame

    steps = [r[0] for rows in curves.values() for r in rows] or [0, 1]
    values = [v for rows in curves.values() for r in rows for v in r[1:]] or [0.0, 1.0]
    y0, y1 = (int(min(values) * 50) - 1) / 50, (int(max(values) * 50) + 2) / 50  # a 0.02 grid around the data
    chart = chart_frame(size, margins=(60, 250, 20, 40), x_range=(0, max(steps)), y_range=(y0, y1))
    chart.grid_y([y0 + k * 0.02 for k in range(round((y1 - y0) / 0.02) + 1)], "{:.2f}".format)
    chart.grid_x(sorted(set(steps)), lambda s: f"{s // 1000}k", fill=None)
    chart.axis_titles(x="training step", y="voxel IoU (32^3)")
    colours = [(31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40)]
    legend = 0
    for (name, rows), col in zip(curves.items(), colours, strict=False):
        for index, label, width, marker in ((1, "test (unseen subjects)", 3, "o"), (2, "own training images", 1, "s")):
            xy = [(chart.x_px(r[0]), chart.y_px(r[index])) for r in rows]
            if len(xy) > 1:
                chart.draw.line(xy, fill=col, width=width)
            for x, y in xy:
                box = [x - 3, y - 3, x + 3, y + 3]
                chart.draw.ellipse(box, fill=col) if marker == "o" else chart.draw.rectangle(box, outline=col)
            ly = chart.top + 10 + 18 * legend
            chart.draw.line([chart.right + 10, ly, chart.right + 30, ly], fill=col, width=width)
            chart.draw.text((chart.right + 36, ly - 6), f"{name}: {label}", fill=(0, 0, 0))
            legend += 1
    chart.save(path)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", metavar="NAME=RUN")
    ap.add_argument("--test", required=True, help="dataset whose test split holds the unseen subjects")
    ap.add_argument("--train", required=True, help="the runs' training dataset")
    ap.add_argument("--train-limit", type=int, default=416, help="own training images scored (default 416)")
    ap.add_argument("--plot", type=Path, help="write the curves to this PNG")
    ap.add_argument("--pair", action="append", default=[], metavar="A-B", help="paired test differences A - B")
    args = ap.parse_args(argv)
    curves = {}
    for item in args.runs:
        name, _, path = item.partition("=")
        curves[name] = curve(Path(path), args.test, args.train, args.train_limit)
    print("| run | step | test IoU | own training images | gap |")
    print("| :--- | ---: | ---: | ---: | ---: |")
    for name, rows in curves.items():
        for step, test, train in rows:
            print(f"| {name} | {step:,} | {test:.4f} | {train:.4f} | {train - test:+.3f} |")
    paths = dict(item.partition("=")[::2] for item in args.runs)
    for pair in args.pair:
        a, _, b = pair.partition("-")
        for step in sorted({r[0] for r in curves[a]} & {r[0] for r in curves[b]}):
            res = [load_evaluation(Path(paths[n]) / "curve" / f"step_{step:07d}" / "test") for n in (a, b)]
            d = paired_difference(*res)
            print(f"{a} - {b} at step {step:,}: " + (f"{d.mean:+.4f} ± {d.sem:.4f} ({d.better} / {d.n} images favour {a})"
                                                    if d else "fewer than 2 test images scored by both"))
    if args.plot:
        plot(curves, args.plot)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
