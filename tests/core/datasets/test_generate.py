"""The generation driver (cerberus_core.datasets.generate): determinism, atomic shards, resume after a kill,
refusing foreign folders, supersampled images."""
from __future__ import annotations

import json
import subprocess
import sys
import textwrap
from dataclasses import replace

import numpy as np
import pytest

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.format import DatasetError, sha256_file
from cerberus_core.datasets.manifest import MANIFEST, Manifest
from cerberus_core.datasets.plan import preset_config
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import ConfigError
from cerberus_core.plumbing.atomic import TEMP_MARKER
from cerberus_core.plumbing.outputs import MARKER, write_marker

QUIET = {"progress": False, "log": lambda s: None}


def _fingerprint(root) -> dict[str, str]:
    """sha256 of every file of a dataset (manifest included), by relative path."""
    return {p.relative_to(root).as_posix(): sha256_file(p) for p in sorted(root.rglob("*")) if p.is_file()}


def test_same_seed_same_dataset(pairs_dataset, pairs_config, tmp_path):
    again = tmp_path / "again"
    Dataset.generate(pairs_config(), again, **QUIET)
    assert _fingerprint(again) == _fingerprint(pairs_dataset)
    other = tmp_path / "other"
    Dataset.generate(pairs_config(seed=1), other, **QUIET)
    m0 = json.loads((pairs_dataset / MANIFEST).read_text())
    m1 = json.loads((other / MANIFEST).read_text())
    sha = lambda m: [s["files"]["images"]["sha256"] for s in m["splits"]["train"]["shards"]]  # noqa: E731
    assert not set(sha(m0)) & set(sha(m1))


def test_interrupted_run_resumes_to_the_identical_dataset(pairs_dataset, pairs_config, tmp_path):
    out = tmp_path / "ds"
    done = []

    def crash_after_two(split, rec):
        done.append(rec.name)
        if len(done) == 2:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        Dataset.generate(pairs_config(), out, on_shard=crash_after_two, **QUIET)
    manifest = Manifest.read(out)
    assert not manifest.complete and len(manifest.split("train").shards) == 2

    with pytest.raises(DatasetError, match="incomplete"):
        Dataset.open(out).quadruplets()
    finished = manifest.split("train").totals()["quadruplets"]
    assert len(Dataset.open(out).quadruplets(allow_partial=True)) == finished > 0
    rebuilt = []
    Dataset.generate(pairs_config(), out, on_shard=lambda split, rec: rebuilt.append((split, rec.name)), **QUIET)
    final = Manifest.read(out)
    everything = [(split, s.name) for split in ("train", "test") for s in final.split(split).shards]
    assert rebuilt == everything[2:]  # the finished shards were not redone
    assert _fingerprint(out) == _fingerprint(pairs_dataset)


def test_killed_mid_shard_leaves_no_accepted_half_shard(pairs_dataset, pairs_config, tmp_path):
    """SIGKILL the generator after the images file of the second shard is in place, before its other
    files and its manifest entry: the rerun rebuilds that shard and ends identical to a clean run."""
    out = tmp_path / "ds"
    script = textwrap.dedent(f"""
        import os, signal
        from cerberus_core.datasets import format as fmt
        from cerberus_core.datasets.dataset import Dataset
        from cerberus_core.datasets.settings import GenerationConfig, SplitConfig
        saves = []
        original = fmt.atomic_save_npy
        def save(path, array):
            original(path, array)
            saves.append(path)
            if len(saves) == 6:  # shard 0: images views quads vertices; shard 1: images, views
                os.kill(os.getpid(), signal.SIGKILL)
        fmt.atomic_save_npy = save
        splits = {{
            "train": SplitConfig("pairs", subjects=2, pairs=6, meshes=True),
            "test": SplitConfig("grid", subjects=1, poses=2, views=4, canonical=True),
        }}
        config = GenerationConfig("primitives", "test-pairs", splits, image_size=32, shard_images=8)
        Dataset.generate(config, {str(out)!r}, progress=False, log=lambda s: None)
    """)
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert proc.returncode == -9, proc.stderr
    manifest = json.loads((out / MANIFEST).read_text())
    assert [s["name"] for s in manifest["splits"]["train"]["shards"]] == ["shard-00000"]
    assert (out / "train" / "shard-00001.images.npy").exists()  # written, but not listed: not accepted
    torn = out / "train" / ".shard-00001.quads.npy.123.abc.tmp"  # a torn temporary: a marked folder
    torn.mkdir()
    (torn / TEMP_MARKER).write_text("")
    (torn / "file").write_bytes(b"partial")
    Dataset.generate(pairs_config(), out, **QUIET)
    assert _fingerprint(out) == _fingerprint(pairs_dataset)


def test_damaged_finished_shard_is_rebuilt_on_resume(pairs_dataset, tmp_path, pairs_config):
    import shutil

    out = tmp_path / "ds"
    shutil.copytree(pairs_dataset, out)
    victim = out / "train" / "shard-00001.views.npy"
    victim.write_bytes(victim.read_bytes()[:-1] + b"\x00")
    messages = []
    Dataset.generate(pairs_config(), out, progress=False, log=messages.append)
    assert any("damaged" in m and "shard-00001" in m for m in messages)
    assert _fingerprint(out) == _fingerprint(pairs_dataset)


