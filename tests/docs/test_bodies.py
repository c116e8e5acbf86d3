"""docs/bodies.md's worked minimal body source, as written: registered through a real entry point like a
third-party package, a dataset generated from its preset with `cerberus data generate`, checked, and one
training step run on it."""
from __future__ import annotations

import re
from pathlib import Path

from cerberus_core.cli import main
from tests.support.paths import REPO


def _guide_block(first_line: str, language: str) -> str:
    text = (REPO / "docs" / "bodies.md").read_text()
    block = re.search(rf"```{language}\n({re.escape(first_line)}\n.*?)```", text, re.S)
    assert block, f"docs/bodies.md lost its {first_line}"
    return block.group(1)


def test_the_guides_minimal_source_generates_a_dataset_that_trains(tmp_path: Path, fake_dist, monkeypatch, capsys):
    site = fake_dist("block-bodies", {"cerberus.bodies": {"blocks": "block_bodies:BlockSource"}})
    package = site / "block_bodies"
    (package / "presets").mkdir(parents=True)
    (package / "__init__.py").write_text(_guide_block("# block_bodies/__init__.py", "python"))
    (package / "presets" / "blocks_tiny.yaml").write_text(_guide_block("# block_bodies/presets/blocks_tiny.yaml", "yaml"))
    monkeypatch.syspath_prepend(str(site))

    data, run = tmp_path / "data", tmp_path / "run"
    assert main(["data", "generate", "--dataset", "block", "--out", str(data), "--dry-run"]) == 2
    assert "did you mean 'blocks'?" in capsys.readouterr().err
    assert main(["data", "generate", "--dataset", "blocks", "--option", "arm_length=2", "--out", str(data)]) == 2
    assert "arm_length = 2.0: must be a number in (0, 1]" in capsys.readouterr().err
    assert main(["data", "generate", "--dataset", "blocks", "--size", "tiny", "--option", "arm_length=0.5",
                 "--renderer", "torch", "--out", str(data), "--quiet"]) == 0
    assert main(["data", "check", str(data)]) == 0, capsys.readouterr().err
    assert "blocks/tiny" in capsys.readouterr().out

    from cerberus_core.datasets.dataset import Dataset

    dataset = Dataset.open(data)
    assert dataset.manifest.source.options == {"arm_length": 0.5} and dataset.manifest.part_names == ("torso", "arm")
    quads, views = dataset.quadruplets(), dataset.views()
    assert len(quads) == 8 and len(views) == 8
    assert set(views.gt_mesh(0).vertex_parts.tolist()) == {0, 1}
    assert float((quads[0]["images"] < 0.99).float().mean()) > 0.02  # the bodies are drawn
    assert main(["train", "--preset", "tiny", "--set", f"data.root={data}", "--set", "train.steps=1",
                 "--set", "renderer=torch", "--out", str(run)]) == 0, capsys.readouterr().err
    assert (run / "model.safetensors").is_file()
