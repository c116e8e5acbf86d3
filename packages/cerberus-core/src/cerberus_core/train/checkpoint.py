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
import os
import random
import re
import stat
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import yaml
from safetensors import safe_open
from safetensors.torch import load_file, save

from cerberus_core.atomic import atomic_write
from cerberus_core.datasets.format import MANIFEST, Manifest
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.errors import CerberusError, ConfigError
from cerberus_core.model.cerberus import Cerberus
from cerberus_core.names import printable
from cerberus_core.train.config import TrainConfig
from cerberus_core.zoo import available, model_path

FORMAT_VERSION = 1
LAST = "last.pt"
_USE = "point at a run folder, its model.safetensors or checkpoints/last.pt"


class CheckpointError(CerberusError, ValueError):
    """A model file or run folder cannot be loaded; the message names the file and what to pass instead."""


def _reason(exc: BaseException) -> str:
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
        raise CheckpointError(f"no checkpoint at {path}; {_USE}")
    try:
        payload = torch.load(path, map_location=map_location, weights_only=True)
    except Exception as exc:
        raise CheckpointError(f"{path} is not a readable Cerberus checkpoint ({_reason(exc)}); it may be "
                              f"truncated or another kind of file: {_USE}") from None
    if not isinstance(payload, dict) or payload.get("format_version") != FORMAT_VERSION:
        raise CheckpointError(f"{path} is not a Cerberus checkpoint of format {FORMAT_VERSION}; {_USE}")
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


def load_model(path: str | Path, device: str | torch.device = "cpu") -> tuple[Cerberus, TrainConfig]:
    """Build a trained model for evaluation.

    Args:
        path: a run folder (uses ``model.safetensors``, else ``checkpoints/last.pt``), a
            ``.safetensors`` export, a ``.pt`` checkpoint, or the name of a shipped pretrained model
            (``cerberus models`` lists them; see :func:`resolve_weights` for how names and paths differ).
        device: where to put the model.
    Returns:
        ``(model, config)`` with the model in eval mode.
    """
    model, config, _ = load_run(path, device)
    return model, config


#: File endings of model files: a name ending so is a path, never a shipped model's name.
WEIGHT_SUFFIXES = (".safetensors", ".pt")


def looks_like_path(text: str | Path) -> bool:
    """Whether a model argument is a path rather than a shipped model's name: a :class:`~pathlib.Path`,
    or text with a folder separator, starting with ``.`` or ``~`` (``./human``), or ending in
    ``.safetensors`` / ``.pt``."""
    if isinstance(text, Path):
        return True
    seps = {"/", os.sep, *([os.altsep] if os.altsep else [])}
    return any(sep in text for sep in seps) or text.startswith((".", "~")) or text.endswith(WEIGHT_SUFFIXES)


def resolve_weights(path: str | Path) -> Path:
    """The model file that a model argument names.

    A bare name (see :func:`looks_like_path`) that a shipped model has is that model's checksum-verified
    weights, even where a local folder has the same name (a warning says how to name the folder:
    ``./human``); another bare name is taken as a path. A run folder gives its ``model.safetensors``,
    else ``checkpoints/last.pt``.

    Raises:
        CheckpointError: a missing path, a folder that is not a run (a dataset folder says so), a FIFO,
            device or other non-regular file (refused before it is opened, so nothing hangs).
        ZooError: a shipped model's file is missing or damaged.
    """
    if not looks_like_path(path):
        name = str(path)
        local = _exists(Path(name))
        if name in available():
            if local:
                warnings.warn(f"{name!r} is the shipped model {name!r}, not the local {printable(name)}: write "
                              f"./{printable(name)} for that path", UserWarning, stacklevel=3)
            return model_path(name)  # its checksum-verified weights
        if not local:
            model_path(name)  # ZooError: no such shipped model, listing the shipped ones
    path = Path(path).expanduser()
    shown = printable(path)
    try:
        path.stat()
    except FileNotFoundError:
        raise CheckpointError(f"{shown} does not exist; {_USE}") from None
    except OSError as exc:  # a name too long, a loop of symlinks, no permission
        raise CheckpointError(f"{shown[:80]}{'...' if len(shown) > 80 else ''}: cannot be read "
                              f"({exc.strerror or exc}); {_USE}") from None
    if path.is_dir():
        for candidate in (path / "model.safetensors", checkpoint_dir(path) / LAST):
            if candidate.is_file():
                return candidate
        if (path / "manifest.json").is_file():
            raise CheckpointError(f"{shown} is a dataset folder, not a training run; pass the run folder "
                                  f"first and the dataset with --data {shown}")
        raise CheckpointError(f"{shown} holds neither model.safetensors nor checkpoints/{LAST}, so it is not a "
                              "training run folder; train one with `cerberus train --out RUN`")
    if not path.is_file():
        raise CheckpointError(f"{shown} is {_file_kind(path)}, not a model file; {_USE}")
    return path


