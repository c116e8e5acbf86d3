"""End to end through the CLI: generate a tiny human dataset, train a few steps, evaluate, reconstruct."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from cerberus_core.cli import main
from cerberus_core.datasets.dataset import Dataset

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("pipeline")
    data, run = root / "data", root / "run"
    assert main(["data", "generate", "--dataset", "human", "--size", "tiny", "--out", str(data), "--quiet"]) == 0
    assert main(["train", "--preset", "tiny", "--set", f"data.root={data}", "--out", str(run)]) == 0
    return {"root": root, "data": data, "run": run}


@pytest.fixture(scope="module")
def evaluated(trained) -> Path:
    out = trained["root"] / "eval"
    assert main(["eval", str(trained["run"]), "--out", str(out)]) == 0
    return out


def test_eval_writes_scores_and_figure(evaluated) -> None:
    out = evaluated
    result = json.loads((out / "results.json").read_text())
    assert result["protocol"] == "kato" and result["resolution"] == 32
    assert result["standard"]["count"] > 0
    assert 0.0 <= result["standard"]["mean"] <= 1.0
    assert result["hard"] is not None and 0.0 <= result["hard"]["mean"] <= 1.0
    assert "Voxel IoU" in (out / "results.md").read_text()
    assert Image.open(out / "table2.png").size[0] > 0
    for stem in {p.name.split("_")[0] + "_" + p.name.split("_")[1] for p in (out / "pictures").glob("test_*.png")}:
        for glb in (f"{stem}.glb", f"{stem}_gt.glb", f"{stem}_new_pose.glb"):  # what the 3D viewer shows
            assert (out / "pictures" / glb).is_file(), glb
    assert (out / "pictures" / "index.html").is_file()


def test_eval_viewer_shows_reconstruction_and_ground_truth(evaluated, chromium) -> None:
    import html
    import re

    pictures = evaluated / "pictures"
    dom, console = chromium.dump_dom((pictures / "index.html").as_uri())
    assert console == [], f"console messages: {console}"
    status = json.loads(html.unescape(re.search(r'<pre id="viewer-status"[^>]*>(.*?)</pre>', dom, re.S).group(1)))
    assert status["ready"] and status["errors"] == [] and status["cards"], status
    for card in status["cards"]:
        for key, suffix in (("reconstruction", ""), ("ground_truth", "_gt"), ("new_pose", "_new_pose")):
            scene = trimesh.load(pictures / f"{card['name']}{suffix}.glb", force="scene")
            assert card["meshCounts"][key] == len(scene.geometry), (card, key)


def test_reconstruct_exports_parts_and_pictures(trained) -> None:

    ds = Dataset.open(trained["data"]).views("test")
    paths = []
    for i in (0, 1):
        img = np.asarray(ds[i]["images"], dtype=np.float32) * 255  # the reader's contract: float in [0, 1]
        path = trained["root"] / f"input{i}.png"
        Image.fromarray(img.transpose(1, 2, 0).round().astype(np.uint8)).save(path)
        paths.append(str(path))
    out = trained["root"] / "rec"
    with pytest.warns(UserWarning, match="resized from 64x64 to 32x32"):  # the tiny run works at 32 px
        assert main(["reconstruct", str(trained["run"]), *paths, "--out", str(out)]) == 0
    scene = trimesh.load(out / "input0.glb")
    assert isinstance(scene, trimesh.Scene) and len(scene.geometry) >= 1
    for what in ("input", "reconstruction", "parts", "turntable", "new_lighting", "new_pose", "figure1"):
        assert (out / f"input0_{what}.png").is_file(), what
    assert (out / "input0_new_pose.glb").is_file() and (out / "index.html").is_file()  # the 3D viewer


def test_reconstruct_refuses_missing_image(trained, capsys) -> None:
    assert main(["reconstruct", str(trained["run"]), str(trained["root"] / "nope.png"),
                 "--out", str(trained["root"] / "rec2")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_eval_on_a_missing_split_is_a_message_not_a_traceback(trained, capsys) -> None:
    assert main(["eval", str(trained["run"]), "--split", "nosuch", "--out", str(trained["root"] / "eval2")]) == 2
    err = capsys.readouterr().err
    assert "no split 'nosuch'" in err and "Traceback" not in err