def test_foreign_or_different_folders_are_refused(pairs_dataset, pairs_config, tmp_path):
    import shutil

    out = tmp_path / "ds"
    shutil.copytree(pairs_dataset, out)
    before = _fingerprint(out)
    with pytest.raises(DatasetError, match="different dataset.*seed"):
        Dataset.generate(pairs_config(seed=3), out, **QUIET)
    assert _fingerprint(out) == before  # nothing overwritten
    Dataset.generate(pairs_config(seed=3), out, overwrite=True, **QUIET)
    assert json.loads((out / MANIFEST).read_text())["config"]["seed"] == 3
    assert Dataset.open(out).verify() == []



def test_overwrite_never_touches_a_folder_the_toolkit_did_not_write(pairs_dataset, pairs_config, tmp_path):
    """Issue 39: ``data generate --out ~ --overwrite`` replaced ``~/train`` and ``~/test``. A folder holding
    anything but a dataset the toolkit wrote is refused, ``overwrite`` or not, and nothing in it changes."""
    import shutil

    busy = tmp_path / "busy"
    for name in ("train", "test"):
        (busy / name).mkdir(parents=True)
        (busy / name / "thesis.tex").write_text("mine")
    for overwrite in (False, True):
        with pytest.raises(ConfigError, match=r"is not empty \(it holds test, train\) and is not a dataset .* written "
                           "by Cerberus"):
            Dataset.generate(pairs_config(), busy, overwrite=overwrite, **QUIET)
    assert sorted(p.relative_to(busy).as_posix() for p in busy.rglob("*")) == [
        "test", "test/thesis.tex", "train", "train/thesis.tex"]
    # a dataset written before the marker (its manifest reads) is still the toolkit's: replaced with overwrite
    old = tmp_path / "old"
    shutil.copytree(pairs_dataset, old)
    (old / MARKER).unlink()
    Dataset.generate(pairs_config(seed=3), old, overwrite=True, **QUIET)
    assert json.loads((old / MARKER).read_text())["kind"] == "dataset"
    # a split folder the old dataset did not write is not replaced, nor written into
    (old / "extra").mkdir()
    (old / "extra" / "mine.txt").write_text("mine")
    config = pairs_config()
    config = replace(config, splits={**config.splits, "extra": config.splits["test"]})
    with pytest.raises(DatasetError, match="holds extra, which the dataset there did not write"):
        Dataset.generate(config, old, overwrite=True, **QUIET)
    assert (old / "extra" / "mine.txt").read_text() == "mine"
    # a run or results are another kind of output: refused by name
    run = tmp_path / "run"
    run.mkdir()
    write_marker(run, "run")
    (run / "config.yaml").write_text("x")
    with pytest.raises(ConfigError, match=r"holds a training run \(cerberus train\), and an output is only ever"):
        Dataset.generate(pairs_config(), run, overwrite=True, **QUIET)


def test_resuming_a_finished_dataset_does_nothing(pairs_dataset, pairs_config, tmp_path):
    import shutil

    out = tmp_path / "ds"
    shutil.copytree(pairs_dataset, out)
    built = []
    Dataset.generate(pairs_config(), out, on_shard=lambda *a: built.append(a), **QUIET)
    assert built == []
    assert _fingerprint(out) == _fingerprint(pairs_dataset)


def test_stored_images_match_a_fresh_render_of_the_stored_mesh(pairs_dataset):
    """Cameras, light, albedo and meshes in the files are exactly what produced the images."""
    import torch

    from cerberus_core.render.api import render
    from cerberus_core.render.backends import make_renderer

    views = Dataset.open(pairs_dataset).views("train")
    renderer = make_renderer("torch")
    for i in (0, 5, len(views) - 1):
        item, body = views[i], views.gt_mesh(i)
        cam = views.cameras({k: item[k][None] for k in ("azimuth", "elevation", "distance", "fov_y")})
        out = render(renderer, torch.as_tensor(body.vertices)[None], torch.as_tensor(body.faces), cam,
                     views.scene.light(cam), albedo=views.scene.albedo, background=views.scene.background)
        again = (out.image[0].clamp(0, 1) * 255 + 0.5).to(torch.uint8).float() / 255
        assert torch.equal(again, item["images"])
        assert np.abs(body.vertices).max() <= 0.5


