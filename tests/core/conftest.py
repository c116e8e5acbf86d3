"""Fixtures shared by the core package's tests (``tests/core/**``), in sections:

* datasets: small datasets of capsule figures (the ``primitives`` source), generated with the real renderer
  into temporary folders;
* training: the tiny on-disk dataset (6 training quadruplets at 32 pixels, made in a few seconds), the
  ``tiny`` training config on it, a run trained 2 steps on it (``tiny_run``), and ``one_thread``;
* evaluation: the torch renderer, capsule-figure bodies and the tiny rendered test set of
  ``tests/support/oracle.py``, and the voxel IoU scorer of cerberus-metrics;
* the shipped ``human`` run.

Helpers that test modules import live in ``tests/support/``, not here.
"""
from __future__ import annotations

from pathlib import Path

import pytest
import torch

from cerberus_core.bodies.primitives import PrimitiveBodySource, sample_subjects
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.plan import preset_config
from cerberus_core.datasets.settings import GenerationConfig, SplitConfig
from cerberus_core.errors import PluginError
from cerberus_core.plugins import get_metric
from cerberus_core.render.backends import make_renderer
from cerberus_core.train import train
from cerberus_core.train.settings import load_config
from tests.support.oracle import TinyViewDataset


# ------------------------------------------------------------------ datasets
def tiny_pairs_config(**overrides) -> GenerationConfig:
    """Pairs layout (Human protocol) with 3 training shards and a test grid with canonical poses."""
    splits = {
        "train": SplitConfig("pairs", subjects=2, pairs=6, meshes=True),
        "test": SplitConfig("grid", subjects=1, poses=2, views=4, canonical=True),
    }
    base = {"dataset": "primitives", "preset": "test-pairs", "splits": splits, "image_size": 32, "shard_images": 8}
    base.update(overrides)
    return GenerationConfig(**base)


def tiny_grid_config(**overrides) -> GenerationConfig:
    """Grid layout (Animal protocol): shared azimuths, quadruplets from pose pairs x view pairs."""
    splits = {
        "train": SplitConfig("grid", subjects=2, poses=3, views=3, azimuths="shared", quadruplets_per_pose=2),
        "test": SplitConfig("grid", subjects=1, poses=2, views=2),
    }
    base = {"dataset": "primitives", "preset": "test-grid", "splits": splits, "image_size": 32, "shard_images": 64}
    base.update(overrides)
    return GenerationConfig(**base)


@pytest.fixture(scope="session")
def pairs_dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("pairs") / "ds"
    Dataset.generate(tiny_pairs_config(), out, progress=False, log=lambda s: None)
    return out


@pytest.fixture(scope="session")
def grid_dataset(tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("grid") / "ds"
    Dataset.generate(tiny_grid_config(), out, progress=False, log=lambda s: None)
    return out


@pytest.fixture(scope="session")
def tiny_preset_config() -> GenerationConfig:
    return preset_config("primitives", "tiny", image_size=32)


@pytest.fixture(scope="session")
def pairs_config():
    """Factory of the pairs-layout test config (keyword overrides)."""
    return tiny_pairs_config


@pytest.fixture(scope="session")
def grid_config():
    """Factory of the grid-layout test config (keyword overrides)."""
    return tiny_grid_config


# ------------------------------------------------------------------ training
@pytest.fixture(scope="session")
def tiny_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("data") / "primitives_tiny"
    Dataset.generate(preset_config("primitives", "tiny", image_size=32), root, progress=False, log=lambda _: None)
    return root


@pytest.fixture
def tiny_config(tiny_root):
    """``tiny_config(key=value, ...)`` → the ``tiny`` preset on the tiny dataset, with ``--set`` style overrides."""
    def make(*overrides: str):
        return load_config(preset="tiny", overrides=[f"data.root={tiny_root}", "train.tensorboard=false",
                                                     *overrides])
    return make


@pytest.fixture
def one_thread():
    """One intra-op thread: small tensors gain nothing from more, and on a shared machine an
    oversubscribed OpenMP pool can be tens of times slower. Restored after each test."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


@pytest.fixture(scope="session")
def tiny_run(tiny_root, tmp_path_factory):
    """A run of the ``tiny`` preset trained 2 steps on the tiny dataset (one thread), for ``Run`` and ``cerberus eval``."""
    config = load_config(preset="tiny", overrides=[f"data.root={tiny_root}", "train.tensorboard=false",
                                                    "train.steps=2", "train.progress=false"])
    run = tmp_path_factory.mktemp("run") / "run"
    threads = torch.get_num_threads()
    torch.set_num_threads(1)
    try:
        train(config, run)
    finally:
        torch.set_num_threads(threads)
    return run


# ------------------------------------------------------------------ evaluation
@pytest.fixture(scope="session")
def iou_scorer():
    """The ``voxel_iou_scorer`` factory through its entry point, or a skip while cerberus-metrics is absent."""
    try:
        return get_metric("voxel_iou_scorer")
    except PluginError as exc:
        pytest.skip(f"the voxel_iou metric is not installed (pip install cerberus-metrics): {exc}")


@pytest.fixture(scope="session")
def renderer():
    return make_renderer("torch")


@pytest.fixture(scope="session")
def primitive_bodies():
    source = PrimitiveBodySource()
    subjects = sample_subjects(2, seed=1, split="test")
    return [b for s in subjects for b in source.posed_bodies(s, [0, 1, 2])]


@pytest.fixture(scope="session")
def tiny_dataset(renderer):
    return TinyViewDataset(renderer)


# ------------------------------------------------------------------ the shipped model
@pytest.fixture(scope="module")
def human_run():
    """The shipped ``human`` run (``Run.load("human")``)."""
    from cerberus_core import Run

    return Run.load("human")
