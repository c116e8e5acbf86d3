"""Checkpoints: atomic writes, safe loads (``weights_only=True``), exact resumption, weight export.

Layout of a run folder::

    RUN/config.yaml                 the resolved training config
    RUN/checkpoints/last.pt         the latest checkpoint (replaced atomically)
    RUN/checkpoints/step_XXXXXXX.pt kept copies (``train.keep_every``)
    RUN/model.safetensors           final weights + config (written at the end of training)

A checkpoint is a plain dict of tensors, numbers and strings — model and optimiser state, the step,
every RNG state (Python, NumPy, torch CPU and CUDA) and the config as YAML — so it loads with
``torch.load(..., weights_only=True)``: no arbitrary pickles.
"""
from __future__ import annotations

import random
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch
from safetensors.torch import load_file, save

from cerberus_core.atomic import atomic_write
from cerberus_core.model.cerberus import Cerberus

if TYPE_CHECKING:
    from cerberus_core.train.config import TrainConfig

FORMAT_VERSION = 1
LAST = "last.pt"


def checkpoint_dir(run_dir: str | Path) -> Path:
    return Path(run_dir) / "checkpoints"


# ------------------------------------------------------------------ RNG state
def capture_rng() -> dict[str, Any]:
    """Every RNG state the training process uses, as tensors and plain numbers."""
    version, mt, gauss = random.getstate()
    np_kind, np_keys, np_pos, np_has_gauss, np_gauss = np.random.get_state()
    state: dict[str, Any] = {
        "python_version": version,
        "python_state": torch.tensor(mt, dtype=torch.int64),
        "python_gauss": gauss,
        "numpy_keys": torch.from_numpy(np_keys.astype(np.int64)),
        "numpy_pos": int(np_pos),
        "numpy_has_gauss": int(np_has_gauss),
        "numpy_gauss": float(np_gauss),
        "torch_cpu": torch.get_rng_state(),
    }
    if torch.cuda.is_available():
        state["torch_cuda"] = torch.cuda.get_rng_state_all()
    return state


def restore_rng(state: dict[str, Any]) -> None:
    """Inverse of :func:`capture_rng`."""
    random.setstate((state["python_version"], tuple(int(x) for x in state["python_state"].tolist()),
                     state["python_gauss"]))
    np.random.set_state(("MT19937", state["numpy_keys"].numpy().astype(np.uint32), state["numpy_pos"],
                         state["numpy_has_gauss"], state["numpy_gauss"]))
    torch.set_rng_state(state["torch_cpu"])
    if "torch_cuda" in state and torch.cuda.is_available():
        torch.cuda.set_rng_state_all(state["torch_cuda"])


# ------------------------------------------------------------------ save / load
def save_checkpoint(path: str | Path, *, model: torch.nn.Module, optimizer: torch.optim.Optimizer,
                    scheduler: Any, step: int, config_yaml: str, extra: dict[str, Any] | None = None) -> Path:
    """Write a resumable checkpoint atomically.

    Args:
        path: destination ``.pt`` file.
        model: the (unwrapped) model.
        optimizer, scheduler: their state dicts are saved.
        step: number of completed optimisation steps.
        config_yaml: the resolved config.
        extra: more plain values (counters) to keep.
    """
    payload = {
        "format_version": FORMAT_VERSION,
        "step": int(step),
        "model": model.state_dict(),
        "optimizer": optimizer.state_dict(),
        "scheduler": scheduler.state_dict() if scheduler is not None else {},
        "rng": capture_rng(),
        "config": config_yaml,
        "extra": dict(extra or {}),
    }
    path = Path(path)
    atomic_write(path, lambda fh: torch.save(payload, fh))
    return path


def load_checkpoint(path: str | Path, map_location: str | torch.device = "cpu") -> dict[str, Any]:
    """Load a checkpoint written by :func:`save_checkpoint` (safe: ``weights_only=True``)."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no checkpoint at {path}")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:
        raise ValueError(f"{path} is not a readable Cerberus checkpoint ({type(exc).__name__}: {exc})") from exc
    if not isinstance(payload, dict) or payload.get("format_version") != FORMAT_VERSION:
        raise ValueError(f"{path} is not a Cerberus checkpoint of format {FORMAT_VERSION}")
    return payload


def export_weights(model: Cerberus, path: str | Path, config_yaml: str, step: int) -> Path:
    """Write the model weights as safetensors, with the config and step in the metadata."""
    tensors = {k: v.detach().contiguous().cpu() for k, v in model.state_dict().items()}
    meta = {"config": config_yaml, "step": str(step), "format": "cerberus-model"}
    path = Path(path)
    atomic_write(path, lambda fh: fh.write(save(tensors, metadata=meta)))
    return path


def load_model(path: str | Path, device: str | torch.device = "cpu") -> tuple[Cerberus, TrainConfig]:
    """Build a trained model for evaluation.

    Args:
        path: a run folder (uses ``model.safetensors``, else ``checkpoints/last.pt``), a
            ``.safetensors`` export or a ``.pt`` checkpoint.
        device: where to put the model.
    Returns:
        ``(model, config)`` with the model in eval mode.
    """
    import yaml
    from safetensors import safe_open

    from cerberus_core.train.config import TrainConfig

    path = Path(path)
    if path.is_dir():
        for candidate in (path / "model.safetensors", checkpoint_dir(path) / LAST):
            if candidate.is_file():
                path = candidate
                break
        else:
            raise FileNotFoundError(f"{path} holds neither model.safetensors nor checkpoints/{LAST}; "
                                    "is it a training run folder?")
    if path.suffix == ".safetensors":
        with safe_open(str(path), framework="pt") as f:
            meta = f.metadata() or {}
        if "config" not in meta:
            raise ValueError(f"{path} has no Cerberus config in its metadata; export it with export_weights")
        config_yaml, state = meta["config"], load_file(str(path))
    else:
        payload = load_checkpoint(path)
        config_yaml, state = payload["config"], payload["model"]
    config = TrainConfig.from_dict(yaml.safe_load(config_yaml))
    model = Cerberus(config.model)
    model.load_state_dict(state)
    return model.to(device).eval(), config

