"""``Run`` (cerberus_core.run): a trained run as one object, the one call ``cerberus eval`` makes
(``Run.evaluate``), and the checks it makes as the CLI does (issue 26)."""
from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest
import torch

from cerberus_core import Run
from cerberus_core.errors import CheckpointError, ConfigError
from cerberus_core.plugins import (
    METRIC_GROUP,
)
from cerberus_core.run import EvalSettings
from cerberus_core.weights import load_weights, resolve_weights

pytestmark = pytest.mark.usefixtures("one_thread")  # as tests/core/train/conftest.py does


def test_a_run_folder_loads_as_one_object(tiny_run, tiny_root):
    run = Run.load(tiny_run)
    loaded = load_weights(resolve_weights(tiny_run))
    model, config, scene = loaded.model, loaded.config, loaded.scene
    assert run.path == tiny_run / "model.safetensors" and run.step == 2 and run.weights_info.newer is None
    assert run.data_root == tiny_root and run.config.to_dict() == config.to_dict()
    for (k, a), (_, b) in zip(run.model.state_dict().items(), model.state_dict().items(), strict=True):
        assert torch.equal(a, b), k
    assert not run.model.training and run.recorded_scene == scene
    assert run.scene.to_dict() == run.scene_for(tiny_root).to_dict()  # recorded, or read from the data
    assert run.default_out() == tiny_run / "eval" and repr(run) == f"Run({run.path}, step 2)"
    last = Run.load(tiny_run / "checkpoints" / "last.pt")
    assert last.path.name == "last.pt" and last.step == 2 and last.default_out() == tiny_run / "checkpoints" / "eval"


def test_a_run_named_bare_from_its_parent_writes_into_itself(tiny_run, monkeypatch):
    # `cerberus eval myrun` (no ./, not a shipped name) must write myrun/eval, not ./eval
    monkeypatch.chdir(tiny_run.parent)
    run = Run.load(tiny_run.name)
    assert not run.shipped and run.default_out() == Path(tiny_run.name) / "eval"


def test_load_refuses_a_missing_run_and_a_bad_device(tmp_path):
    with pytest.raises(CheckpointError, match="does not exist"):
        Run.load(tmp_path / "nothing")
    with pytest.raises(ConfigError, match="device = 'tpu': expected cpu, cuda or cuda:N"):
        Run.load(tmp_path / "nothing", device="tpu")


def test_the_shipped_human_model_loads_by_name():
    run = Run.load("human")
    assert run.path.name == "human.safetensors" and run.step is not None and run.step > 0
    assert run.model.config.num_parts == run.config.model.num_parts and run.scene.fov_y > 0
    assert run.shipped and run.default_out() == Path("eval")


