"""The typed manifest (cerberus_core.datasets.manifest): read, written, round-tripped, refused when
damaged, and read when an earlier version wrote it."""
from __future__ import annotations

import json
import shutil
from dataclasses import FrozenInstanceError, replace
from pathlib import Path

import pytest

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.format import DatasetError
from cerberus_core.datasets.manifest import (
    FORMAT_VERSION,
    MANIFEST,
    FileRecord,
    Manifest,
    ShardRecord,
    SplitRecord,
)
from cerberus_core.datasets.scene import SceneSetup, read_scene
from cerberus_core.datasets.settings import GenerationConfig

OLD_MANIFEST = Path(__file__).with_name("old_manifest.json")
"""The manifest of `primitives`/`tiny` as the first release of the format wrote it (cerberus_core
0.1.0, commit 5386e9a), kept as written."""


def test_read_gives_typed_records(pairs_dataset):
    m = Manifest.read(pairs_dataset)
    raw = json.loads((pairs_dataset / MANIFEST).read_text())
    assert m.root == pairs_dataset and m.path == pairs_dataset / MANIFEST and m.complete
    assert (m.dataset, m.preset, m.image_size) == (raw["dataset"], raw["preset"], raw["image_size"])
    assert m.part_names == tuple(raw["part_names"]) and m.subject_names == [s["name"] for s in raw["subjects"]]
    assert isinstance(m.scene, SceneSetup) and m.scene == read_scene(raw["scene"])
    train = m.split("train")
    assert isinstance(train, SplitRecord) and train.complete and train.layout == "pairs"
    assert all(isinstance(s, ShardRecord) for s in train.shards)
    assert [s.index for s in train.shards] == list(range(train.planned_shards))
    assert isinstance(train.shards[0].files["images"], FileRecord)
    assert train.totals()["images"] == train.planned_images
    assert m.subjects[0].subject.name == m.subjects[0].name and "train" in m.subjects[0].splits
    assert isinstance(m.config, GenerationConfig) and m.config.to_dict() == raw["config"]
    assert isinstance(Dataset.open(pairs_dataset).views("test").manifest, Manifest)  # what the readers hold
    with pytest.raises(DatasetError, match="no split 'val'; this dataset has \\['test', 'train'\\]"):
        m.split("val")
    with pytest.raises(FrozenInstanceError):
        m.complete = False  # type: ignore[misc]


def test_to_json_is_what_the_generator_wrote_and_reads_back_equal(pairs_dataset):
    m = Manifest.read(pairs_dataset)
    assert m.to_json() == json.loads((pairs_dataset / MANIFEST).read_text())
    assert Manifest.from_json(m.to_json(), pairs_dataset) == m


def test_a_split_s_content_id_follows_its_files_not_its_folder_name_or_preset(pairs_dataset):
    """``SplitRecord.content_id`` (an evaluation's ``data_id``) is read from the manifest's file sha256s: a dataset
    named or preset otherwise, or in another folder, holds the same split while its files are the same; a file of
    other content is another split."""
    m = Manifest.read(pairs_dataset)
    test = m.split("test")
    assert len(test.content_id) == 16 and int(test.content_id, 16) >= 0 and test.content_id != m.split("train").content_id
    renamed = Manifest.from_json(m.to_json() | {"dataset": "other", "preset": "large"}, pairs_dataset.parent / "copy")
    assert renamed.split("test").content_id == test.content_id
    shard = test.shards[0]
    images = replace(shard.files["images"], sha256="0" * 64)
    changed = replace(test, shards=(replace(shard, files={**shard.files, "images": images}), *test.shards[1:]))
    assert changed.content_id != test.content_id


def test_write_is_atomic_and_round_trips(pairs_dataset, tmp_path):
    ds = tmp_path / "ds"
    shutil.copytree(pairs_dataset, ds)
    m = Manifest.read(ds)
    unfinished = m.with_shards({"train": m.split("train").shards[:1]})
    assert not unfinished.split("train").complete and unfinished.split("test").shards == ()
    unfinished.write()
    assert Manifest.read(ds) == unfinished and not list(ds.glob(".*.tmp"))
    again = unfinished
    for shard in reversed(m.split("train").shards):
        again = again.with_shard("train", shard)  # a shard already there is replaced, not repeated
    assert again.split("train") == m.split("train")  # shards kept in index order


def test_read_errors_name_the_problem(tmp_path, pairs_dataset):
    with pytest.raises(DatasetError, match="does not exist"):
        Manifest.read(tmp_path / "nope")
    with pytest.raises(DatasetError, match="not a Cerberus dataset"):
        Manifest.read(tmp_path)
    (tmp_path / MANIFEST).write_text("{not json")
    with pytest.raises(DatasetError, match="not valid JSON"):
        Manifest.read(tmp_path)
    raw = json.loads((pairs_dataset / MANIFEST).read_text())
    cases = {
        "format version 2": raw | {"format_version": FORMAT_VERSION + 1},
        "not a cerberus-dataset manifest": raw | {"format": "other"},
        "manifest lacks 'subjects'": {k: v for k, v in raw.items() if k != "subjects"},
        "manifest.image_size is '64'": raw | {"image_size": "64"},
        "splits.train lacks 'layout'": raw | {"splits": raw["splits"] | {"train": {"planned_shards": 1}}},
        "invalid scene set-up": raw | {"scene": raw["scene"] | {"elevation": "high"}},
    }
    for problem, record in cases.items():
        (tmp_path / MANIFEST).write_text(json.dumps(record))
        with pytest.raises(DatasetError, match=problem):
            Manifest.read(tmp_path)
    ds = tmp_path / "ds"
    shutil.copytree(pairs_dataset, ds)
    (ds / MANIFEST).write_text(json.dumps(cases["format version 2"]))
    with pytest.raises(DatasetError, match="format version"):  # `cerberus data check` exits 2 on it
        Dataset.open(ds)


