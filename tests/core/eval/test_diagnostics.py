"""The table of diagnostics (cerberus_core.eval.diagnostics): a new diagnostic is one module and one row; a toy
one, added as a row, shows up in results.json, results.md, the printed summary and as a ``--no-X`` flag."""
from __future__ import annotations

import json
import re

import pytest

from cerberus_core.cli.eval import skip_flag
from cerberus_core.errors import ConfigError
from cerberus_core.eval.diagnostics import DIAGNOSTICS, Diagnostic, diagnostic_names, running
from cerberus_core.eval.runner import EvalConfig


class ImageCount:
    """The toy diagnostic's one accumulator class: counts the images and marks each record."""

    @classmethod
    def for_evaluation(cls, context) -> ImageCount:  # noqa: ARG003 - needs nothing of the evaluation
        return cls()

    def __init__(self) -> None:
        self.images = 0

    def update(self, batch) -> None:
        self.images += len(batch.records)
        for rec in batch.records:
            rec["toy_seen"] = True

    def summary(self) -> dict:
        return {"images": self.images}


@pytest.fixture
def toy():
    row = Diagnostic("toy_count", ImageCount, "the toy count of images",
                     line=lambda s: f"toy count: {s['images']} images",
                     section=lambda r: ["## Toy count", "", f"{r['toy_count']['images']} images counted.", ""])
    DIAGNOSTICS.append(row)
    yield row
    DIAGNOSTICS.remove(row)


def test_the_table_names_every_switch_once():
    names = diagnostic_names()
    assert names == ["hard", "part_quality", "visibility", "depth", "segments", "allocation"]  # results.json's order
    assert len({d.key for d in DIAGNOSTICS}) == len(DIAGNOSTICS)
    assert [skip_flag(d.name) for d in DIAGNOSTICS][:3] == ["--no-hard", "--no-part-quality", "--no-visibility"]
    assert [d.name for d in running(())][:3] == ["visibility", "hard", "part_quality"]  # visible_pixels leads a record
    with pytest.raises(ConfigError, match=r"skip = 'segment': is not a diagnostic \(did you mean 'segments'\?\)"):
        EvalConfig(skip=("segment",))
    with pytest.raises(ConfigError, match="not one string"):
        EvalConfig(skip="hard")
    with pytest.raises(ConfigError, match="needs"):
        Diagnostic("x", ImageCount, "x", frozenset({"gpu"}))


def test_a_toy_diagnostic_is_one_row(toy, tiny_run, tiny_root, tmp_path, capsys):
    from cerberus_core.cli import main

    args = ["eval", str(tiny_run), "--data", str(tiny_root), "--limit", "2", "--no-part-quality", "--no-hard",
            "--figure-images", "1", "--viewer-images", "0", "--renderer", "torch"]
    assert main([*args, "--out", str(tmp_path / "on")]) == 0
    printed = capsys.readouterr().out
    assert "toy count: 2 images" in printed.splitlines()
    result = json.loads((tmp_path / "on" / "results.json").read_text())
    assert result["toy_count"] == {"images": 2} and all(r["toy_seen"] for r in result["records"])
    keys = list(result)
    assert keys.index("toy_count") == keys.index("allocation") + 1 == keys.index("seconds") - 1  # after the others
    assert "## Toy count\n\n2 images counted." in (tmp_path / "on" / "results.md").read_text()

    assert main([*args, "--out", str(tmp_path / "off"), "--no-toy-count"]) == 0
    assert "toy count" not in capsys.readouterr().out
    result = json.loads((tmp_path / "off" / "results.json").read_text())
    assert result["toy_count"] is None and "toy_seen" not in result["records"][0]
    with pytest.raises(SystemExit):
        main(["eval", "--help"])
    assert re.search(r"--no-toy-count\s+skip the toy count of images", capsys.readouterr().out)
