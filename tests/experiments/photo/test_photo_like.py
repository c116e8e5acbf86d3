"""experiments/photo/photo_like.py end to end on two test images of a tiny human set: the photos are rendered, cut
out by the exact mask, reconstructed by the shipped silhouette model, fitted, and scored; the script's numbers are
the README's, so it must keep running against the library."""
from __future__ import annotations

import json
import subprocess
import sys

import torch

from cerberus_core.cli import main
from tests.support.paths import REPO

SCRIPT = REPO / "experiments" / "photo" / "photo_like.py"


def test_photo_like_scores_the_network_and_the_fit(tmp_path):
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        generated = main(["data", "generate", "--dataset", "human", "--size", "tiny", "--set", "splits.train.pairs=1",
                          "--out", str(tmp_path / "data"), "--quiet"])
    finally:
        torch.set_num_threads(threads)
    assert generated == 0
    out = tmp_path / "out"
    done = subprocess.run([sys.executable, str(SCRIPT), "human-silhouette", str(tmp_path / "data"), str(out),
                           "--images", "2", "--size", "64", "--masks", "exact", "--fit", "3"],
                          capture_output=True, text=True, timeout=600, cwd=tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    results = json.loads((out / "results.json").read_text())
    assert results["images"] == 2
    for name in ("exact", "exact_fit"):
        assert 0.0 < results[name]["voxel_iou"] <= 1.0 and 0.0 < results[name]["silhouette_iou"] <= 1.0
        assert len(results[name]["per_image"]) == 2
    assert results["exact_fit"]["fit_steps"] == 3 and results["exact_fit"]["paired_vs_unfitted"]["images"] == 2
    assert "exact_fit mask: voxel IoU" in done.stdout
    assert (out / "sheet.png").is_file() and len(list((out / "photos").glob("*_exact.png"))) == 2
