"""Every command with bad input: one line on stderr naming the problem, exit 2, nothing written or changed.

The table drives ``cerberus_core.cli.main`` in-process against one tiny dataset and one 2-step run;
each case snapshots the whole working folder (names, sizes, modification times) before and after.
"""
from __future__ import annotations

import re
import shlex
import struct
import zlib
from pathlib import Path

import pytest
import torch

from cerberus_core.cli import main
from cerberus_core.datasets.generate import generate
from cerberus_core.datasets.plan import preset_config


def fake_png(path: Path, width: int, height: int) -> Path:
    """A PNG whose header claims ``width x height`` (no pixel data: only the header is ever read)."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
                     + chunk(b"IEND", b""))
    return path


@pytest.fixture(scope="module")
def place(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("cli_errors")
    data, run = root / "data", root / "run"
    generate(preset_config("primitives", "tiny", image_size=32), data, progress=False, log=lambda _: None)
    torch_threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        assert main(["train", "--preset", "tiny", "--set", f"data.root={data}", "--set", "train.steps=2",
                     "--set", "train.tensorboard=false", "--set", "train.progress=false", "--out", str(run)]) == 0
    finally:
        torch.set_num_threads(torch_threads)
    (root / "notes").mkdir()
    (root / "notes" / "todo.txt").write_text("my notes\n")
    (root / "afile").write_text("a file\n")
    (root / "empty.yaml").write_text("# nothing here\n")
    (root / "bad.yaml").write_text("train:\n  steps: [1\n")
    last = (run / "checkpoints" / "last.pt").read_bytes()
    (root / "trunc.pt").write_bytes(last[: len(last) // 3])
    (root / "random.pt").write_bytes(bytes(range(256)) * 8)
    torch.save({"x": torch.nn.Linear(1, 1)}, root / "pickled.pt")  # a pickled module, not plain tensors
    (root / "trunc.safetensors").write_bytes((run / "model.safetensors").read_bytes()[:100])
    from PIL import Image
    Image.new("RGB", (40, 40), (200, 10, 10)).save(root / "img.png")
    fake_png(root / "huge.png", 20000, 20000)
    fake_png(root / "big.png", 9000, 5000)
    return {"root": root, "data": data, "run": run}


NO_CUDA = pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA is available here")
GEN = "data generate --dataset primitives --size tiny --quiet"

# (id, argv with {placeholders}, text the one-line error must contain)
CASES = [
    ("train-set-yaml", "train --preset tiny --set train.steps=[1 --out {root}/new", "not valid YAML"),
    ("train-set-key", "train --preset tiny --set =3 --out {root}/new", "section.key=value"),
    ("train-set-type", "train --preset tiny --set optim.lr=fast --out {root}/new", "optim.lr: expected a number"),
    ("train-set-unknown", "train --preset tiny --set optim.lrr=1 --out {root}/new", "unknown config key"),
    ("train-set-nan", "train --preset tiny --set data.root={data} --set losses.smoothness=.nan --out {root}/new",
     "losses.smoothness = nan: must be a finite number"),
    ("train-set-inf", "train --preset tiny --set data.root={data} --set optim.lr=.inf --out {root}/new", "finite"),
    ("train-config-empty", "train --config {root}/empty.yaml --out {root}/new", "is empty"),
    ("train-config-yaml", "train --config {root}/bad.yaml --out {root}/new", "bad.yaml:3: not valid YAML"),
    ("train-config-missing", "train --config {root}/nope.yaml --out {root}/new", "no such file"),
    pytest.param("train-cuda", "train --preset tiny --set data.root={data} --set device=cuda --out {root}/new",
                 "CUDA is not available", marks=NO_CUDA),
    ("train-out-dataset", "train --preset tiny --set data.root={data} --out {data}", "is a dataset folder"),
    ("train-out-notes", "train --preset tiny --set data.root={data} --out {root}/notes", "not empty"),
    ("train-out-file", "train --preset tiny --set data.root={data} --out {root}/afile", "is a file"),
    ("train-out-run", "train --preset tiny --set data.root={data} --out {run}", "--resume"),
    ("train-resume-none", "train --preset tiny --set data.root={data} --out {root}/new --resume", "no checkpoint"),
    ("train-data-missing", "train --preset tiny --set data.root={root}/nodata --out {root}/new", "does not exist"),
    ("train-steps-0", "train --preset tiny --set data.root={data} --set train.steps=0 --out {root}/new",
     "must be positive"),
    pytest.param("eval-cuda", "eval {run} --device cuda", "CUDA is not available", marks=NO_CUDA),
    ("eval-truncated", "eval {root}/trunc.pt", "not a readable Cerberus checkpoint"),
    ("eval-random", "eval {root}/random.pt", "not a readable Cerberus checkpoint"),
    ("eval-pickled", "eval {root}/pickled.pt", "pickled Python object"),
    ("eval-truncated-safetensors", "eval {root}/trunc.safetensors", "not a readable safetensors file"),
    ("eval-missing", "eval {root}/nothing", "does not exist"),
    ("eval-dataset", "eval {data}", "is a dataset folder, not a training run"),
    ("eval-notes", "eval {root}/notes", "not a training run folder"),
    ("eval-resolution-0", "eval {run} --resolution 0", "--resolution: must be >= 1"),
    ("eval-resolution-huge", "eval {run} --resolution 100000", "at most"),
    ("eval-protocol", "eval {run} --protocol foo", "--protocol 'foo': unknown"),
    ("eval-limit-negative", "eval {run} --limit -3", "--limit: must be >= 1"),
    ("eval-limit-0", "eval {run} --limit 0", "--limit: must be >= 1"),
    ("eval-figure-images-0", "eval {run} --figure-images 0", "--figure-images: must be >= 1"),
    ("eval-baseline-missing", "eval {run} --baseline X={root}/missing", "--baseline X="),
    ("eval-baseline-form", "eval {run} --baseline justaname", "NAME=RUN"),
    ("eval-out-file", "eval {run} --out {root}/afile", "is a file"),
    ("eval-out-dataset", "eval {run} --out {data}", "is a dataset folder"),
    ("eval-data-notes", "eval {run} --data {root}/notes", "not a Cerberus dataset"),
    ("eval-split", "eval {run} --split nosuch", "no split 'nosuch'"),
    ("eval-renderer", "eval {run} --renderer nope", "unknown renderer 'nope'"),
    pytest.param("reconstruct-cuda", "reconstruct {run} {root}/img.png --device cuda --out {root}/rec",
                 "CUDA is not available", marks=NO_CUDA),
    ("reconstruct-azimuth-nan", "reconstruct {run} {root}/img.png --azimuth nan --out {root}/rec", "finite"),
    ("reconstruct-truncated", "reconstruct {root}/trunc.pt {root}/img.png --out {root}/rec", "not a readable"),
    ("reconstruct-pickled", "reconstruct {root}/pickled.pt {root}/img.png --out {root}/rec", "pickled"),
    ("reconstruct-missing-image", "reconstruct {run} {root}/nope.png --out {root}/rec", "no such file"),
    ("reconstruct-not-image", "reconstruct {run} {root}/bad.yaml --out {root}/rec", "cannot be read as an image"),
    ("reconstruct-huge", "reconstruct {run} {root}/huge.png --out {root}/rec", "downscale it first"),
    ("reconstruct-big", "reconstruct {run} {root}/big.png --out {root}/rec", "9000x5000 pixels is too large"),
    ("reconstruct-out-file", "reconstruct {run} {root}/img.png --out {root}/afile", "is a file"),
    ("reconstruct-out-dataset", "reconstruct {run} {root}/img.png --out {data}", "is a dataset folder"),
    ("reconstruct-data-notes", "reconstruct {run} {root}/img.png --data {root}/notes --out {root}/rec",
     "not a Cerberus dataset"),
    ("demo-size-0", "demo --image-size 0 --out {root}/demo", "--image-size: must be >= 1"),
    ("demo-size-huge", "demo --image-size 100000 --out {root}/demo", "at most"),
    ("demo-out-file", "demo --out {root}/afile", "is a file"),
    ("demo-out-dataset", "demo --out {data}", "is a dataset folder"),
    ("demo-renderer", "demo --renderer nope --out {root}/demo", "unknown renderer 'nope'"),
    # data generate: the whole generation is validated before --dry-run returns and before the folder's
    # lock or manifest is written (cerberus_core.datasets.generate.validate_generation)
    *[(f"data-generate-{name}{'-dry-run' if dry else ''}", f"{GEN} {argv}{' --dry-run' if dry else ''}", expected)
      for name, argv, expected in [
          ("image-size-huge", "--image-size 100000 --out {root}/new", "image_size must lie in 8..1024"),
          ("image-size-negative", "--image-size -5 --out {root}/new", "image_size must lie in 8..1024"),
          ("memory", "--size paper --image-size 1024 --shard-images 100000 --batch-size 100000 --out {root}/new",
           "GiB of memory"),
          ("renderer", "--renderer foo --out {root}/new", "unknown renderer 'foo'"),
          ("set-renderer", "--set renderer=foo --out {root}/new", "unknown renderer 'foo'"),
          ("size", "--size nope --out {root}/new", "unknown preset 'nope' for dataset 'primitives'"),
          ("set-yaml", "--set seed=[1 --out {root}/new", "not valid YAML"),
          ("set-key", "--set splits.train.pair=3 --out {root}/new", "did you mean 'splits.train.pairs'"),
          ("set-nan", "--set scene.elevation=.nan --out {root}/new", "scene.elevation = nan: must be a finite"),
          ("pairs-negative", "--set splits.train.pairs=-1 --out {root}/new", "pairs must be >= 0"),
          ("split-empty", "--set splits.train.pairs=0 --out {root}/new", "split 'train' would be empty"),
          ("split-huge", "--set splits.train.pairs=100000000 --out {root}/new", "400,000,000 images, more than"),
          ("subjects-huge", "--set splits.train.subjects=1000000 --out {root}/new", "subjects 1000000: at most"),
          ("views-huge", "--set splits.test.views=100000 --out {root}/new", "views 100000: at most 360"),
          ("quadruplets-negative", "--set splits.test.quadruplets_per_pose=-1 --out {root}/new", "must be >= 0"),
          ("scene-near", "--set scene.near=-1 --out {root}/new", "near must be > 0"),
          ("scene-far", "--set scene.far=1 --out {root}/new", "far 1.0 must exceed the distance"),
          ("scene-background", "--set scene.background=[2,0,0] --out {root}/new", "RGB values must lie in [0, 1]"),
          ("seed-negative", "--seed -1 --out {root}/new", "seed must be >= 0"),
          ("shard-images-0", "--shard-images 0 --out {root}/new", "shard_images must be >= 4"),
          ("batch-size-0", "--batch-size 0 --out {root}/new", "--batch-size: must be >= 1"),
          ("test-fraction-not-folder", "--test-fraction 0.5 --out {root}/new", "--dataset folder only"),
          ("out-file", "--out {root}/afile", "is a file"),
          ("out-under-file", "--out {root}/afile/sub", "is under"),
          ("out-notes", "--out {root}/notes", "is not empty and holds no Cerberus dataset"),
          ("out-other-dataset", "--seed 5 --out {data}", "holds a different dataset"),
      ] for dry in (False, True)],
    pytest.param("data-generate-cuda", GEN + " --device cuda --out {root}/new", "CUDA is not available",
                 marks=NO_CUDA),
    ("data-generate-folder-no-source", "data generate --dataset folder --out {root}/new", "--source DIR is required"),
    ("data-generate-folder-missing", "data generate --dataset folder --source {root}/nothing --out {root}/new",
     "does not exist"),
    ("data-generate-folder-fraction", "data generate --dataset folder --source {root}/notes --test-fraction 2 "
     "--out {root}/new", "test_fraction must lie in [0, 1]"),
    ("data-check-missing", "data check {root}/nothing", "does not exist"),
    ("data-check-file", "data check {root}/afile", "is a file, not a dataset folder"),
    ("data-check-notes", "data check {root}/notes", "is not a Cerberus dataset"),
    ("data-show-missing", "data show {root}/nothing --out {root}/sheet.png", "does not exist"),
    ("data-show-notes", "data show {root}/notes --out {root}/sheet.png", "is not a Cerberus dataset"),
    ("data-show-split", "data show {data} --split nosuch --out {root}/sheet.png", "no split 'nosuch'"),
    ("data-show-count-0", "data show {data} --count 0 --out {root}/sheet.png", "--count: must be >= 1"),
    ("data-show-scale-huge", "data show {data} --scale 1000 --out {root}/sheet.png", "--scale 1000: at most"),
    ("data-show-out-folder", "data show {data} --out {root}/notes", "is a folder"),
    ("data-show-out-under-file", "data show {data} --out {root}/afile/sheet.png", "which is a file"),
    ("data-show-renderer", "data show {data} --renderer nope --out {root}/sheet.png", "unknown renderer 'nope'"),
    ("data-show-renderer-parts", "data show {data} --parts --renderer nope --out {root}/sheet.png",
     "unknown renderer 'nope'"),
]


def snapshot(root: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(root)): (p.stat().st_size, p.stat().st_mtime_ns) for p in sorted(root.rglob("*"))}


@pytest.mark.parametrize(("case", "argv", "expected"), CASES,
                         ids=[c.values[0] if hasattr(c, "marks") else c[0] for c in CASES])
def test_bad_input_is_one_line_exit_2_and_writes_nothing(place, capsys, case, argv, expected):
    args = [a.format(**{k: str(v) for k, v in place.items()}) for a in argv.split()]
    before = snapshot(place["root"])
    try:
        code = main(args)
    except SystemExit as exc:  # argparse usage errors
        code = exc.code
    out, err = capsys.readouterr()
    assert code == 2, (case, out, err)
    assert err.endswith("\n") and err.count("\n") == 1, f"not one line: {err!r}"
    assert re.match(rf"cerberus {args[0]}( [a-z]+)?: ", err), err  # argparse names the sub-command's action
    assert expected in err, err
    assert "Traceback" not in err and "weights_only" not in err
    assert out == ""
    assert snapshot(place["root"]) == before, "the failed command wrote or changed files"


def test_same_named_inputs_get_distinct_outputs(place, tmp_path, capsys):
    from PIL import Image

    for folder, colour in (("a", (200, 10, 10)), ("b", (10, 10, 200))):
        (tmp_path / folder).mkdir()
        Image.new("RGB", (32, 32), colour).save(tmp_path / folder / "x.png")
    out = tmp_path / "rec"
    assert main(["reconstruct", str(place["run"]), str(tmp_path / "a" / "x.png"), str(tmp_path / "b" / "x.png"),
                 "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    files = [p for p in out.rglob("*") if p.is_file()]
    assert f"wrote {len(files)} files for 2 image(s)" in printed and "a_x" in printed and "b_x" in printed
    assert (out / "a_x.glb").is_file() and (out / "b_x.glb").is_file()
    # per image: 13 pictures and meshes plus its new-pose GLB for the viewer; and the one viewer page
    assert (out / "index.html").is_file()
    assert len(files) - 1 == 2 * len([p for p in files if str(p.relative_to(out)).startswith("a_x")]) == 28


def test_a_run_is_usable_from_another_directory(place, tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # the run's data.root is stored absolute; its scene set-up is in the run
    assert main(["eval", str(place["run"]), "--limit", "1", "--no-hard", "--no-part-quality", "--figure-images", "1",
                 "--out", "ev"]) == 0
    assert (tmp_path / "ev" / "results.json").is_file()
    capsys.readouterr()


def test_an_unfinished_dataset_names_the_command_that_finishes_it(tmp_path, monkeypatch, capsys):
    """A reader's refusal (train, eval) gives the exact `cerberus data generate` command, and it resumes."""
    import cerberus_core.datasets.generate as gen
    from cerberus_core.datasets.readers import QuadrupletDataset

    data = tmp_path / "partial"
    original = gen.generate

    def interrupted_after_one_shard(*args, **kwargs):
        def stop(split, rec):
            raise KeyboardInterrupt
        return original(*args, **kwargs, on_shard=stop)

    monkeypatch.setattr(gen, "generate", interrupted_after_one_shard)
    assert main(["data", "generate", "--dataset", "primitives", "--size", "tiny", "--image-size", "24",
                 "--shard-images", "8", "--set", "splits.train.pairs=4", "--set", "scene.albedo=[0.5, 0.6, 0.7]",
                 "--out", str(data), "--quiet"]) == 130
    monkeypatch.undo()
    capsys.readouterr()
    before = snapshot(tmp_path)
    code = main(["train", "--preset", "tiny", "--set", f"data.root={data}", "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "allow_partial" not in err, err
    assert "split 'train' is incomplete (1 of 2 shards)" in err
    assert snapshot(tmp_path) == before
    words = shlex.split(re.search(r"`(cerberus data generate [^`]*)`", err).group(1))
    assert "splits.train.pairs=4" in words and "scene.albedo=[0.5, 0.6, 0.7]" in words and "--image-size" in words
    assert main([*words[1:], "--quiet"]) == 0
    assert re.search(r"resuming .*: 1 of 4 shards already done", capsys.readouterr().out)
    assert len(QuadrupletDataset(data)) == 4
    assert main(["data", "check", str(data)]) == 0


def test_the_scene_of_a_model_is_never_a_silent_default(place, tmp_path):
    """Issue 11 (6): reconstruct fell back to a default scene when the run's data was not there."""
    from dataclasses import replace

    from cerberus_core.errors import ConfigError
    from cerberus_core.train.checkpoint import load_run, model_scene

    _, config, saved = load_run(place["run"])
    assert saved is not None, "a run records its scene with its weights"
    trained_on = model_scene(config, None, None)  # the training data is still there
    assert model_scene(config, None, saved) == trained_on == model_scene(config, place["data"], None)
    gone = replace(config, data=replace(config.data, root=str(tmp_path / "moved")))
    with pytest.raises(ConfigError, match="pass --data DATASET"):
        model_scene(gone, None, None)
    with pytest.raises(ConfigError, match="not a Cerberus dataset"):
        model_scene(config, place["root"] / "notes", saved)


def test_training_verifies_the_shard_checksums_when_it_starts(place, tmp_path, capsys):
    """Issue 11: training checked shard sizes but never their checksums. A flipped byte (same size) is
    refused before the run folder exists."""
    import shutil

    data = tmp_path / "data"
    shutil.copytree(place["data"], data)
    victim = next((data / "train").glob("*.images.npy"))
    raw = bytearray(victim.read_bytes())
    raw[-1] ^= 0xFF
    victim.write_bytes(bytes(raw))
    code = main(["train", "--preset", "tiny", "--set", f"data.root={data}", "--set", "train.steps=1",
                 "--out", str(tmp_path / "run")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "sha256 mismatch" in err and str(victim) in err, err
    assert not (tmp_path / "run").exists()


def test_a_run_resumes_from_another_directory(place, tmp_path, monkeypatch, capsys):
    """Issue 11 (6): a run stored a relative data.root, so `train --resume` failed from another directory."""
    run = tmp_path / "run"
    common = ["--set", "train.tensorboard=false", "--set", "train.progress=false"]
    torch_threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        monkeypatch.chdir(place["root"])
        assert main(["train", "--preset", "tiny", "--set", "data.root=data", "--set", "train.steps=1", *common,
                     "--out", str(run)]) == 0
        (tmp_path / "elsewhere").mkdir()
        monkeypatch.chdir(tmp_path / "elsewhere")
        assert main(["train", "--out", "../run", "--resume", "--set", "train.steps=2", *common]) == 0
    finally:
        torch.set_num_threads(torch_threads)
    assert "finished step 2" in capsys.readouterr().out