def test_a_manifest_written_by_the_first_release_still_reads(tmp_path):
    (tmp_path / MANIFEST).write_text(OLD_MANIFEST.read_text())
    m = Manifest.read(tmp_path)
    assert (m.dataset, m.preset, m.image_size, m.complete) == ("primitives", "tiny", 64, True)
    assert m.generator == {"cerberus_core": "0.1.0"}
    assert sorted(m.splits) == ["test", "train"] and all(s.complete for s in m.splits.values())
    assert m.split("train").shards[0].files["images"].shape == (24, 3, 64, 64)
    assert isinstance(m.config, GenerationConfig) and m.config.splits["train"].layout == "pairs"
    assert m.to_json() == json.loads(OLD_MANIFEST.read_text())  # rewritten on resume without loss


def _shard(m):
    return m["splits"]["train"]["shards"][0]


MALFORMED = [  # (id, change to the stored manifest, words of the one-line DatasetError)
    ("images-huge", lambda m: _shard(m).update(images=10**18), "images is 1000000000000000000, not a count"),
    ("images-negative", lambda m: _shard(m).update(images=-5), "images is -5, not a count"),
    ("images-text", lambda m: _shard(m).update(images="8"), "images is '8', not int"),
    ("quadruplets-float", lambda m: _shard(m).update(quadruplets=2.5), "quadruplets is 2.5, not int"),
    ("image-size-huge", lambda m: m.update(image_size=10**9), "image_size is 1000000000, not a size in [1, 4096]"),
    ("image-size-zero", lambda m: m.update(image_size=0), "image_size is 0"),
    ("subject-index", lambda m: _shard(m).update(subjects=[99]), "names subject 99, but the manifest has"),
    ("subjects-text", lambda m: _shard(m).update(subjects="01"), "subjects is '01', not a list of counts"),
    ("shape-text", lambda m: _shard(m)["files"]["images"].update(shape="abc"), "shape is 'abc', not a list"),
    ("shape-nested", lambda m: _shard(m)["files"]["images"].update(shape=[[8]]), "shape[0] is [8], not a count"),
    ("dtype-number", lambda m: _shard(m)["files"]["images"].update(dtype=7), "dtype is 7, not str"),
    ("bytes-negative", lambda m: _shard(m)["files"]["images"].update(bytes=-1), "bytes is -1, not a count"),
    ("part-names-text", lambda m: m.update(part_names=[["head"]]), "part_names is [['head']], not a list of strings"),
    ("subject-splits", lambda m: m["subjects"][0].update(splits=[["train"]]), "splits is [['train']]"),
    ("canonical-text", lambda m: m["subjects"][0].update(canonical_pose="first"), "canonical_pose is 'first'"),
    ("layout", lambda m: m["splits"]["train"].update(layout="spiral"), "layout is 'spiral', not 'pairs' or 'grid'"),
    ("planned-negative", lambda m: m["splits"]["train"].update(planned_shards=-1), "planned_shards is -1"),
    ("meshes-text", lambda m: m["splits"]["train"].update(meshes="yes"), "meshes is 'yes', not bool"),
    ("preset-number", lambda m: m.update(preset=3), "preset is 3, not str"),
    ("generator-list", lambda m: m.update(generator=[1]), "generator is list, not an object"),
    ("files-list", lambda m: _shard(m).update(files=[1]), "files is list, not an object"),
    ("splits-empty", lambda m: m.update(splits={}), "splits records [], but its config plans ['test', 'train']"),
    ("split-unplanned", lambda m: m["splits"].update(extra=m["splits"]["train"]), "but its config plans"),
    ("shard-twice", lambda m: m["splits"]["train"]["shards"].append(_shard(m)),
     "splits.train.shards records shards [0, 0, 1, 2, 3], not distinct shards of the 4 planned"),
]


@pytest.mark.parametrize(("case", "change", "words"), MALFORMED, ids=[c[0] for c in MALFORMED])
def test_every_malformed_field_is_one_dataset_error_naming_it(pairs_dataset, tmp_path, capsys, case, change, words):
    """Issue 34: the reader turns a field of the wrong type, sign, size or depth into one DatasetError line
    naming the field (never a raw ValueError, TypeError or RecursionError), from the API and `cerberus data check`
    (exit 2), and nothing is changed."""
    from cerberus_core.cli import main

    root = tmp_path / "ds"
    shutil.copytree(pairs_dataset, root)
    record = json.loads((root / MANIFEST).read_text())
    change(record)
    (root / MANIFEST).write_text(json.dumps(record))
    before = (root / MANIFEST).read_bytes()
    with pytest.raises(DatasetError) as caught:
        Manifest.read(root)
    assert words in str(caught.value) and "regenerate" in str(caught.value) and "\n" not in str(caught.value)
    assert main(["data", "check", str(root)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and words in err and "Traceback" not in err
    assert (root / MANIFEST).read_bytes() == before


def test_a_manifest_nested_too_deeply_is_one_line(tmp_path):
    (tmp_path / MANIFEST).write_text("[" * 200_000 + "]" * 200_000)
    with pytest.raises(DatasetError, match="nested too deeply"):
        Manifest.read(tmp_path)


def test_a_manifest_with_a_number_too_long_to_read_is_one_line(tmp_path):
    """Python's json raises a plain ValueError (not a JSONDecodeError) for an integer of more than 4300 digits."""
    (tmp_path / MANIFEST).write_text('{"format_version": 1' + "0" * 5000 + "}")
    with pytest.raises(DatasetError, match=r"not valid JSON \(holds a number of more than 4300 digits\); the dataset is corrupt"):
        Manifest.read(tmp_path)