def test_evaluate_is_what_cerberus_eval_does(tiny_run, tiny_root, tmp_path, capsys):
    from cerberus_core.cli import main

    settings = EvalSettings(limit=3, skip=("part_quality",), figure_images=1, viewer_images=0, renderer="torch")
    evaluation = Run.load(tiny_run).evaluate(tiny_root, settings, tmp_path / "lib")
    captured = capsys.readouterr()
    printed = captured.out
    assert printed.startswith(f"evaluating {tiny_run / 'model.safetensors'} at step 2\n")
    assert printed.endswith("\n".join(evaluation.lines()) + "\n") and evaluation.out == tmp_path / "lib"
    assert evaluation.result.standard.count == 3 and evaluation.weights.step == 2
    assert "over 3 of 12 images: " in evaluation.lines()[0]  # the tiny test split: 1 subject x 3 poses x 4 views
    # review of issue 43: after the evaluation's bar, depth's renders and the pictures have bars of their own
    assert "depth: 100%" in captured.err and "figures: 100%" in captured.err
    assert main(["eval", str(tiny_run), "--data", str(tiny_root), "--out", str(tmp_path / "cli"), "--limit", "3",
                 "--no-part-quality", "--figure-images", "1", "--viewer-images", "0", "--renderer", "torch"]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == printed.splitlines()[-1].replace("/lib/", "/cli/")
    lib, cli = (json.loads((tmp_path / n / "results.json").read_text()) for n in ("lib", "cli"))
    for one in (lib, cli):  # the pass's time, and the whole command's (figures and pictures included) beside it
        assert 0 <= one.pop("seconds") <= one.pop("total_seconds")
    assert lib == cli
    assert lib["computed_with"] == {"renderer": "torch", "device": "cpu", "dtype": "torch.float32"}  # issue 34
    for name in ("results.md", "table2.png", ".cerberus-output.json"):
        assert (tmp_path / "lib" / name).is_file(), name
    # issue 39: one bound, the metric's (2..1024), checked before anything runs (1 failed 167 s later)
    for bad in (1, 2000):
        with pytest.raises(ConfigError, match=rf"^resolution = {bad}: resolution must be an integer in \[2, 1024\]"):
            EvalSettings(resolution=bad)
    capsys.readouterr()
    assert main(["eval", str(tiny_run), "--data", str(tiny_root), "--resolution", "1"]) == 2  # the CLI: its flag
    assert capsys.readouterr().err.strip().startswith("cerberus eval: --resolution 1: resolution must be an integer "
                                                      "in [2, 1024]")



def test_evaluate_in_an_input_look_shows_the_model_the_test_images_so(tiny_run, tiny_root, tmp_path, capsys):
    """``EvalSettings.input_look`` (``cerberus eval --input-look``): the model reconstructs the images in that look
    (the figure's input panel shows them too); the ground truth is the same, and results.json records the look."""
    from cerberus_core.cli import main
    from cerberus_core.datasets.dataset import Dataset
    from cerberus_core.datasets.looks import flat_look
    from cerberus_core.eval.runner import evaluate_dataset

    run = Run.load(tiny_run)
    settings = EvalSettings(limit=3, skip=("hard", "part_quality", "segments"), figure_images=1,
                            viewer_images=0, renderer="torch", input_look="flat")
    evaluation = run.evaluate(tiny_root, settings, tmp_path / "flat")
    assert "the test images in the flat input look" in capsys.readouterr().out.splitlines()[0]
    views = Dataset.open(tiny_root).views("test")
    scored = [r["index"] for r in evaluation.result.records]
    flat = evaluate_dataset(views, lambda im, cam: run.model.reconstruct(flat_look(im, views.scene.background), cam),
                            settings, indices=scored, renderer=None)
    assert [r["iou"] for r in evaluation.result.records] == [r["iou"] for r in flat.records]
    shaded = evaluate_dataset(views, run.model.reconstruct, settings, indices=scored)
    assert [r["iou"] for r in flat.records] != [r["iou"] for r in shaded.records]
    assert json.loads((tmp_path / "flat" / "results.json").read_text())["input_look"] == "flat"
    assert "(flat input look)" in (tmp_path / "flat" / "results.md").read_text().splitlines()[0]
    assert main(["eval", str(tiny_run), "--data", str(tiny_root), "--input-look", "flat", "--limit", "3", "--no-hard",
                 "--no-part-quality", "--no-segments", "--figure-images", "1", "--viewer-images", "0",
                 "--renderer", "torch", "--out", str(tmp_path / "cli")]) == 0
    assert json.loads((tmp_path / "cli" / "results.json").read_text())["standard"] == \
        json.loads((tmp_path / "flat" / "results.json").read_text())["standard"]
    run.config.data.input_look = "flat"  # a model that learned flat silhouettes is scored on them by default (issue 41)
    default = run.evaluate(tiny_root, replace(settings, input_look=None), tmp_path / "own", verbose=False)
    assert [r["iou"] for r in default.result.records] == [r["iou"] for r in flat.records]
    assert json.loads((tmp_path / "own" / "results.json").read_text())["input_look"] == "flat"
    with pytest.raises(ConfigError, match="input_look = 'grey': must be one of 'shaded', 'flat', 'random'"):
        EvalSettings(input_look="grey")
    capsys.readouterr()
    with pytest.raises(SystemExit):
        main(["eval", str(tiny_run), "--input-look", "grey"])
    assert "--input-look: invalid choice: 'grey'" in capsys.readouterr().err


def test_evaluation_without_the_metrics_package_names_it_not_a_flag(tmp_path, monkeypatch) -> None:
    """core + a backend alone: `cerberus eval` / Run.evaluate say to install cerberus-metrics (issue 26),
    not '--protocol ...: unknown plugin' for a flag nobody gave."""
    from importlib.util import find_spec

    import cerberus_core.eval.diagnostics as diagnostics
    import cerberus_core.run as run_module
    from cerberus_core.errors import MissingPackageError
    from cerberus_core.plugins import get_plugin as real_get_plugin

    monkeypatch.setattr(diagnostics, "get_metric", lambda name: real_get_plugin(METRIC_GROUP, name, path=[str(tmp_path)]))
    with pytest.raises(MissingPackageError) as err:
        run_module.EvalSettings()
    assert "pip install 'cerberus-core[eval]'" in str(err.value) and "--protocol" not in str(err.value)
    assert "needs cerberus-metrics," in str(err.value)
    # issue 34: every missing piece at once, before anything starts, and the extra that brings them
    monkeypatch.setattr(diagnostics, "find_spec", lambda name: None if name == "scipy" else find_spec(name))
    with pytest.raises(MissingPackageError, match=r"needs cerberus-metrics and scipy, .*cerberus-core\[eval\]"):
        run_module.EvalSettings()
    # the body segments need scipy too: checked up front, not after the evaluation's bar has started
    with pytest.raises(MissingPackageError, match=r"needs cerberus-metrics and scipy, "):
        run_module.EvalSettings(skip=("part_quality",))
    with pytest.raises(MissingPackageError, match=r"needs cerberus-metrics, which is not installed: .* brings it "):
        run_module.EvalSettings(skip=("part_quality", "segments"))



def test_a_limited_evaluation_spreads_and_says_which_images_of_how_many(tiny_run, tiny_root, tmp_path):
    """Review of issue 43: ``--limit N`` scored the split's first N images (the test split is ordered subject, pose,
    view: a few poses of one subject) and results.json recorded neither the data, the split, the limit nor which
    images. A limit now spreads over the split (whole poses while depth runs), results.json records it under
    ``data``, and results.md's title and the console say "N of M images". The console also says how many
    predictions the metric rejected or clamped, which only results.md said."""
    from cerberus_core.datasets.dataset import Dataset
    from cerberus_core.eval.compare import comparison_rows

    run = Run.load(tiny_run)
    settings = EvalSettings(limit=3, skip=("hard", "part_quality", "visibility", "segments", "allocation"),
                            figure_images=1, viewer_images=0, renderer="torch", progress=False)
    whole = run.evaluate(tiny_root, settings, tmp_path / "whole", verbose=False)
    spread = run.evaluate(tiny_root, replace(settings, skip=(*settings.skip, "depth")), tmp_path / "spread",
                          verbose=False)
    manifest = Dataset.open(tiny_root).manifest
    root, data_id = str(manifest.root), manifest.split("test").content_id
    assert len(data_id) == 16 and data_id != manifest.split("train").content_id
    for evaluation, indices, selection in ((whole, [0, 2, 3], "whole poses, spread evenly"),
                                           (spread, [0, 6, 11], "spread evenly")):  # 1 subject x 3 poses x 4 views
        record = json.loads((evaluation.out / "results.json").read_text())
        assert [r["index"] for r in record["records"]] == indices
        assert record["data_id"] == data_id and list(record).index("data_id") == list(record).index("data") - 1
        assert record["data"] == {"root": root, "dataset": "primitives", "preset": "tiny", "split": "test",
                                  "split_images": 12, "limit": 3, "selection": selection, "images": 3}
        md = (evaluation.out / "results.md").read_text().splitlines()
        assert md[0] == f"# Evaluation of {tiny_run} at step 2, 3 of 12 images"
        assert f"; 3 of 12 images of the test split of primitives/tiny, data_id {data_id} (" in md[2]
        assert " s to score, " in md[2]
        assert evaluation.lines()[0].startswith("voxel IoU (kato, 32^3) over 3 of 12 images: ")
    # the same data, other images of it: they pair (by index, on the images both scored)
    assert comparison_rows({"whole": json.loads((whole.out / "results.json").read_text()),
                            "spread": json.loads((spread.out / "results.json").read_text())})[1][1][1] == 3
    assert whole.result["depth"]["poses"] == 1 and spread.result["depth"] is None
    assert not any("rejected" in line for line in whole.lines())
    standard = replace(whole.result.standard, clipped=2, failed=1)
    flagged = replace(whole, result=replace(whole.result, standard=standard))
    assert flagged.lines()[1] == "voxel IoU: 1 rejected (scored 0), 2 clamped to the grid"
    # the depth line says what its figures are over: here 3 views of one pose, every image scored
    assert any(line.startswith("depth: over 1 test pose seen from several views (all 3 images scored), ")
               for line in whole.lines())
    assert "Over 1 test pose seen from several views (all 3 images scored), " in \
        (whole.out / "results.md").read_text()
    # and with one image (`limit=1`), why it measured nothing, where the line was missing
    lone = {"poses": 0, "images": 0, "images_evaluated": 1, "note": "no pose has two of its views among the 1 image "
            "scored (depth compares the views of each pose): score more images (a larger limit), or ..."}
    alone = replace(whole, result=replace(whole.result, diagnostics=whole.result.diagnostics | {"depth": lone}))
    assert "depth: not measured: no pose has two of its views among the 1 image scored (depth compares the views of " \
           "each pose): score more images (a larger limit), or ..." in alone.lines()


@pytest.mark.parametrize("limit", [0, -1, 2.5, True])
def test_evaluate_refuses_a_limit_the_cli_refuses(limit):
    from cerberus_core.run import EvalSettings

    with pytest.raises(ValueError, match=r"limit = .*: must be an integer >= 1 \(EvalSettings\(limit=...\)\)"):
        EvalSettings(limit=limit)


def test_domain_notes_name_another_kind_of_body_and_another_camera(human_run, pairs_dataset):
    notes = human_run.domain_notes(pairs_dataset)
    assert any("trained on human bodies" in n and "primitives bodies" in n for n in notes)
    assert any("differs from the model's training scenes" in n for n in notes)


@pytest.mark.parametrize(("images", "options", "words"), [
    ([], {}, "images: no image given; pass at least one image file"),
    (["x.png"], {"azimuth": float("nan")}, "azimuth = nan: must be a finite number"),
    (["x.png"], {"azimuth": float("inf")}, "azimuth = inf: must be a finite number"),
    (["x.png"], {"azimuth": "north"}, "azimuth = 'north': must be a finite number"),
    (["x.png"], {"viewer_images": -1}, "viewer_images = -1: must be an integer >= 0"),
], ids=["no-images", "azimuth-nan", "azimuth-inf", "azimuth-text", "viewer-negative"])
def test_reconstruct_images_checks_what_the_cli_checks(tiny_run, tmp_path, images, options, words):
    """Issue 34: the API refuses, with the CLI's own check (the command passes its flags straight to it), before
    anything is read or written."""
    run = Run.load(tiny_run)
    with pytest.raises(ConfigError, match=words.replace("(", r"\(").replace(")", r"\)")):
        run.reconstruct_images([tmp_path / p for p in images], tmp_path / "out", **options)
    assert list(tmp_path.iterdir()) == []


def test_model_reconstruct_refuses_nan_images(tiny_run):
    """Issue 34: NaN passes a ``max() <= 1`` range check; the input contract refuses it by name."""
    from cerberus_core.errors import ShapeError
    from cerberus_core.render.camera import Camera

    run = Run.load(tiny_run)
    images = torch.full((2, 3, 32, 32), 0.5)
    images[1, 0, 3, 4] = float("nan")
    camera = Camera.look_at(torch.zeros(2), torch.zeros(2), 2.0, image_size=32)
    with pytest.raises(ShapeError, match="reconstruct: 1 of 6144 image values are NaN or infinite"):
        run.model.reconstruct(images, camera)


def test_the_viewer_names_parts_by_their_labels_and_shows_each_scored_image_s_iou(tiny_run, tiny_root, tmp_path):
    """Issue 34: the viewer said ``part_05`` where the model card knows the head, and no image's IoU. ``cerberus
    eval`` labels the parts it scored (part quality) and shows the IoU it computed for each card (its pictures are
    of the images it scored, within ``limit``); ``cerberus reconstruct`` with a shipped model takes its card's labels; a run
    folder's reconstruction keeps ``part_NN``."""
    from PIL import Image

    from tests.support.viewer import page_data

    run = Run.load(tiny_run)
    settings = EvalSettings(limit=3, figure_images=2, viewer_images=2, renderer="torch")
    evaluation = run.evaluate(tiny_root, settings, tmp_path / "ev", verbose=False)
    data = page_data(tmp_path / "ev" / "pictures" / "index.html")
    labels = evaluation.result.part_labels()
    assert labels and len(labels) == run.model.config.num_parts
    assert data["part_labels"] == {f"part_{k:02d}": label for k, label in enumerate(labels) if label}
    scored = evaluation.result.image_ious()
    assert sorted(scored) == [0, 2, 3]  # 3 views of the first pose, spread (depth runs: whole poses, and 4 do not fit)
    figure = [int(e["name"].split("_")[1]) for e in data["entries"]]  # spread over the images it scored
    assert figure == [0, 3]
    assert [e["iou"] for e in data["entries"]] == [scored[0], scored[3]]

    human = Run.load("human")
    assert human.part_labels() == ["torso", "lower_arm.L", "pelvis", "shin.R", "shin.L", "head", "torso",
                                   "thigh.L", "pelvis"]  # the card's part table
    assert run.part_labels() is None
    picture = tmp_path / "in.png"
    Image.new("RGB", (64, 64)).save(picture)
    human.reconstruct_images([picture], tmp_path / "rec", viewer_images=1)
    assert page_data(tmp_path / "rec" / "index.html")["part_labels"]["part_05"] == "head"
    run.reconstruct_images([picture], tmp_path / "rec_run", viewer_images=1)
    assert page_data(tmp_path / "rec_run" / "index.html")["part_labels"] == {}


@pytest.mark.parametrize(("call", "words"), [
    (lambda run, tmp: Run.load(None), "path: got NoneType None"),
    (lambda run, tmp: run.reconstruct_images(str(tmp / "a.png"), tmp / "out"), "images: got str"),
    (lambda run, tmp: run.reconstruct_images([1], tmp / "out"), r"images\[0\]: got int 1"),
    (lambda run, tmp: run.reconstruct_images([tmp / "a.png"], None), "out: got NoneType None"),
    (lambda run, tmp: run.reconstruct_images([tmp / "a.png"], tmp / "out", masks=str(tmp / "m.png")), "masks: got str"),
    (lambda run, tmp: run.evaluate(tmp, {"limit": 1}, tmp / "out"), "settings: got dict"),
    (lambda run, tmp: run.evaluate(tmp, out=tmp / "out", baselines={"b": 5}), r"baselines\['b'\]: got int 5"),
    (lambda run, tmp: run.evaluate(out=7), "out: got int 7"),
], ids=["load-none", "images-str", "images-int", "out-none", "masks-str", "settings-dict", "baseline-int", "out-int"])
def test_the_api_names_a_parameter_of_the_wrong_kind(tiny_run, tmp_path, call, words):
    """Issue 34 campaign: these ended in a TypeError or AttributeError naming no parameter, or (a str of images)
    read one character at a time ("/: is a folder")."""
    from cerberus_core.errors import InputTypeError

    run = Run.load(tiny_run)
    with pytest.raises(InputTypeError, match=words):
        call(run, tmp_path)
    assert list(tmp_path.iterdir()) == []
