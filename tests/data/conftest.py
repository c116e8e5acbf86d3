"""Fixtures of the dataset-pipeline tests: small datasets of capsule figures (the ``primitives``
source), generated with the real renderer into temporary folders."""
from __future__ import annotations

from pathlib import Path

import pytest

from cerberus_core.datasets.plan import GenerationConfig, SplitConfig, preset_config


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
    from cerberus_core.datasets.generate import generate

    out = tmp_path_factory.mktemp("pairs") / "ds"
    generate(tiny_pairs_config(), out, progress=False, log=lambda s: None)
    return out


@pytest.fixture(scope="session")
def grid_dataset(tmp_path_factory) -> Path:
    from cerberus_core.datasets.generate import generate

    out = tmp_path_factory.mktemp("grid") / "ds"
    generate(tiny_grid_config(), out, progress=False, log=lambda s: None)
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
