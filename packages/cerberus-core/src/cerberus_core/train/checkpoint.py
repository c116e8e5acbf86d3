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

import json
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


def export_weights(model: Cerberus, path: str | Path, config_yaml: str, step: int,
                   scene: dict[str, Any] | None = None) -> Path:
    """Write the model weights as safetensors, with the config, the step and (``scene``) the scene
    set-up the model was trained with in the metadata, so the file alone can reconstruct images."""
    tensors = {k: v.detach().contiguous().cpu() for k, v in model.state_dict().items()}
    meta = {"config": config_yaml, "step": str(step), "format": "cerberus-model"}
    if scene is not None:
        meta["scene"] = json.dumps(scene, sort_keys=True)
    path = Path(path)
    atomic_write(path, lambda fh: fh.write(save(tensors, metadata=meta)))
    return path


def _resolve(path: str | Path) -> Path:
    """A run folder, weights file, or the name of a shipped model (:mod:`cerberus_core.zoo`) → the file."""
    p = Path(path)
    if not p.exists() and isinstance(path, str) and "/" not in path and not p.suffix:
        from cerberus_core.zoo import model_path

        return model_path(path)
    if p.is_dir():
        for candidate in (p / "model.safetensors", checkpoint_dir(p) / LAST):
            if candidate.is_file():
                return candidate
        raise FileNotFoundError(f"{p} holds neither model.safetensors nor checkpoints/{LAST}; "
                                "is it a training run folder?")
    return p


def load_model(path: str | Path, device: str | torch.device = "cpu") -> tuple[Cerberus, TrainConfig]:
    """Build a trained model for evaluation.

    Args:
        path: a run folder (uses ``model.safetensors``, else ``checkpoints/last.pt``), a
            ``.safetensors`` export, a ``.pt`` checkpoint, or the name of a shipped pretrained
            model (``"human"``, ``"animal"``: ``cerberus models`` lists them).
        device: where to put the model.
    Returns:
        ``(model, config)`` with the model in eval mode.
    """
    import yaml

    from cerberus_core.train.config import TrainConfig

    path = _resolve(path)
    if path.suffix == ".safetensors":
        config_yaml, state = _read_safetensors(path)
    else:
        payload = load_checkpoint(path)
        config_yaml, state = payload["config"], payload["model"]
    config = TrainConfig.from_dict(yaml.safe_load(config_yaml))
    model = Cerberus(config.model)
    model.load_state_dict(state)
    return model.to(device).eval(), config


def _metadata(path: Path) -> dict[str, str]:
    from safetensors import safe_open

    with safe_open(str(path), framework="pt") as f:
        return f.metadata() or {}


def _read_safetensors(path: Path) -> tuple[str, dict[str, torch.Tensor]]:
    meta = _metadata(path)
    if "config" not in meta:
        raise ValueError(f"{path} has no Cerberus config in its metadata; export it with export_weights")
    return meta["config"], load_file(str(path))


def model_scene(path: str | Path, config: TrainConfig, data: str | Path | None = None):
    """The scene set-up (camera elevation, distance, field of view, light, background) a model was
    trained with, as a :class:`~cerberus_core.datasets.scene.SceneSetup`.

    In order: the dataset ``data`` if given (its manifest); the scene stored with the weights
    (:func:`export_weights`); the run's training dataset if it is still there. Raises
    ``FileNotFoundError`` when none is available rather than guessing a scene the model never saw.
    ``path`` as in :func:`load_model`.
    """
    from cerberus_core.datasets.format import MANIFEST, read_manifest
    from cerberus_core.datasets.scene import SceneSetup

    if data is not None:
        return SceneSetup.from_dict(read_manifest(Path(data))["scene"])
    weights = _resolve(path)
    if weights.suffix != ".safetensors" and weights.parent.name == "checkpoints":
        weights = weights.parent.parent / "model.safetensors"
    if weights.is_file() and weights.suffix == ".safetensors":
        meta = _metadata(weights)
        if "scene" in meta:
            return SceneSetup.from_dict(json.loads(meta["scene"]))
    root = Path(config.data.root)
    if (root / MANIFEST).is_file():
        return SceneSetup.from_dict(read_manifest(root)["scene"])
    raise FileNotFoundError(f"the scene set-up of {path} is unknown: its weights predate stored scenes and its "
                            f"training data {root} is gone; pass the dataset it was trained on with --data")
