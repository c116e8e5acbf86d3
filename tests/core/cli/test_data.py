"""``cerberus data generate / check / show`` end to end."""
from __future__ import annotations

import re

import numpy as np
import pytest
from PIL import Image

from cerberus_core.cli import main
from cerberus_core.datasets.dataset import Dataset


def test_generate_check_show_primitives(tmp_path, capsys):
    out = tmp_path / "ds"
    args = ["data", "generate", "--dataset", "primitives", "--size", "tiny", "--out", str(out), "--image-size", "32",
            "--quiet"]
    assert main(args) == 0
    assert "train" in capsys.readouterr().out
    assert main(["data", "check", str(out)]) == 0
    assert "ok" in capsys.readouterr().out
    png = tmp_path / "sheet.png"
    assert main(["data", "show", str(out), "--out", str(png), "--parts", "--count", "3"]) == 0
    img = np.asarray(Image.open(png))
    assert img.shape[0] > 3 * 32 and img.shape[1] > 6 * 32 and img.std() > 0
    assert main(["data", "show", str(out), "--split", "test", "--out", str(tmp_path / "t.png")]) == 0

    # rerunning resumes (nothing to do); other options refuse; a damaged file fails the check
    assert main(args) == 0
    assert main(args[:-1] + ["--seed", "4", "--quiet"]) == 2
    assert "different dataset" in capsys.readouterr().err
    victim = next((out / "train").glob("*.images.npy"))
    victim.write_bytes(victim.read_bytes()[:-1] + b"\x01")
    assert main(["data", "check", str(out)]) == 1
    err = capsys.readouterr().err
    assert str(victim) in err and "sha256" in err


def test_cli_input_errors(tmp_path, capsys):
    assert main(["data", "generate", "--dataset", "folder", "--out", str(tmp_path / "x")]) == 2
    assert "--source" in capsys.readouterr().err
    assert main(["data", "generate", "--dataset", "folder", "--source", str(tmp_path / "none"),
                 "--out", str(tmp_path / "x")]) == 2
    assert "does not exist" in capsys.readouterr().err
    assert main(["data", "check", str(tmp_path)]) == 2  # not a dataset: bad input (1 is for a damaged dataset)
    assert main(["data", "generate", "--dataset", "human", "--size", "paper", "--out", str(tmp_path / "p"),
                 "--dry-run"]) == 0
    text = capsys.readouterr().out
    assert "78000 images" in text and "19500 quadruplets" in text and "3248 images" in text
    assert not (tmp_path / "p").exists()


def test_generate_takes_set_overrides_with_the_training_configs_validation(tmp_path, capsys):
    import yaml

    base = ["data", "generate", "--dataset", "primitives", "--size", "tiny", "--out", str(tmp_path / "x")]
    assert main([*base, "--set", "splits.train.pairs=3", "--set", "scene.elevation=20", "--image-size", "48",
                 "--set", "image_size=40", "--print-config"]) == 0
    cfg = yaml.safe_load(capsys.readouterr().out)
    assert cfg["splits"]["train"]["pairs"] == 3 and cfg["scene"]["elevation"] == 20.0 and cfg["image_size"] == 40
    assert cfg["preset"] == "tiny" and cfg["dataset"] == "primitives"
    for flags, message in ((["--set", "splits.train.pair=3"], "did you mean 'splits.train.pairs'"),
                           (["--set", "splits.train.layout=pair"], "splits.train.layout: must be one of 'pairs'"),
                           (["--set", "scene.fov_y=200"], r"scene.fov_y = 200.0: must be a number in \(0, 180\)"),
                           (["--set", "seed"], "section.key=value"),
                           (["--size", "tiniest"], "--size tiniest: unknown size preset for dataset 'primitives'.*tiny")):
        assert main([*base, *flags, "--dry-run"]) == 2
        assert re.search(message, capsys.readouterr().err)
    assert not (tmp_path / "x").exists()
    # --preset still names the size, with a deprecation note
    assert main([*base[:4], "--preset", "tiny", *base[6:], "--dry-run"]) == 0
    captured = capsys.readouterr()
    assert "--preset is deprecated" in captured.err and "primitives/tiny" in captured.out


