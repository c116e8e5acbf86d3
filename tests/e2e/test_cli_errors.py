"""Every command with bad input: one line on stderr naming the problem, exit 2, nothing written or changed.

The table drives ``cerberus_core.cli.main`` in-process against one tiny dataset and one 2-step run;
each case snapshots the whole working folder (names, sizes, modification times) before and after.
"""
from __future__ import annotations

import json
import os
import re
import shlex
import shutil
import struct
import zlib
from pathlib import Path

import pytest
import torch

from cerberus_core.cli import main
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.plan import preset_config
from cerberus_core.plumbing.outputs import MARKER

# The reconstruct inputs here are synthetic coloured squares, out of the training domain by design: the
# out-of-domain warning is expected in every test that reconstructs them (its own tests, which assert it, are
# in tests/core/reconstruct/test_input_domain.py).
pytestmark = pytest.mark.filterwarnings("ignore:.*out of the training domain:UserWarning")


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
    Dataset.generate(preset_config("primitives", "tiny", image_size=32), data, progress=False, log=lambda _: None)
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
    (root / "meshes" / "ann").mkdir(parents=True)  # a folder source: one subject, one pose (a tetrahedron)
    (root / "meshes" / "ann" / "rest.obj").write_text(TETRA)
    (root / "empty.yaml").write_text("# nothing here\n")
    (root / "bad.yaml").write_text("train:\n  steps: [1\n")
    last = (run / "checkpoints" / "last.pt").read_bytes()
    (root / "trunc.pt").write_bytes(last[: len(last) // 3])
    (root / "random.pt").write_bytes(bytes(range(256)) * 8)
    torch.save({"x": torch.nn.Linear(1, 1)}, root / "pickled.pt")  # a pickled module, not plain tensors
    (root / "trunc.safetensors").write_bytes((run / "model.safetensors").read_bytes()[:100])
    _bad_model_files(root, run)
    shutil.copytree(data, root / "badscene")  # a dataset whose manifest records an unusable scene
    manifest = json.loads((root / "badscene" / "manifest.json").read_text())
    (root / "badscene" / "manifest.json").write_text(json.dumps(manifest | {"scene": manifest["scene"] | {
        "elevation": "high"}}))
    os.mkfifo(root / "pipe.png")  # a FIFO: opening it for reading would block until a writer comes
    os.mkfifo(root / "pipe.safetensors")
    os.mkfifo(root / "pipe.yaml")
    from PIL import Image
    Image.new("RGB", (40, 40), (200, 10, 10)).save(root / "img.png")
    fake_png(root / "huge.png", 20000, 20000)
    fake_png(root / "big.png", 9000, 5000)
    (root / "loop.png").symlink_to("loop.png")  # a symlink loop (issue 34)
    (root / "loopdir").symlink_to("loopdir")
    (root / "deep.yaml").write_text("train:\n" + "".join("  " * i + f"k{i}:\n" for i in range(1, 40)))
    (root / "listkey.yaml").write_text("? [1, 2]\n: 3\n")
    (root / "dup.yaml").write_text("extends: tiny\ntrain:\n  steps: 3\n  steps: 5\n")
    return {"root": root, "data": data, "run": run}


#: A tetrahedron in OBJ form, the smallest closed mesh.
TETRA = "v 0 0 0\nv 0.3 0 0\nv 0 0.3 0\nv 0 0 0.3\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def _bad_model_files(root: Path, run: Path) -> None:
    """Model files that load as safetensors but must be refused: NaN weights, a damaged scene record."""
    from safetensors import safe_open
    from safetensors.torch import load_file, save_file

    with safe_open(str(run / "model.safetensors"), framework="pt") as f:
        meta = f.metadata()
    state = load_file(str(run / "model.safetensors"))
    save_file({k: torch.full_like(v, float("nan")) if v.is_floating_point() else v for k, v in state.items()},
              str(root / "nan.safetensors"), metadata=meta)
    save_file(state, str(root / "scene_json.safetensors"), metadata=meta | {"scene": "{not json"})
    save_file(state, str(root / "scene_value.safetensors"), metadata=meta | {"scene": '{"elevation": "high"}'})


NO_CUDA = pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA is available here")
GEN = "data generate --dataset primitives --size tiny --quiet"

# (id, argv with {placeholders}, text the one-line error must contain)
CASES = [
    ("train-set-yaml", "train --preset tiny --set train.steps=[1 --out {root}/new", "not valid YAML"),
    ("train-set-key", "train --preset tiny --set =3 --out {root}/new", "section.key=value"),
    ("train-set-type", "train --preset tiny --set optim.lr=fast --out {root}/new", "optim.lr: expected a number"),
    ("train-set-unknown", "train --preset tiny --set optim.lrr=1 --out {root}/new", "unknown config key"),
    ("train-set-renamed", "train --preset tiny --set model.predict_rotation=false --out {root}/new",
     "model.predict_rotation became model.rotation (true → camera, false → none); remove model.predict_rotation "
     "and write --set model.rotation=VALUE in its place"),
    ("train-set-nan", "train --preset tiny --set data.root={data} --set losses.smoothness=.nan --out {root}/new",
     "losses.smoothness = nan: must be a finite number"),
    ("train-set-inf", "train --preset tiny --set data.root={data} --set optim.lr=.inf --out {root}/new", "finite"),
    ("train-config-empty", "train --config {root}/empty.yaml --out {root}/new", "is empty"),
    ("train-config-yaml", "train --config {root}/bad.yaml --out {root}/new", "bad.yaml:3: not valid YAML"),
    ("train-config-missing", "train --config {root}/nope.yaml --out {root}/new", "no such file"),
    pytest.param("train-cuda", "train --preset tiny --set data.root={data} --set device=cuda --out {root}/new",
                 "CUDA is not available", marks=NO_CUDA),
    ("train-out-dataset", "train --preset tiny --set data.root={data} --out {data}", "holds a dataset (cerberus data generate)"),
    ("train-out-notes", "train --preset tiny --set data.root={data} --out {root}/notes", "not empty"),
    ("train-out-file", "train --preset tiny --set data.root={data} --out {root}/afile", "is a file"),
    ("train-out-run", "train --preset tiny --set data.root={data} --out {run}", "--resume"),
    ("train-resume-none", "train --preset tiny --set data.root={data} --out {root}/new --resume", "no checkpoint"),
    ("train-data-missing", "train --preset tiny --set data.root={root}/nodata --out {root}/new", "does not exist"),
    ("train-steps-0", "train --preset tiny --set data.root={data} --set train.steps=0 --out {root}/new",
     "train.steps = 0: must be an integer >= 1"),
    # issue 34: numbers bounded before anything is allocated, rules between settings, one strict YAML reader
    ("train-image-size-huge", "train --preset tiny --set data.root={data} --set data.image_size=100000 --out {root}/new",
     "data.image_size = 100000: must be an integer in [32, 4096] (--set data.image_size=VALUE)"),
    ("train-num-parts-huge", "train --preset tiny --set data.root={data} --set model.num_parts=100000 --out {root}/new",
     "model.num_parts = 100000: must be an integer in [1, 64]"),
    ("train-num-workers-huge", "train --preset tiny --set data.root={data} --set data.num_workers=100000 "
     "--out {root}/new", "data.num_workers = 100000: must be an integer in [0, 256]"),
    ("train-memory", "train --preset tiny --set data.root={data} --set data.image_size=4096 --set model.width=1024 "
     "--out {root}/new", "data.image_size = 4096: needs at least"),
    ("train-warmup", "train --preset tiny --set data.root={data} --set losses.cross_view=own "
     "--set losses.cross_view_warmup=10 --out {root}/new", "losses.cross_view_warmup = 10: must be less than train.steps (4)"),
    ("train-resume-shorter", "train --out {run} --resume --set train.steps=1", "already reached step 2"),
    ("train-set-duplicate", 'train --preset tiny --set train={{"steps":1,"steps":2}} --out {root}/new',
     "the key 'steps' is given twice"),
    ("train-set-list-key", "train --preset tiny --set data={{[1]:2}} --out {root}/new", "a list is used as a key"),
    ("train-set-deep", "train --preset tiny --set train.steps=" + "[" * 40 + "1" + "]" * 40 + " --out {root}/new",
     "nested deeper than 16 levels"),
    ("train-set-deep-unclosed", "train --preset tiny --set train.steps=" + "[" * 5000 + " --out {root}/new",
     "nested deeper than 16 levels"),
    ("train-config-deep", "train --config {root}/deep.yaml --out {root}/new", "deep.yaml:16: not valid YAML (nested"),
    ("train-config-list-key", "train --config {root}/listkey.yaml --out {root}/new", "a list is used as a key"),
    ("train-config-duplicate", "train --config {root}/dup.yaml --out {root}/new", "given twice (lines 3 and 4)"),
    ("train-data-loop", "train --preset tiny --set data.root={root}/loopdir --out {root}/new", "a symlink loop"),
    ("reconstruct-image-loop", "reconstruct {run} {root}/loop.png --out {root}/rec", "a symlink loop"),
    ("reconstruct-azimuth-inf", "reconstruct {run} {root}/img.png --azimuth inf --out {root}/rec",
     "--azimuth inf: must be a finite number"),
    ("eval-data-loop", "eval {run} --data {root}/loopdir --out {root}/ev", "loopdir"),
    ("data-check-loop", "data check {root}/loopdir", "loopdir"),
    ("data-show-out-manifest", "data show {data} --out {data}/manifest.json", "is the input"),
    ("data-generate-source-loop", "data generate --dataset folder --source {root}/loopdir --out {root}/new",
     "--source {root}/loopdir: cannot be resolved: a symlink loop"),
    # a valid folder source inside the output: refused as an input the dataset would be written over (check_apart
    # in validate_generation, before the renderer is built and before the output rule looks at the folder)
    ("data-generate-out-holds-source", "data generate --dataset folder --source {root}/meshes --out {root}",
     "holds the input " + "{root}/meshes, and a dataset is written there"),
    pytest.param("eval-cuda", "eval {run} --device cuda", "CUDA is not available", marks=NO_CUDA),
    ("eval-truncated", "eval {root}/trunc.pt", "not a readable Cerberus checkpoint"),
    ("eval-random", "eval {root}/random.pt", "not a readable Cerberus checkpoint"),
    ("eval-pickled", "eval {root}/pickled.pt", "pickled Python object"),
    ("eval-truncated-safetensors", "eval {root}/trunc.safetensors", "not a readable safetensors file"),
    ("eval-missing", "eval {root}/nothing", "does not exist"),
    ("eval-dataset", "eval {data}", "is a dataset folder, not a training run"),
    ("eval-notes", "eval {root}/notes", "not a training run folder"),
    ("eval-resolution-0", "eval {run} --resolution 0", "--resolution 0: resolution must be an integer in [2, 1024]"),
    ("eval-resolution-1", "eval {run} --resolution 1", "--resolution 1: resolution must be an integer in [2, 1024]"),
    ("eval-resolution-huge", "eval {run} --resolution 100000", "--resolution 100000: resolution must be an integer in"),
    ("eval-protocol", "eval {run} --protocol foo", "--protocol foo: unknown protocol 'foo'"),
    ("eval-limit-negative", "eval {run} --limit -3", "--limit: must be >= 1"),
    ("eval-limit-0", "eval {run} --limit 0", "--limit: must be >= 1"),
    ("eval-figure-images-0", "eval {run} --figure-images 0", "--figure-images: must be >= 1"),
    ("eval-baseline-missing", "eval {run} --baseline X={root}/missing", "--baseline X="),
    ("eval-baseline-form", "eval {run} --baseline justaname", "NAME=RUN"),
    ("eval-out-file", "eval {run} --out {root}/afile", "is a file"),
    ("eval-out-dataset", "eval {run} --out {data}", "holds a dataset (cerberus data generate), and an output is only"),
    ("eval-data-notes", "eval {run} --data {root}/notes", "not a Cerberus dataset"),
    ("eval-split", "eval {run} --split nosuch", "no split 'nosuch'"),
    ("eval-renderer", "eval {run} --renderer nope", "unknown renderer 'nope'"),
    # issue 20: model files that cannot be scored, result folders that must not be replaced
    ("eval-fifo", "eval {root}/pipe.safetensors", "is a FIFO (named pipe), not a model file"),
    ("eval-nan-weights", "eval {root}/nan.safetensors", "hold NaN or infinite values"),
    ("eval-scene-not-json", "eval {root}/scene_json.safetensors", "recorded scene set-up is not JSON"),
    ("eval-scene-manifest", "eval {run} --data {root}/badscene", "scene.elevation: expected a number, got 'high'"),
    ("reconstruct-scene-manifest", "reconstruct {run} {root}/img.png --data {root}/badscene --out {root}/rec",
     "invalid scene set-up (scene.elevation: expected a number, got 'high'"),
    ("data-show-scene-manifest", "data show {root}/badscene --out {root}/sheet.png", "invalid scene set-up"),
    ("eval-unknown-name", "eval nosuchmodel", "no pretrained model named 'nosuchmodel'"),
    ("eval-out-notes", "eval {run} --out {root}/notes --overwrite", "is not empty (it holds"),
    ("eval-out-run", "eval {run} --out {run}", "an output folder is replaced whole"),
    ("eval-out-data-parent", "eval {run} --data {data} --out {root}", "an output folder is replaced whole"),
    ("reconstruct-fifo", "reconstruct {run} {root}/pipe.png --out {root}/rec", "is a FIFO (named pipe), not an image"),
    ("reconstruct-device", "reconstruct {run} /dev/zero --out {root}/rec", "is a device, not an image"),
    ("reconstruct-nan-weights", "reconstruct {root}/nan.safetensors {root}/img.png --out {root}/rec", "NaN"),
    ("reconstruct-scene-value", "reconstruct {root}/scene_value.safetensors {root}/img.png --out {root}/rec",
     "invalid scene set-up"),
    ("reconstruct-out-inputs", "reconstruct {run} {root}/img.png --out {root}", "holds the input " + "{root}/img.png"),
    ("reconstruct-out-run", "reconstruct {run} {root}/img.png --out {run}", "an output folder is replaced whole"),
    ("reconstruct-out-notes", "reconstruct {run} {root}/img.png --out {root}/notes --overwrite", "is not empty (it holds"),
    ("reconstruct-model-path", "reconstruct --model ./human {root}/img.png --out {root}/rec",
     "takes a shipped model's name"),
    ("reconstruct-out-name-long", "reconstruct {run} {root}/img.png --out {root}/" + "o" * 300,
     "is 300 bytes long; file systems allow 255"),
    ("reconstruct-out-path-long", "reconstruct {run} {root}/img.png --out {root}/" + "/".join(["d" * 200] * 25),
     "the path is"),
    ("reconstruct-image-path-long", "reconstruct {run} {root}/" + "/".join(["d" * 200] * 25) + ".png --out {root}/rec",
     "cannot be read (File name too long)"),
    ("eval-run-name-long", "eval ./" + "r" * 300, "cannot be read (File name too long)"),
    ("eval-out-name-long", "eval {run} --out {root}/" + "e" * 300, "is 300 bytes long"),
    ("data-show-out-name-long", "data show {data} --out {root}/" + "s" * 300 + ".png", "is 304 bytes long"),
    ("train-config-fifo", "train --config {root}/pipe.yaml --out {root}/new", "is not a regular file"),
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
    ("reconstruct-out-dataset", "reconstruct {run} {root}/img.png --out {data}", "holds a dataset (cerberus data generate)"),
    ("reconstruct-data-notes", "reconstruct {run} {root}/img.png --data {root}/notes --out {root}/rec",
     "not a Cerberus dataset"),
    ("demo-size-0", "demo --image-size 0 --out {root}/demo", "--image-size: must be >= 1"),
    ("demo-size-huge", "demo --image-size 100000 --out {root}/demo", "at most"),
    ("demo-out-file", "demo --out {root}/afile", "is a file"),
    ("demo-out-dataset", "demo --out {data}", "holds a dataset (cerberus data generate)"),
    ("demo-renderer", "demo --renderer nope --out {root}/demo", "unknown renderer 'nope'"),
    # data generate: the whole generation is validated before --dry-run returns and before the folder's
    # lock or manifest is written (cerberus_core.datasets.generate.validate_generation)
    *[(f"data-generate-{name}{'-dry-run' if dry else ''}", f"{GEN} {argv}{' --dry-run' if dry else ''}", expected)
      for name, argv, expected in [
          ("image-size-huge", "--image-size 100000 --out {root}/new", "--image-size 100000: must be an integer in [8, 1024]"),
          ("image-size-negative", "--image-size -5 --out {root}/new", "--image-size -5: must be an integer in [8, 1024]"),
          ("memory", "--size paper --image-size 1024 --shard-images 100000 --batch-size 100000 --out {root}/new",
           "GiB of memory"),
          ("renderer", "--renderer foo --out {root}/new", "unknown renderer 'foo'"),
          ("set-renderer", "--set renderer=foo --out {root}/new", "unknown renderer 'foo'"),
          ("size", "--size nope --out {root}/new", "--size nope: unknown size preset for dataset 'primitives'"),
          ("set-yaml", "--set seed=[1 --out {root}/new", "not valid YAML"),
          ("set-key", "--set splits.train.pair=3 --out {root}/new", "did you mean 'splits.train.pairs'"),
          ("set-nan", "--set scene.elevation=.nan --out {root}/new", "scene.elevation = nan: must be a finite"),
          ("pairs-negative", "--set splits.train.pairs=-1 --out {root}/new", "splits.train.pairs = -1: must be an integer >= 0"),
          ("split-empty", "--set splits.train.pairs=0 --out {root}/new", "split 'train' would be empty"),
          ("split-huge", "--set splits.train.pairs=100000000 --out {root}/new", "400,000,000 images, more than"),
          ("subjects-huge", "--set splits.train.subjects=1000000 --out {root}/new", "splits.train.subjects = 1000000: must be an integer in [0, 10000]"),
          ("views-huge", "--set splits.test.views=100000 --out {root}/new", "splits.test.views = 100000: must be an integer in [1, 360]"),
          ("quadruplets-negative", "--set splits.test.quadruplets_per_pose=-1 --out {root}/new",
           "splits.test.quadruplets_per_pose = -1: must be an integer >= 0"),
          ("scene-near", "--set scene.near=-1 --out {root}/new", "scene.near = -1.0: must be a number > 0"),
          ("scene-far", "--set scene.far=1 --out {root}/new", "far 1.0 must exceed the distance"),
          ("scene-background", "--set scene.background=[2,0,0] --out {root}/new", "RGB values must lie in [0, 1]"),
          ("seed-negative", "--seed -1 --out {root}/new", "--seed -1: must be an integer >= 0"),
          ("shard-images-0", "--shard-images 0 --out {root}/new", "--shard-images 0: must be an integer >= 4"),
          ("batch-size-0", "--batch-size 0 --out {root}/new", "--batch-size: must be >= 1"),
          ("test-fraction-not-folder", "--test-fraction 0.5 --out {root}/new", "--test-fraction 0.5: not an option of the primitives body source"),
          ("out-file", "--out {root}/afile", "is a file"),
          ("out-under-file", "--out {root}/afile/sub", "is under"),
          ("out-notes", "--out {root}/notes", "is not empty (it holds todo.txt) and is not a dataset"),
          ("out-other-dataset", "--seed 5 --out {data}", "holds a different dataset"),
      ] for dry in (False, True)],
    pytest.param("data-generate-cuda", GEN + " --device cuda --out {root}/new", "CUDA is not available",
                 marks=NO_CUDA),
    ("data-generate-folder-no-source", "data generate --dataset folder --out {root}/new", "--source: the folder source needs its folder of meshes: --source DIR"),
    ("data-generate-folder-missing", "data generate --dataset folder --source {root}/nothing --out {root}/new",
     "does not exist"),
    ("data-generate-folder-fraction", "data generate --dataset folder --source {root}/notes --test-fraction 2 "
     "--out {root}/new", "--test-fraction 2.0: must be a number in [0, 1]"),
    ("data-check-missing", "data check {root}/nothing", "does not exist"),
    ("data-check-file", "data check {root}/afile", "is a file, not a dataset folder"),
    ("data-check-notes", "data check {root}/notes", "is not a Cerberus dataset"),
    ("data-show-missing", "data show {root}/nothing --out {root}/sheet.png", "does not exist"),
    ("data-show-notes", "data show {root}/notes --out {root}/sheet.png", "is not a Cerberus dataset"),
    ("data-show-split", "data show {data} --split nosuch --out {root}/sheet.png", "no split 'nosuch'"),
    ("data-show-count-0", "data show {data} --count 0 --out {root}/sheet.png", "--count: must be >= 1"),
    ("data-show-scale-huge", "data show {data} --scale 1000 --out {root}/sheet.png",
     "--scale 1000: must be an integer in [1, 16]"),
    ("data-show-out-folder", "data show {data} --out {root}/notes", "is a folder"),
    ("data-show-out-under-file", "data show {data} --out {root}/afile/sheet.png", "which is a file"),
    ("data-show-renderer", "data show {data} --renderer nope --out {root}/sheet.png", "unknown renderer 'nope'"),
    pytest.param("data-show-out-unwritable", "data show {data} --out /sys/cerberus-sheet.png", "cannot write",
                 marks=pytest.mark.skipif(not Path("/sys").is_dir(), reason="no /sys here")),
    ("data-show-renderer-parts", "data show {data} --parts --renderer nope --out {root}/sheet.png",
     "unknown renderer 'nope'"),
]


def snapshot(root: Path) -> dict[str, tuple[int, int]]:
    return {str(p.relative_to(root)): (p.lstat().st_size, p.lstat().st_mtime_ns) for p in sorted(root.rglob("*"))}


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
    assert expected.format(**{k: str(v) for k, v in place.items()}) in err, err
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
    files = [p for p in out.rglob("*") if p.is_file() and p.name != MARKER]
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
    import cerberus_core.datasets.dataset as dataset_module

    data = tmp_path / "partial"
    original = dataset_module.write_dataset

    def interrupted_after_one_shard(*args, **kwargs):
        def stop(split, rec):
            raise KeyboardInterrupt
        return original(*args, **{**kwargs, "on_shard": stop})

    monkeypatch.setattr(dataset_module, "write_dataset", interrupted_after_one_shard)
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
    assert len(Dataset.open(data).quadruplets()) == 4
    assert main(["data", "check", str(data)]) == 0


def test_the_scene_of_a_model_is_never_a_silent_default(place, tmp_path):
    """Issue 11 (6): reconstruct fell back to a default scene when the run's data was not there."""
    from dataclasses import replace

    from cerberus_core.errors import ConfigError
    from cerberus_core.run import Run, model_scene

    run = Run.load(place["run"])
    config, saved = run.config, run.recorded_scene
    assert saved is not None, "a run records its scene with its weights"
    trained_on = model_scene(config, None, None)  # the training data is still there
    assert model_scene(config, None, saved) == trained_on == model_scene(config, place["data"], None)
    gone = replace(config, data=replace(config.data, root=str(tmp_path / "moved")))
    with pytest.raises(ConfigError, match="pass `data=DATASET`"):
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


# ------------------------------------------------------------------ issue 20: no lost or mixed-up file
def _image(path: Path, colour=(200, 10, 10)) -> Path:
    from PIL import Image

    Image.new("RGB", (32, 32), colour).save(path)
    return path


def _tree(folder: Path) -> dict[str, bytes]:
    return {str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()}


def test_outputs_of_one_input_never_take_another_inputs_name(place, tmp_path, capsys):
    """x.png writes x_new_pose.glb (the viewer's new pose), which is also the GLB of x_new_pose.png:
    each input keeps every one of its outputs, under names that share nothing."""
    from cerberus_core.reconstruct.write import OUTPUT_PATTERNS, output_names

    inputs = [_image(tmp_path / "x.png"), _image(tmp_path / "x_new_pose.png", (10, 10, 200)),
              _image(tmp_path / "X_parts.png", (10, 200, 10))]
    stems = output_names(inputs)
    assert stems[0] == "x" and stems[1] != "x_new_pose" and len({s.casefold() for s in stems}) == 3
    out = tmp_path / "rec"
    assert main(["reconstruct", str(place["run"]), *map(str, inputs), "--out", str(out)]) == 0
    assert "x_new_pose.png -> " in capsys.readouterr().out  # the renamed input is named
    written = {p.name for p in out.iterdir()} - {"index.html", MARKER}
    expected = [{pattern.format(s) for pattern in OUTPUT_PATTERNS} for s in stems]
    masked_only = {f"{s}{suffix}" for s in stems for suffix in ("_mask.png", "_steps.png")}  # written with a mask
    assert written <= set().union(*expected), "OUTPUT_PATTERNS must list every name reconstruct writes"
    assert set().union(*expected) - masked_only <= written
    assert sum(len(e - masked_only) for e in expected) == len(written)  # no name is shared between two inputs


def test_a_result_folder_is_complete_or_untouched(place, tmp_path, capsys, monkeypatch):
    """A second reconstruct into the same --out replaces the first one's results whole; one stopped midway by
    SIGTERM, or one that runs out of disk space, leaves the earlier results exactly as they were and no
    temporary folder beside them."""
    import resource
    import signal

    import cerberus_core.eval.figures as figures

    a, b = _image(tmp_path / "a.png"), _image(tmp_path / "b.png", (10, 10, 200))
    out = tmp_path / "results" / "rec"
    assert main(["reconstruct", str(place["run"]), str(a), str(b), "--out", str(out)]) == 0
    assert main(["reconstruct", str(place["run"]), str(a), "--out", str(out)]) == 0  # an earlier result: replaced
    first = _tree(out)
    assert not any(name.startswith("b") for name in first), "no mix of old and new results"
    capsys.readouterr()

    calls = []
    real_save_png = figures.save_png

    def save_then_sigterm(image, path):
        calls.append(path)
        written = real_save_png(image, path)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGTERM)  # a real signal, midway through the pictures
        return written

    monkeypatch.setattr(figures, "save_png", save_then_sigterm)
    assert main(["reconstruct", str(place["run"]), str(b), "--out", str(out)]) == 143
    monkeypatch.undo()
    assert capsys.readouterr().err == "cerberus reconstruct: terminated (SIGTERM)\n"
    assert len(calls) == 3 and _tree(out) == first
    assert sorted(p.name for p in out.parent.iterdir()) == ["rec"], "a temporary folder was left behind"

    soft, hard = resource.getrlimit(resource.RLIMIT_FSIZE)
    resource.setrlimit(resource.RLIMIT_FSIZE, (20_000, hard))  # files past 20 kB fail with EFBIG, as on a full disk
    try:
        code = main(["reconstruct", str(place["run"]), str(b), "--out", str(out)])
    finally:
        resource.setrlimit(resource.RLIMIT_FSIZE, (soft, hard))
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and f"cannot write {out}/" in err and "File too large" in err, err
    assert _tree(out) == first
    assert sorted(p.name for p in out.parent.iterdir()) == ["rec"]


def test_an_unwritable_out_is_one_line(place, tmp_path, capsys):
    """/sys refuses new folders even to root (a chmod would not stop root)."""
    if not Path("/sys").is_dir():
        pytest.skip("no /sys here")
    code = main(["reconstruct", str(place["run"]), str(_image(tmp_path / "a.png")), "--out", "/sys/cerberus-out"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "cannot write /sys/cerberus-out" in err, err
    assert "Traceback" not in err


def test_hostile_file_names_are_outputs_and_printed_safely(place, tmp_path, capsys):
    """A 250-byte name, a name that is not UTF-8 and one with terminal escapes: every input gets its outputs
    (names within the file system's limit, valid UTF-8), and nothing raw reaches the terminal."""
    names = ["n" * 246 + ".png", os.fsdecode(b"caf\xe9.png"), "\x1b[31mred\x07.png"]
    inputs = [_image(tmp_path / n, (30 * i, 100, 200)) for i, n in enumerate(names)]
    out = tmp_path / "rec"
    assert main(["reconstruct", str(place["run"]), *map(str, inputs), "--out", str(out)]) == 0
    printed, err = capsys.readouterr()
    for text in (printed, err):
        assert "\x1b" not in text and "\x07" not in text
        text.encode("utf-8")  # no lone surrogate from the undecodable name
    glbs = sorted(p.name for p in out.glob("*.glb") if not p.name.endswith("_new_pose.glb"))
    assert len(glbs) == 3
    for p in out.rglob("*"):
        assert len(os.fsencode(p.name)) <= 255
        p.name.encode("utf-8")
    assert "\\x1b[31mred\\x07" in printed  # shown escaped


def test_a_shipped_name_is_never_a_local_folder(place, tmp_path, monkeypatch):
    """`human` is the shipped model even beside a folder called human; ./human is the folder."""
    import shutil
    import warnings

    from cerberus_core.weights import resolve_weights
    from cerberus_core.zoo import ZOO_DIR

    monkeypatch.chdir(tmp_path)
    shutil.copytree(place["run"], tmp_path / "human")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        assert resolve_weights("human") == ZOO_DIR / "human.safetensors"
    assert any("write ./human" in str(w.message) for w in caught)
    assert resolve_weights("./human") == Path("human") / "model.safetensors"
    assert resolve_weights(str(tmp_path / "human")).parent == tmp_path / "human"
    help_text = " ".join(__import__("cerberus_core.cli", fromlist=["build_parser"]).build_parser()
                         ._subparsers._group_actions[0].choices["reconstruct"].format_help().split())
    assert "./human" in help_text


def test_eval_reports_its_step_and_a_newer_checkpoint(place, tmp_path, capsys):
    """After an interrupted --resume, last.pt is newer than model.safetensors: eval says which step it
    scores, warns, and records both in results.json."""
    import json
    import shutil

    run = tmp_path / "run"
    shutil.copytree(place["run"], run)
    payload = torch.load(run / "checkpoints" / "last.pt", weights_only=True)
    payload["step"] = 5  # as a resumed training that checkpointed step 5, then was stopped
    torch.save(payload, run / "checkpoints" / "last.pt")
    (run / "eval").mkdir()
    (run / "eval" / "results.json").write_text("{}")  # an earlier version's results, marked as they were then:
    (run / "eval" / ".cerberus-result.json").write_text('{"command": "cerberus eval", "written": 0}')  # replaced
    with pytest.warns(UserWarning, match=r"holds step 2 but .*last.pt is at step 5.*resuming its training"):
        assert main(["eval", str(run), "--limit", "1", "--no-hard", "--no-part-quality", "--figure-images", "1",
                     "--viewer-images", "0"]) == 0
    printed = capsys.readouterr().out
    assert f"evaluating {run / 'model.safetensors'} at step 2" in printed
    assert f"note: these scores are for step 2; the run has a newer checkpoint {run / 'checkpoints' / 'last.pt'}" in printed
    record = json.loads((run / "eval" / "results.json").read_text())
    assert record["model"]["step"] == 2 and record["model"]["newer_checkpoint"]["step"] == 5
    assert "Warning" in (run / "eval" / "results.md").read_text()
    # the checkpoint itself is scored when named, without a warning
    assert main(["eval", str(run / "checkpoints" / "last.pt"), "--limit", "1", "--no-hard", "--no-part-quality",
                 "--figure-images", "1", "--viewer-images", "0", "--out", str(tmp_path / "ev")]) == 0
    printed = capsys.readouterr().out
    assert "at step 5" in printed and "note:" not in printed


def test_a_training_that_crashed_before_its_first_checkpoint_restarts(place, tmp_path, capsys):
    """A run stopped by a NaN at its first step leaves config.yaml and metrics.csv but no checkpoint; the
    command run again starts there with no manual clean-up (and --resume says why it cannot)."""
    run = tmp_path / "run"
    common = ["train", "--preset", "tiny", "--set", f"data.root={place['data']}", "--set", "train.steps=1",
              "--set", "train.tensorboard=false", "--set", "train.progress=false", "--out", str(run)]
    torch_threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        assert main([*common, "--set", "debug.poison_steps=[0]", "--set", "train.on_nonfinite=stop"]) == 3
        assert (run / "config.yaml").is_file() and not (run / "checkpoints" / "last.pt").exists()
        capsys.readouterr()
        assert main([*common, "--resume"]) == 2
        assert "stopped before its first checkpoint" in capsys.readouterr().err
        with pytest.warns(UserWarning, match="stopped before its first checkpoint .*starts again"):
            assert main(common) == 0  # the same command, no manual clean-up
    finally:
        torch.set_num_threads(torch_threads)
    assert "finished step 1" in capsys.readouterr().out
    assert (run / "model.safetensors").is_file()


#: Every command that takes --out, over a folder (for cerberus-metrics batch: a file) holding a foreign file, with
#: --overwrite where the command has it (issue 39: the rule is "only what the toolkit wrote as the same output").
OVER_FOREIGN = [
    ("data generate", GEN + " --out {out} --overwrite"),
    ("train", "train --preset tiny --set data.root={data} --set train.steps=1 --out {out}"),
    ("eval", "eval {run} --data {data} --limit 1 --out {out} --overwrite"),
    ("reconstruct", "reconstruct {run} {root}/img.png --out {out} --overwrite"),
    ("reconstruct --model", "reconstruct --model human {root}/img.png --out {out} --overwrite"),
    ("demo", "demo --renderer torch --out {out}"),
    ("cerberus-metrics batch", "batch --pairs {root}/pairs.csv --no-progress --out {out}/results.json"),
]


@pytest.mark.parametrize(("command", "argv"), OVER_FOREIGN, ids=[c[0] for c in OVER_FOREIGN])
def test_no_command_replaces_a_folder_it_did_not_write(place, tmp_path, capsys, command, argv):
    """Each command, pointed with --overwrite at a folder of someone else's files (under a temporary folder),
    refuses in one line (exit 2) naming what is there, and every file survives unchanged."""
    from cerberus_metrics.cli import main as metrics_main

    out = tmp_path / "mine"
    (out / "sub").mkdir(parents=True)
    (out / "thesis.tex").write_text("years of work")
    (out / "sub" / "data.csv").write_text("1,2,3")
    (out / "results.json").write_text('{"mine": true}')
    (out / f".{out.name}.999999.mine.tmp").mkdir()  # named like a dead writer's temporary, but not one
    if command.startswith("cerberus-metrics"):
        (tmp_path / "a.obj").write_text(TETRA)
        (place["root"] / "pairs.csv").write_text(f"pred,gt\n{tmp_path / 'a.obj'},{tmp_path / 'a.obj'}\n")
    before = snapshot(tmp_path)
    args = [a.format(out=out, **{k: str(v) for k, v in place.items()}) for a in argv.split()]
    code = metrics_main(args) if command.startswith("cerberus-metrics") else main(args)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert "is not empty (it holds" in err or "exists and is not results that cerberus-metrics batch wrote" in err
    assert snapshot(tmp_path) == before
