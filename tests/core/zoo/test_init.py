"""The pretrained-model registry: names, checksums, clear errors (no weights needed)."""
import json

import pytest
import torch
import yaml

from cerberus_core import zoo
from cerberus_core.errors import ZooError
from cerberus_core.model import Cerberus, ModelConfig
from cerberus_core.run import Run
from cerberus_core.train.checkpoint import export_weights
from cerberus_core.train.settings import TrainConfig


def _fake_zoo(tmp_path, monkeypatch, tamper=False):
    """A zoo folder holding one small exported model."""
    monkeypatch.setattr(zoo, "ZOO_DIR", tmp_path)
    config = TrainConfig()
    config.model = ModelConfig(width=8, shape_latent_dim=16, depth_offset=2.5)
    torch.manual_seed(0)
    model = Cerberus(config.model)
    scene = {"elevation": 20.0, "fov_y": 30.0, "distance": 2.5}
    export_weights(model, tmp_path / "tiny.safetensors", yaml.safe_dump(config.to_dict()), 7, scene=scene)
    digest = zoo.sha256_file(tmp_path / "tiny.safetensors")
    if tamper:
        digest = "0" * 64
    entry = {"name": "tiny", "summary": "a test model", "weights": "tiny.safetensors", "sha256": digest,
             "card": "tiny.md", "results": {"test_iou": 0.5}}
    (tmp_path / "tiny.json").write_text(json.dumps(entry))
    (tmp_path / "tiny.md").write_text("# tiny\n")
    return model


def test_a_model_file_of_an_earlier_version_loads_with_its_renamed_keys(tmp_path):
    """A model file whose config says ``model.predict_rotation: false`` (written before it became ``model.rotation``)
    loads as ``rotation: none``, with the same weights."""
    config = TrainConfig()
    config.model = ModelConfig(width=8, shape_latent_dim=16, depth_offset=2.5, num_parts=1, rotation="none")
    torch.manual_seed(0)
    model = Cerberus(config.model)
    saved = config.to_dict()
    saved["model"]["predict_rotation"] = saved["model"].pop("rotation") != "none"  # False
    export_weights(model, tmp_path / "old.safetensors", yaml.safe_dump(saved), 7)
    run = Run.load(tmp_path / "old.safetensors")
    assert run.config.model.rotation == "none" and run.config.model.num_parts == 1
    for (k, a), (_, b) in zip(run.model.state_dict().items(), model.state_dict().items(), strict=True):
        assert torch.equal(a, b), k


def test_a_shipped_name_loads_verified_weights_and_its_scene(tmp_path, monkeypatch):
    ref = _fake_zoo(tmp_path, monkeypatch)
    assert list(zoo.available()) == ["tiny"]
    run = Run.load("tiny")
    model, config, scene = run.model, run.config, run.recorded_scene
    for (k, a), (_, b) in zip(model.state_dict().items(), ref.state_dict().items(), strict=True):
        assert torch.equal(a, b), k
    assert (scene["elevation"], scene["fov_y"], scene["distance"]) == (20.0, 30.0, 2.5)
    assert config.model.width == 8 and run.shipped


def test_unknown_names_and_damaged_files_are_refused_with_the_fix(tmp_path, monkeypatch):
    _fake_zoo(tmp_path, monkeypatch, tamper=True)
    with pytest.raises(ZooError, match="fails its checksum.*reinstall"):
        Run.load("tiny")
    with pytest.raises(ZooError, match="no pretrained model named 'dog'.*shipped: tiny"):
        Run.load("dog")


def test_every_shipped_entry_matches_its_file():
    """The real registry: every entry's weights exist, verify, and name a model card; its part labels (issue 34:
    the viewer names parts by them) are one per learned part."""
    for name, entry in zoo.available().items():
        assert zoo.model_path(name).is_file()
        assert entry.card_path.is_file(), f"{name}: model card {entry.card_path} missing"
        assert len(entry.part_labels) == Run.load(name).model.config.num_parts, name


def test_part_labels_of_the_wrong_type_are_one_clear_error(tmp_path, monkeypatch):
    _fake_zoo(tmp_path, monkeypatch)
    assert zoo.available()["tiny"].part_labels == []  # an entry without them: the viewer says part_NN
    data = json.loads((tmp_path / "tiny.json").read_text())
    for bad in ("head", [1, 2], {"0": "head"}):
        (tmp_path / "tiny.json").write_text(json.dumps(data | {"part_labels": bad}))
        with pytest.raises(ZooError, match="'part_labels' must be a JSON list of strings"):
            zoo.available()


@pytest.mark.parametrize(("entry", "expected"), [
    ('{"name": "tiny", ', "not readable JSON"),
    ('["tiny"]', "expected a JSON object"),
    ('{"name": "tiny"}', "missing"),
    (None, "it must name a .safetensors file beside the entry"),  # weights: a path out of the zoo
])
def test_a_damaged_registry_entry_is_one_clear_error(tmp_path, monkeypatch, capsys, entry, expected):
    """Issue 20: a malformed entry was a JSONDecodeError / TypeError traceback, and its weights path went
    unchecked (``ZOO_DIR / "../../x.safetensors"``)."""
    from cerberus_core.cli import main

    _fake_zoo(tmp_path, monkeypatch)
    if entry is None:
        data = json.loads((tmp_path / "tiny.json").read_text())
        entry = json.dumps(data | {"weights": "../../elsewhere/tiny.safetensors"})
    (tmp_path / "tiny.json").write_text(entry)
    with pytest.raises(ZooError, match=expected):
        zoo.available()
    assert main(["models"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and expected in err and "Traceback" not in err


def test_registry_text_reaches_the_terminal_escaped(tmp_path, monkeypatch, capsys):
    from cerberus_core.cli import main

    _fake_zoo(tmp_path, monkeypatch)
    data = json.loads((tmp_path / "tiny.json").read_text())
    (tmp_path / "tiny.json").write_text(json.dumps(data | {"summary": "\x1b[2J\x1b]0;owned\x07 cleared",
                                                           "results": {"iou\x1b[31m": 1}}))
    assert main(["models"]) == 0
    out = capsys.readouterr().out
    assert "\x1b" not in out and "\x07" not in out and "\\x1b[2J" in out


def test_long_model_names_and_summaries_wrap_in_their_column(tmp_path, monkeypatch, capsys):
    """Issue 34: ``cerberus models`` padded names to 8 characters, so a longer name (``human-nmrr``) pushed its
    summary out of line with the others, and a long summary ran past the terminal's edge."""
    from cerberus_core.cli import main

    _fake_zoo(tmp_path, monkeypatch)
    data = json.loads((tmp_path / "tiny.json").read_text())
    name = "my_very_long_model_name"
    summary = " ".join(f"word{k}" for k in range(60))
    (tmp_path / "long.json").write_text(json.dumps(data | {"name": name, "summary": summary, "card": "tiny.md"}))
    monkeypatch.setenv("COLUMNS", "70")
    assert main(["models"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert all(len(line) <= 70 for line in lines), lines
    column = lines[0].index("word0")  # "long" sorts first; every line of both rows starts its text here
    assert lines[0].startswith(name) and all(line[:column].strip() in ("", name, "tiny") for line in lines)
    row = [line[column:] for line in lines[:next(i for i, line in enumerate(lines) if line.startswith("tiny"))]]
    assert " ".join(row).split()[:60] == summary.split()  # every word, in order, within the column
