"""The GPU path (``--device cuda``) of training, evaluation and reconstruction.

Without a GPU (every CI machine) the CUDA tests skip and the refusals are checked: ``--device cuda``
says in one line that CUDA is not available, before anything is written. With a GPU, a few steps of
the tiny preset train on CUDA with each installed renderer backend, and a run trained there is used
for reconstruction and (with cerberus-metrics installed) evaluated there; the renderer conformance
suite holds every backend to the same numbers on CUDA as on the CPU
(``cerberus_core/testing/test_devices.py``)."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
import torch

from cerberus_core.datasets.dataset import Dataset

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


def has(module: str) -> bool:
    import importlib.util

    return importlib.util.find_spec(module) is not None


def installed_renderers() -> list[str]:
    from cerberus_core.render.backends import available_renderers

    return available_renderers()


@pytest.fixture(scope="module")
def cuda_run(data: Path, tmp_path_factory) -> Path:
    """A few steps of the tiny preset trained on CUDA with the torch renderer."""
    run = tmp_path_factory.mktemp("cuda") / "run"
    res = cerberus("train", "--preset", "tiny", "--set", f"data.root={data}", "--set", "renderer=torch",
                   "--set", "speed.autocast=auto", "--device", "cuda", "--out", str(run), cwd=run.parent)
    assert res.returncode == 0, res.stderr
    return run


@CUDA
@pytest.mark.slow
@pytest.mark.parametrize("renderer", ["torch", "warp"])
def test_train_on_cuda(data: Path, tmp_path: Path, renderer: str) -> None:
    if renderer not in installed_renderers():
        pytest.skip(f"the {renderer} renderer backend is not installed")
    run = tmp_path / "run"
    res = cerberus("train", "--preset", "tiny", "--set", f"data.root={data}", "--set", f"renderer={renderer}",
                   "--set", "speed.autocast=auto", "--device", "cuda", "--out", str(run), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (run / "model.safetensors").is_file()
    assert "device: cuda" in (run / "config.yaml").read_text()


@CUDA
@pytest.mark.slow
def test_reconstruct_on_cuda(data: Path, cuda_run: Path, tmp_path: Path) -> None:
    from PIL import Image


    view = Dataset.open(data).views("test")[0]["images"]  # (3, H, W) in [0, 1]
    Image.fromarray((view.permute(1, 2, 0).numpy() * 255).round().astype("uint8")).save(tmp_path / "view.png")
    res = cerberus("reconstruct", str(cuda_run), str(tmp_path / "view.png"), "--device", "cuda", "--out",
                   str(tmp_path / "rec"), cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "rec").is_dir()


@CUDA
@pytest.mark.slow
def test_eval_on_cuda(cuda_run: Path, tmp_path: Path) -> None:
    if not has("pymeshlab"):
        pytest.skip("cerberus eval needs cerberus-metrics (pymeshlab)")
    res = cerberus("eval", str(cuda_run), "--device", "cuda", "--out", str(tmp_path / "eval"), "--no-part-quality",
                   cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert (tmp_path / "eval" / "results.json").is_file()
