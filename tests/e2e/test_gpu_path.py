"""The GPU path (``--device cuda``) of training, evaluation and reconstruction.

Without a GPU (every CI machine) the CUDA tests skip and the refusals are checked: ``--device cuda``
says in one line that CUDA is not available, before anything is written. With a GPU, a few steps of
the tiny preset train on CUDA with each renderer backend, and the trained run is evaluated and used
for reconstruction there; the CPU suite already holds the Warp and torch renderers to the same
numbers on CUDA as on the CPU (tests/warp)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import torch

CUDA = pytest.mark.skipif(not torch.cuda.is_available(), reason="needs a CUDA device")
NO_CUDA = pytest.mark.skipif(torch.cuda.is_available(), reason="CUDA is available here")


def cerberus(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "cerberus_core.cli", *args], capture_output=True, text=True,
                          cwd=cwd, timeout=900)


@pytest.fixture(scope="module")
def data(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("gpu") / "data"
    res = cerberus("data", "generate", "--dataset", "primitives", "--size", "tiny", "--out", str(root), "--quiet",
                   cwd=root.parent)
    assert res.returncode == 0, res.stderr
    return root


@NO_CUDA
def test_train_device_cuda_is_refused_in_one_line_without_a_gpu(data: Path, tmp_path: Path) -> None:
    res = cerberus("train", "--preset", "tiny", "--set", f"data.root={data}", "--device", "cuda",
                   "--out", str(tmp_path / "run"), cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [
        "cerberus train: --device cuda: CUDA is not available on this machine; use --device cpu"]
    assert not (tmp_path / "run").exists()


def test_train_device_is_the_config_key(tmp_path: Path) -> None:
    res = cerberus("train", "--preset", "tiny", "--device", "cpu", "--print-config", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert "device: cpu" in res.stdout.splitlines()


@CUDA
@pytest.mark.slow
@pytest.mark.parametrize("renderer", ["torch", "warp"])
def test_train_eval_and_reconstruct_on_cuda(data: Path, tmp_path: Path, renderer: str) -> None:
    run = tmp_path / "run"
    res = cerberus("train", "--preset", "tiny", "--set", f"data.root={data}", "--set", f"renderer={renderer}",
                   "--set", "speed.autocast=auto", "--device", "cuda", "--out", str(run), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (run / "model.safetensors").is_file()
    assert "device: cuda" in (run / "config.yaml").read_text()
    res = cerberus("eval", str(run), "--device", "cuda", "--out", str(tmp_path / "eval"), "--no-part-quality",
                   cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "eval" / "results.json").is_file()
    from PIL import Image

    from cerberus_core.datasets.readers import ViewDataset

    view = ViewDataset(data, "test")[0]["images"]  # (3, H, W) in [0, 1]
    Image.fromarray((view.permute(1, 2, 0).numpy() * 255).round().astype("uint8")).save(tmp_path / "view.png")
    res = cerberus("reconstruct", str(run), str(tmp_path / "view.png"), "--device", "cuda", "--out",
                   str(tmp_path / "rec"), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
