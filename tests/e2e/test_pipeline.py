"""End to end through the CLI: generate a tiny human dataset, train a few steps, evaluate, reconstruct."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
import trimesh
from PIL import Image

from cerberus_core.cli import main

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def trained(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("pipeline")
    data, run = root / "data", root / "run"
    assert main(["data", "generate", "--dataset", "human", "--size", "tiny", "--out", str(data), "--quiet"]) == 0
    assert main(["train", "--preset", "tiny", "--set", f"data.root={data}", "--out", str(run)]) == 0
    return {"root": root, "data": data, "run": run}


def test_eval_writes_scores_and_figure(trained) -> None:
    out = trained["root"] / "eval"
    assert main(["eval", str(trained["run"]), "--out", str(out)]) == 0
    result = json.loads((out / "results.json").read_text())
    assert result["protocol"] == "kato" and result["resolution"] == 32
    assert result["standard"]["count"] > 0
    assert 0.0 <= result["standard"]["mean"] <= 1.0
    assert result["hard"] is not None and 0.0 <= result["hard"]["mean"] <= 1.0
    assert "Voxel IoU" in (out / "results.md").read_text()
    assert Image.open(out / "table2.png").size[0] > 0


def test_reconstruct_exports_parts_and_pictures(trained) -> None:
    from cerberus_core.datasets.readers import ViewDataset

    ds = ViewDataset(trained["data"], "test")
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


def test_reconstruct_refuses_missing_image(trained, capsys) -> None:
    assert main(["reconstruct", str(trained["run"]), str(trained["root"] / "nope.png"),
                 "--out", str(trained["root"] / "rec2")]) == 2
    assert "no such file" in capsys.readouterr().err


def test_eval_on_a_missing_split_is_a_message_not_a_traceback(trained, capsys) -> None:
    assert main(["eval", str(trained["run"]), "--split", "nosuch", "--out", str(trained["root"] / "eval2")]) == 2
    err = capsys.readouterr().err
    assert "no split 'nosuch'" in err and "Traceback" not in err
