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
import re
from pathlib import Path
from typing import Any

import numpy as np
import torch
from safetensors.torch import save

from cerberus_core.errors import CheckpointError
from cerberus_core.model.cerberus import Cerberus
from cerberus_core.plumbing.atomic import atomic_write

FORMAT_VERSION = 1
LAST = "last.pt"
USE_RUN = "point at a run folder, its model.safetensors or checkpoints/last.pt"
"""The fix a message about a wrong model path names."""


def error_reason(exc: BaseException) -> str:
    """A short, safe description of why torch / safetensors could not read a file (never torch's advice
    to retry with ``weights_only=False``, which would run arbitrary code from the file)."""
    text = str(exc)
    found = re.search(r"Unsupported global: GLOBAL (\S+)", text)
    if found:
        return (f"it holds a pickled Python object ({found.group(1)}), not only tensors; Cerberus loads only plain "
                "checkpoints, as arbitrary pickles can run code")
    if "Weights only load failed" in text:
        after = text.split("WeightsUnpickler error:", 1)[-1]
        detail = next((line.strip() for line in after.splitlines() if line.strip()), "unreadable")
        return f"not a torch checkpoint: {detail[:80]}"
    first = next((line.strip() for line in text.splitlines() if line.strip()), "")
    first = first.split(". ", 1)[0].rstrip(".")  # the first sentence
    return f"{type(exc).__name__}: {first[:120]}" if first else type(exc).__name__


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
        raise CheckpointError(f"no checkpoint at {path}; {USE_RUN}")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:
        raise CheckpointError(f"{path} is not a readable Cerberus checkpoint ({error_reason(exc)}); it may be "
                              f"truncated or another kind of file: {USE_RUN}") from None
    if not isinstance(payload, dict) or payload.get("format_version") != FORMAT_VERSION:
        raise CheckpointError(f"{path} is not a Cerberus checkpoint of format {FORMAT_VERSION}; {USE_RUN}")
    return payload


def export_weights(model: Cerberus, path: str | Path, config_yaml: str, step: int,
                   scene: dict[str, Any] | None = None) -> Path:
    """Write the model weights as safetensors, with the config, step and (optionally) the training
    data's scene set-up (:class:`~cerberus_core.datasets.scene.SceneSetup` as a dict) in the metadata."""
    tensors = {k: v.detach().contiguous().cpu() for k, v in model.state_dict().items()}
    meta = {"config": config_yaml, "step": str(step), "format": "cerberus-model"}
    if scene is not None:
        meta["scene"] = json.dumps(scene)
    path = Path(path)
    atomic_write(path, lambda fh: fh.write(save(tensors, metadata=meta)))
    return path