def _exists(path: Path) -> bool:
    """``path.exists()``, ``False`` where the name cannot even be looked up (too long, say)."""
    try:
        return path.exists()
    except OSError:
        return False


def _file_kind(path: Path) -> str:
    """``a FIFO``, ``a character device``, ... for a path that exists but is not a regular file or folder."""
    mode = path.stat().st_mode
    for test, kind in ((stat.S_ISFIFO, "a FIFO (named pipe)"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return kind
    return "not a regular file"


def _step_of(path: Path) -> int | None:
    """The training step a model file records (``None`` where it records none)."""
    if path.suffix == ".safetensors":
        from safetensors import safe_open

        try:
            with safe_open(str(path), framework="pt") as f:
                step = (f.metadata() or {}).get("step")
        except Exception:  # noqa: BLE001 - load_run reports a damaged file properly
            return None
    else:
        step = load_checkpoint(path).get("step")
    try:
        return int(step) if step is not None else None
    except (TypeError, ValueError):
        return None


@dataclass(frozen=True)
class WeightsInfo:
    """Which weights a model argument loads, and whether newer ones exist.

    Attributes:
        path: the model file (``RUN/model.safetensors``, a checkpoint, a shipped model's file).
        step: the training step it records (``None``: none recorded).
        newer: ``RUN/checkpoints/last.pt`` when it is further trained than ``path`` (an interrupted or
            unfinished ``--resume``: ``model.safetensors`` is written only when a training finishes).
        newer_step: that checkpoint's step.
    """

    path: Path
    step: int | None
    newer: Path | None = None
    newer_step: int | None = None

    def stale_warning(self) -> str | None:
        """One line saying the weights are older than the run's latest checkpoint, with the fix."""
        if self.newer is None:
            return None
        run = printable(self.path.parent)
        return (f"{printable(self.path)} holds step {self.step} but {printable(self.newer)} is at step "
                f"{self.newer_step} (a training resumed and not finished?); scoring step {self.step}: pass "
                f"{printable(self.newer)} to score the newer weights, or finish the run with "
                f"`cerberus train --out {run} --resume`")


def describe_weights(path: str | Path) -> WeightsInfo:
    """:func:`resolve_weights` with the step the weights record and the run's newer checkpoint, if any."""
    file = resolve_weights(path)
    step = _step_of(file)
    last = checkpoint_dir(file.parent) / LAST
    if file.name == "model.safetensors" and last.is_file():
        try:
            last_step = _step_of(last)
        except CheckpointError:
            last_step = None  # an unreadable checkpoint is not newer weights
        if last_step is not None and (step is None or last_step > step):
            return WeightsInfo(file, step, last, last_step)
    return WeightsInfo(file, step)


def load_run(path: str | Path, device: str | torch.device = "cpu") -> tuple[Cerberus, TrainConfig, dict | None]:
    """:func:`load_model`, plus the training data's scene set-up when the file records it (else ``None``).

    Raises:
        CheckpointError: a missing path, a folder that is not a run (a dataset folder says so), a
            truncated, foreign or pickled file, weights that do not fit the saved config, weights that
            are NaN or infinite, or a scene record that is not JSON.
    """
    path = resolve_weights(path)
    shown = printable(path)
    scene = None
    if path.suffix == ".safetensors":
        try:
            with safe_open(str(path), framework="pt") as f:
                meta = f.metadata() or {}
            state = load_file(str(path))
        except Exception as exc:
            raise CheckpointError(f"{shown} is not a readable safetensors file ({_reason(exc)}); it may be "
                                  f"truncated: {_USE}") from None
        if "config" not in meta:
            raise CheckpointError(f"{shown} has no Cerberus config in its metadata; export it with export_weights")
        config_yaml = meta["config"]
        scene = meta.get("scene")
    else:
        payload = load_checkpoint(path)
        config_yaml, state = payload["config"], payload["model"]
        scene = payload.get("extra", {}).get("scene")
    if isinstance(scene, str):
        try:
            scene = json.loads(scene)
        except ValueError as exc:
            raise CheckpointError(f"{shown}: its recorded scene set-up is not JSON ({exc}); the file is damaged: "
                                  "re-export it, or use the run's checkpoints/last.pt") from None
    if scene is not None and not isinstance(scene, dict):
        raise CheckpointError(f"{shown}: its recorded scene set-up is not a mapping ({type(scene).__name__}); the "
                              "file is damaged: re-export it, or use the run's checkpoints/last.pt")
    bad = [k for k, v in state.items() if torch.is_tensor(v) and v.is_floating_point() and not torch.isfinite(v).all()]
    if bad:
        raise CheckpointError(f"{shown}: {len(bad)} of {len(state)} weight tensors hold NaN or infinite values (first: "
                              f"{bad[0]}); the training diverged: use an earlier checkpoint "
                              "(RUN/checkpoints/step_*.pt) or retrain with a lower optim.lr")
    try:
        config = TrainConfig.from_dict(yaml.safe_load(config_yaml))
        model = Cerberus(config.model)
        model.load_state_dict(state)
    except (ValueError, TypeError, KeyError, RuntimeError, yaml.YAMLError) as exc:
        raise CheckpointError(f"{shown}: the saved config and weights do not form a Cerberus model "
                              f"({_reason(exc)}); it was written by another version or is damaged") from None
    return model.to(device).eval(), config, scene


def model_scene(config: TrainConfig, data: str | Path | None = None, saved: dict | None = None):
    """The scene set-up the model was trained with: from ``--data`` (which must be a dataset), else the
    one the run recorded, else from the run's training data if it is still there. Never a silent
    default: without any of them the user is asked for ``--data``.

    Args:
        config: the run's config (from :func:`load_run`).
        data: a dataset folder whose scene the images follow.
        saved: the scene :func:`load_run` returned with the weights.
    Returns:
        A :class:`~cerberus_core.datasets.scene.SceneSetup`.
    """
    def scene_of(record, where: str, fix: str = "pass --data DATASET (the dataset it was trained on)"):
        try:
            return SceneSetup.from_dict(record)
        except (ValueError, TypeError, AttributeError, KeyError) as exc:  # ConfigError is a ValueError
            raise ConfigError(f"{where}: invalid scene set-up ({exc}); {fix}") from None

    if data is not None:
        if not (Path(data) / MANIFEST).is_file():
            raise ConfigError(f"--data {data}: not a Cerberus dataset folder (no {MANIFEST})")
        return scene_of(Manifest.read(Path(data)).get("scene"), f"--data {data}",
                        "its manifest is damaged: regenerate it with `cerberus data generate`")
    if saved is not None:
        return scene_of(saved, "the model's recorded scene")
    root = Path(config.data.root)
    if (root / MANIFEST).is_file():
        return scene_of(Manifest.read(root).get("scene"), f"the run's training data {root}")
    raise ConfigError(f"the run does not record its scene set-up and its training data {root} is not here; pass "
                      "--data DATASET (the dataset it was trained on, or one rendered the same way)")
