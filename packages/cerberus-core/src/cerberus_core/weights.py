"""Which weights a model argument names, and loading them: shipped models by name (:mod:`cerberus_core.zoo`,
checksum-verified), run folders, ``model.safetensors`` exports and ``.pt`` checkpoints, each refused with the fix
when it is not a model file; the step a file records and a run's newer checkpoint (:class:`WeightsInfo`).

:meth:`cerberus_core.run.Run.load` is the way in; this module is what it does before it holds a run::

    >>> from cerberus_core.weights import looks_like_path
    >>> looks_like_path("human"), looks_like_path("./human"), looks_like_path("runs/a/model.safetensors")
    (False, True, True)
"""
from __future__ import annotations

import os
import stat
import warnings
from dataclasses import dataclass
from pathlib import Path

import torch
from safetensors import safe_open
from safetensors.torch import load_file

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.errors import CheckpointError
from cerberus_core.model.cerberus import Cerberus
from cerberus_core.plumbing import jsontext
from cerberus_core.plumbing.names import printable
from cerberus_core.train.checkpoint import LAST, USE_RUN, checkpoint_dir, error_reason, load_checkpoint
from cerberus_core.train.settings import TrainConfig
from cerberus_core.zoo import available, model_path

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
        raise CheckpointError(f"{shown} does not exist; {USE_RUN}") from None
    except OSError as exc:  # a name too long, a loop of symlinks, no permission
        raise CheckpointError(f"{shown[:80]}{'...' if len(shown) > 80 else ''}: cannot be read "
                              f"({exc.strerror or exc}); {USE_RUN}") from None
    if path.is_dir():
        for candidate in (path / "model.safetensors", checkpoint_dir(path) / LAST):
            if candidate.is_file():
                return candidate
        if Dataset.is_dataset(path):
            raise CheckpointError(f"{shown} is a dataset folder, not a training run; pass the run folder "
                                  f"first and the dataset as `data={shown}`")
        raise CheckpointError(f"{shown} holds neither model.safetensors nor checkpoints/{LAST}, so it is not a "
                              "training run folder; train one first (`cerberus train`)")
    if not path.is_file():
        raise CheckpointError(f"{shown} is {_file_kind(path)}, not a model file; {USE_RUN}")
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
        try:
            with safe_open(str(path), framework="pt") as f:
                step = (f.metadata() or {}).get("step")
        except Exception:  # noqa: BLE001 - load_weights reports a damaged file properly
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
                f"{printable(self.newer)} to score the newer weights, or finish the run by resuming its training "
                f"in {run}")


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


@dataclass(frozen=True)
class LoadedWeights:
    """What a model file holds, loaded (:func:`load_weights`; :meth:`cerberus_core.run.Run.load` keeps it).

    Attributes:
        model: the :class:`~cerberus_core.model.Cerberus` model, in eval mode.
        config: its :class:`~cerberus_core.train.settings.TrainConfig`, read from the file.
        scene: the training data's scene set-up as the file records it (a :meth:`SceneSetup.to_dict
            <cerberus_core.datasets.scene.SceneSetup.to_dict>` mapping; ``None``: none recorded).
    """

    model: Cerberus
    config: TrainConfig
    scene: dict | None


def load_weights(path: str | Path, device: str | torch.device = "cpu") -> LoadedWeights:
    """The model (in eval mode on ``device``), its config and the training data's scene set-up when the file
    records it (else ``None``), from what :func:`resolve_weights` names: the loading behind
    :meth:`Run.load <cerberus_core.run.Run.load>`, which is the way in.

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
            raise CheckpointError(f"{shown} is not a readable safetensors file ({error_reason(exc)}); it may be "
                                  f"truncated: {USE_RUN}") from None
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
            scene = jsontext.loads(scene)
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
        config = TrainConfig.from_yaml(config_yaml, shown)
        model = Cerberus(config.model)
        model.load_state_dict(state)
    except (ValueError, TypeError, KeyError, RuntimeError) as exc:
        raise CheckpointError(f"{shown}: the saved config and weights do not form a Cerberus model "
                              f"({error_reason(exc)}); it was written by another version or is damaged") from None
    return LoadedWeights(model.to(device).eval(), config, scene)


__all__ = ["WEIGHT_SUFFIXES", "LoadedWeights", "WeightsInfo", "describe_weights", "load_weights", "looks_like_path",
           "resolve_weights"]
