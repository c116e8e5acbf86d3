"""Shared fixtures of the training tests: a tiny on-disk dataset and the tiny training config.

The dataset is the toolkit's own format (``cerberus_core.datasets``) built from the ``primitives`` body
source (articulated capsule figures) at 32 pixels: 6 training quadruplets, made in a few seconds
with the real renderer.
"""
from __future__ import annotations

import pytest

from cerberus_core.datasets.generate import generate
from cerberus_core.datasets.plan import preset_config
from cerberus_core.train.config import load_config


@pytest.fixture(scope="session")
def tiny_root(tmp_path_factory):
    root = tmp_path_factory.mktemp("data") / "primitives_tiny"
    generate(preset_config("primitives", "tiny", image_size=32), root, progress=False, log=lambda _: None)
    return root


@pytest.fixture
def tiny_config(tiny_root):
    """``tiny_config(key=value, ...)`` → the ``tiny`` preset on the tiny dataset, with ``--set`` style overrides."""
    def make(*overrides: str):
        return load_config(preset="tiny", overrides=[f"data.root={tiny_root}", "train.tensorboard=false",
                                                     *overrides])
    return make


@pytest.fixture(autouse=True)
def _one_thread():
    """One intra-op thread: small tensors gain nothing from more, and on a shared machine an
    oversubscribed OpenMP pool can be tens of times slower. Restored after each test."""
    import torch

    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)