def test_the_memory_of_a_generation_is_checked_where_it_lives(monkeypatch, tmp_path):
    """The shard's images live in RAM; the render buffers in RAM on a CPU, on the GPU with --device cuda."""
    from types import SimpleNamespace

    import torch

    import cerberus_core.datasets.generate as gen
    import cerberus_core.plumbing.machine as machine
    from cerberus_core.datasets.plan import preset_config
    from cerberus_core.errors import ConfigError

    config = preset_config("primitives", "tiny", image_size=1024)  # 24-image shards: 0.07 GiB + 3.75 GiB to render
    job = gen.validate_generation(config, batch_size=24)
    assert job.peak_bytes == 24 * 3 * 1024**2 + 24 * 1024**2 * gen.RENDER_BYTES_PER_PIXEL
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    monkeypatch.setattr(torch.cuda, "get_device_properties", lambda device: SimpleNamespace(total_memory=2**30))
    with pytest.raises(ConfigError, match=r"on GPU cuda \(.*to render 24 views at once\), more than it has \(1.0 GiB"):
        gen.validate_generation(config, device="cuda", batch_size=24)
    gen.validate_generation(config, device="cuda", batch_size=4)  # 0.6 GiB of buffers fit
    ram = {"SC_PAGE_SIZE": 4096, "SC_PHYS_PAGES": 2**30 // 4096}  # a machine with 1 GiB
    monkeypatch.setattr(machine.os, "sysconf", lambda name: ram[name])  # the one place memory is read
    with pytest.raises(ConfigError, match="on this machine .*lower `image_size`, `batch_size` or `shard_images`"):
        gen.validate_generation(config, batch_size=24)
    with pytest.raises(ConfigError, match="on this machine"):  # Dataset.generate() validates first: nothing written
        Dataset.generate(config, tmp_path / "ds", batch_size=24, **QUIET)
    assert not (tmp_path / "ds").exists()



def test_the_body_source_is_loaded_before_the_progress_bar_starts(tmp_path, capsys):
    """Issue 34: anny's one-time cache build (two minutes) ran under the generation's bar, frozen at 0/44, and
    then poisoned its rate (38 s/img). The source's load, announced, now comes before the bar's first line;
    a finished dataset does not load it at all."""
    from cerberus_core.bodies.sources import PrimitiveSource
    from cerberus_core.plumbing.stdio import announce

    class SlowToLoad(PrimitiveSource):
        loads = 0

        def prepare(self) -> None:
            announce("loading the body model")
            self.loads += 1

        def bodies(self, subject, pose_ids):
            assert self.loads == 1, "posed before prepare()"
            return super().bodies(subject, pose_ids)

    config, source = preset_config("primitives", "tiny", image_size=32), SlowToLoad()
    Dataset.generate(config, tmp_path / "ds", source=source, log=lambda s: None)
    err = capsys.readouterr().err
    assert "loading the body model" in err and err.index("loading the body model") < err.index("img")
    Dataset.generate(config, tmp_path / "ds", source=source, log=lambda s: None)  # finished: nothing to pose
    assert source.loads == 1


def test_a_source_missing_its_packages_is_refused_before_anything_is_written(tmp_path):
    """Issue 34: the human source without anny (the animal one without scipy) wrote its manifest and failed later,
    under the bar; every missing package is now named up front, with the extra that brings it."""
    from cerberus_core.bodies.sources import PrimitiveSource
    from cerberus_core.errors import ConfigError

    class Needy(PrimitiveSource):
        packages = {"numpy": "numpy", "no_such_package_a": "needy[extra]", "no_such_package_b": "needy[extra]"}

    config = preset_config("primitives", "tiny", image_size=32)
    with pytest.raises(ConfigError, match=r"^the primitives body source needs no_such_package_a and no_such_package_b, "
                       r"which are not installed: pip install 'needy\[extra\]'$"):
        Dataset.generate(config, tmp_path / "ds", source=Needy(), **QUIET)
    assert not (tmp_path / "ds").exists()


def test_supersampled_images_blend_edges_and_keep_the_coverage(tmp_path):
    """``supersample``: images are rendered larger and box-filtered, so edges take intermediate values
    while the body's total brightness matches the hard render's; stored only when not 1."""
    from cerberus_core.bodies.body import PosedBody
    from cerberus_core.datasets.generate import render_views
    from cerberus_core.render.backends import make_renderer
    from cerberus_core.render.templates import icosphere

    sphere = icosphere(3)
    body = PosedBody(0.3 * sphere.vertices.numpy(), sphere.faces.numpy(), np.zeros(len(sphere.vertices)), ["all"], "s", 0)
    scene = SceneSetup(background=(0.0, 0.0, 0.0))
    renderer = make_renderer("torch")
    args = (renderer, [body], np.zeros(2, dtype=np.int64), np.array([0.0, 90.0]), scene, 32)
    hard, soft = render_views(*args), render_views(*args, supersample=4)
    edge_values = lambda im: int(((im > 0) & (im < 40)).sum())  # noqa: E731  darker than any lit surface pixel
    assert edge_values(soft) > 3 * max(edge_values(hard), 1)
    assert abs(float(soft.astype(np.float64).sum()) / float(hard.astype(np.float64).sum()) - 1) < 0.05
    cfg = preset_config("primitives", "tiny")
    assert "supersample" not in cfg.to_dict() and replace(cfg, supersample=4).to_dict()["supersample"] == 4
    with pytest.raises(ValueError, match=r"supersample = .*: must be an integer in \[1, 8\]"):
        replace(cfg, supersample=0)