@pytest.mark.slow
@pytest.mark.parametrize("dataset", ["human", "animal"])
def test_generate_tiny_real_sources(tmp_path, dataset):
    """The anny humans and the procedural animals through the whole pipeline (tens of seconds)."""

    out = tmp_path / dataset
    assert main(["data", "generate", "--dataset", dataset, "--size", "tiny", "--out", str(out), "--quiet"]) == 0
    assert main(["data", "check", str(out)]) == 0
    quads, views = Dataset.open(out).quadruplets(), Dataset.open(out).views()
    item = quads[0]
    assert item["images"].shape == (4, 3, 64, 64)
    body = views.gt_mesh(0)
    assert len(body.part_names) == len(views.part_names) > 5 and np.abs(body.vertices).max() <= 0.5
    if dataset == "human":
        assert len(views.canonical_indices()) == 1
    assert main(["data", "show", str(out), "--out", str(tmp_path / "s.png"), "--parts"]) == 0


def test_a_second_writer_of_a_dataset_folder_is_refused_with_the_holders_pid(tmp_path, capsys):
    import os

    from cerberus_core.plumbing.lock import folder_lock

    out = tmp_path / "ds"
    with folder_lock(out, "another cerberus data generate"):
        rc = main(["data", "generate", "--dataset", "primitives", "--size", "tiny", "--out", str(out), "--quiet"])
        assert rc == 2
        err = capsys.readouterr().err
        assert f"pid {os.getpid()}" in err and len(err.strip().splitlines()) == 1
        assert [p.name for p in out.iterdir()] == [".cerberus.lock"], "nothing written beside the lock"
    assert main(["data", "generate", "--dataset", "primitives", "--size", "tiny", "--out", str(out), "--quiet"]) == 0
    assert (out / "manifest.json").is_file() and not (out / ".cerberus.lock").exists()


def test_the_resume_command_of_a_folder_dataset_rebuilds_its_config(tmp_path, capsys):
    """cli.datasets.generate_command names the mesh folder and its test split: rerunning it resumes (here:
    nothing left to do) instead of refusing a different dataset."""
    import shlex

    import trimesh

    from cerberus_core.bodies.primitives import PrimitiveBodySource, sample_subjects
    from cerberus_core.cli.datasets import generate_command
    from cerberus_core.datasets.dataset import Dataset

    meshes = tmp_path / "meshes"
    source = PrimitiveBodySource()
    for name, subject in zip(("ann", "ben", "cat"), sample_subjects(3, 1, "train"), strict=True):
        (meshes / name).mkdir(parents=True)
        for k, body in enumerate(source.posed_bodies(subject, [1, 2])):
            trimesh.Trimesh(body.vertices, body.faces, process=False).export(meshes / name / f"p{k}.obj")
            np.save(meshes / name / f"p{k}.parts.npy", body.vertex_parts.astype(np.int64))
    out = tmp_path / "ds"
    assert main(["data", "generate", "--dataset", "folder", "--source", str(meshes), "--test-subjects", "cat",
                 "--image-size", "24", "--out", str(out), "--quiet"]) == 0
    command = generate_command(Dataset.open(out))
    words = shlex.split(command)
    assert words[words.index("--source") + 1] == str(meshes.resolve()) and "--test-subjects" in words
    capsys.readouterr()
    assert main([*words[1:], "--quiet"]) == 0, capsys.readouterr().err
    assert re.search(r"resuming .*: (\d+) of \1 shards already done", capsys.readouterr().out)


def test_an_empty_size_is_refused_not_taken_for_the_default(tmp_path, capsys):
    """Issue 34 campaign: `--size "$SIZE"` with SIZE unset silently generated the default size (4,000 images of
    primitives/small)."""
    out = tmp_path / "d"
    assert main(["data", "generate", "--dataset", "primitives", "--size", "", "--out", str(out), "--dry-run"]) == 2
    err = capsys.readouterr().err
    assert "--size '': unknown size preset for dataset 'primitives'; choose one of paper, small, tiny" in err
    assert not out.exists()
