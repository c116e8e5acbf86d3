"""experiments/parts/table.py on two evaluated runs: the rows pair the second with the first on the images both
scored, and ``--plot`` draws each run where its test and Hard Human IoUs put it."""
from __future__ import annotations

import json
import subprocess
import sys

from PIL import Image

from tests.support.paths import REPO

SCRIPT = REPO / "experiments" / "parts" / "table.py"


def _run(folder, ious, hard):
    (folder / "eval").mkdir(parents=True)
    records = [{"index": i, "iou": v} for i, v in enumerate(ious)]
    (folder / "eval" / "results.json").write_text(json.dumps({"standard": {"mean": sum(ious) / len(ious)},
                                                              "hard": {"mean": hard}, "records": records}))


def test_table_pairs_the_runs_and_plots_the_trade(tmp_path):
    _run(tmp_path / "a", [0.40, 0.50, 0.60], 0.45)
    _run(tmp_path / "b", [0.42, 0.53, 0.59], 0.35)
    png = tmp_path / "trade.png"
    done = subprocess.run([sys.executable, str(SCRIPT), f"a={tmp_path / 'a'}", f"b={tmp_path / 'b'}", "--plot",
                           str(png)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    rows = [line for line in done.stdout.splitlines() if line.startswith("| b |")]
    assert rows and "| 0.5133 | +0.013 ± 0.012 (2 / 3) | 0.3500 |" in rows[0]
    image = Image.open(png).convert("RGB")
    blue = [(x, y) for x in range(image.width) for y in range(image.height) if image.getpixel((x, y)) == (31, 119, 180)]
    assert blue, "no point drawn"
    ys = sorted({y for _, y in blue})
    assert ys[-1] - ys[0] > 100  # Hard Human 0.45 against 0.35: the two points lie far apart vertically
    missing = subprocess.run([sys.executable, str(SCRIPT), f"a={tmp_path / 'a'}", "--plot"], capture_output=True,
                             text=True, timeout=120)
    assert missing.returncode == 2 and "--plot needs a PNG path" in missing.stderr
