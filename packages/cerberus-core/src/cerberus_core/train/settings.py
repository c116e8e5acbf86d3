"""Training settings (:class:`TrainConfig` and its sections): one YAML file with data, model, renderer, losses,
optimiser, schedule, device.

A config file holds any subset of the sections below; missing keys take the defaults (which are the
paper's settings). ``extends: NAME`` (a bundled preset) or ``extends: path/to/other.yaml`` (relative
to the file) loads that config first and applies this file on top; ``extends: [cpu, nmrr]`` merges
several, left to right, each shared ancestor once (the CPU schedule with the NMRr changes). ``--set section.key=value``
overrides apply last; values are parsed as YAML (``--set optim.lr=1e-4``,
``--set losses.pose_consistency=false``, ``--set optim.betas=[0.9,0.99]``).

Bundled presets (``cerberus_core/configs/*.yaml``, listed by :func:`preset_names`): ``paper``,
``cpu``, ``free_cerberus``, ``nmrr``, ``tiny``. See ``docs/training.md``. Files, ``extends``,
``--set`` and the typed validation are the toolkit's one config mechanism, :mod:`cerberus_core.config`
(dataset presets use it too).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Literal

import yaml

from cerberus_core.config import Presets, build, deep_merge, flatten, load_raw, load_yaml, parse_overrides, upgrade
from cerberus_core.datasets.looks import InputLook
from cerberus_core.devices import is_device_name
from cerberus_core.errors import ConfigError
from cerberus_core.fields import Checked, Range, ranged
from cerberus_core.model.cerberus import ModelConfig
from cerberus_core.plumbing.machine import MAX_WORKERS
from cerberus_core.train.objective import LossConfig
from cerberus_core.train.speed import SpeedConfig

__all__ = ["DataConfig", "DebugConfig", "LoopConfig", "OptimConfig", "RenderConfig", "TrainConfig", "config_diff",
           "default_preset", "load_config", "preset_names", "resume_config"]


MAX_IMAGE_SIZE = 4096
"""The largest training resolution (the training's memory is checked too: :meth:`TrainConfig.check_memory`)."""

@dataclass
class DataConfig(Checked):
    """Attributes:
        root: dataset folder (read by ``cerberus_core.datasets.readers.QuadrupletDataset``).
        split: the split to train on.
        image_size: train at this resolution (images are resized, antialiased); ``null``: the
            dataset's own size.
        num_workers: DataLoader worker processes (0: load in the training process); more than the
            machine's cores are lowered to them, with a warning, when the training starts.
        input_look: what the network is shown of each image (:mod:`cerberus_core.datasets.looks`):
            ``shaded`` (the stored render), ``flat`` (the body's mask filled with its mean grey) or
            ``random`` (an albedo colour, a texture and a light balance drawn per image). The losses
            compare against the stored shaded render whatever the look.
    """

    SECTION = "data"

    root: str = "data/human"
    split: str = "train"
    image_size: int | None = ranged(None, ge=32, le=MAX_IMAGE_SIZE, integer=True)
    num_workers: int = ranged(0, ge=0, le=MAX_WORKERS)
    input_look: InputLook = "shaded"


@dataclass
class OptimConfig(Checked):
    """Adam and its learning-rate schedule.

    Attributes:
        lr: peak learning rate (paper: 0.0005).
        betas, eps, weight_decay: Adam's.
        grad_clip: clip the global gradient norm to this (``null``: no clipping).
        schedule: ``constant`` (paper) or ``cosine`` (decays to ``min_lr_ratio * lr`` at the end).
        warmup_steps: linear warm-up from 0 over this many steps.
        min_lr_ratio: final learning rate of the cosine schedule, relative to ``lr``.
    """

    SECTION = "optim"

    lr: float = ranged(0.0005, gt=0)
    betas: list[float] = field(default_factory=lambda: [0.9, 0.999])
    eps: float = ranged(1e-8, gt=0)
    weight_decay: float = ranged(0.0, ge=0)
    grad_clip: float | None = ranged(None, gt=0, integer=False)
    schedule: Literal["constant", "cosine"] = "constant"
    warmup_steps: int = ranged(0, ge=0)
    min_lr_ratio: float = ranged(0.0, ge=0, le=1)

    def validate(self) -> None:
        if len(self.betas) != 2 or not all(Range(ge=0, lt=1).admits(b) for b in self.betas):
            raise ConfigError.about("optim.betas", self.betas, "must be two numbers in [0, 1), e.g. `optim.betas=[0.9,0.999]`")


@dataclass
class LoopConfig(Checked):
    """The training loop.

    Attributes:
        steps: optimisation steps (paper: 100,000).
        batch_size: quadruplets per step, summed over all data-parallel processes (paper: 16).
        checkpoint_every: write ``checkpoints/last.pt`` every this many steps (and at the end).
        keep_every: also keep a copy ``checkpoints/step_XXXXXXX.pt`` every this many steps (0: never).
        log_every: scalar logs (CSV, TensorBoard) every this many steps.
        image_every: PNG grid of inputs, reconstructions and parts every this many steps (0: never).
        allocation_every: the allocation diagnostics of ``cerberus eval`` (keypoint spread, segment to
            nearest keypoint, parts that add little alone) on a fixed batch of 16 test views of the
            training data, logged every this many steps (``metrics.csv``, TensorBoard; 0: never; skipped
            when the data has no test split).
        on_nonfinite: ``stop`` (raise, keeping the last good checkpoint) or ``skip`` (drop the
            step's update) when the loss or the gradient is NaN or infinite.
        max_consecutive_skips: with ``skip``, stop after this many non-finite steps in a row.
        tensorboard: also write TensorBoard event files when ``tensorboard`` is importable.
        progress: show a progress bar.
    """

    SECTION = "train"

    steps: int = ranged(100_000, ge=1)
    batch_size: int = ranged(16, ge=1)
    checkpoint_every: int = ranged(1000, ge=1)
    keep_every: int = ranged(0, ge=0)
    log_every: int = ranged(10, ge=1)
    image_every: int = ranged(1000, ge=0)
    allocation_every: int = ranged(500, ge=0)
    on_nonfinite: Literal["stop", "skip"] = "stop"
    max_consecutive_skips: int = ranged(20, ge=1)
    tensorboard: bool = True
    progress: bool = True


@dataclass
class RenderConfig(Checked):
    """How training renders (the ``render:`` section).

    Attributes:
        antialias: blend across silhouette and occlusion edges with the analytic anti-aliasing op
            (:meth:`cerberus_core.render.interface.Renderer.antialias`, ``docs/antialias.md``), so
            the rendering is differentiable w.r.t. where edges lie: a part over the background can
            grow as well as shrink. Off: the paper's renderer (no visibility gradient).
    """

    SECTION = "render"

    antialias: bool = False


@dataclass
class DebugConfig(Checked):
    """Test hooks. ``poison_steps``: steps whose input images are replaced by NaN (to exercise the
    non-finite handling)."""

    SECTION = "debug"

    poison_steps: list[int] = field(default_factory=list)

    def validate(self) -> None:
        if any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in self.poison_steps):
            raise ConfigError.about("debug.poison_steps", self.poison_steps, "must be step numbers >= 0")


@dataclass
class TrainConfig(Checked):
    """The whole training configuration (see the module docstring).

    Attributes:
        seed: seeds model initialisation, data order and the pose-consistency draws.
        device: ``auto`` (CUDA if available, else CPU), ``cpu`` or ``cuda`` / ``cuda:N``.
        threads: CPU threads of each training process (``torch.set_num_threads``); ``null`` keeps
            PyTorch's default (all cores). On a machine shared with other jobs, 1 thread can be many
            times faster than an oversubscribed default.
        renderer: renderer backend by entry-point name (``torch``, ``warp``), or ``auto`` (Warp if it
            works, else torch; the run's saved config names the one used).
        speed: speed switches of the network (:mod:`cerberus_core.train.speed`), all off by default.
        render: how training renders (:class:`RenderConfig`).
    """

    seed: int = ranged(0, ge=0)
    device: str = "auto"
    threads: int | None = ranged(None, ge=1, integer=True)
    renderer: str = "auto"
    data: DataConfig = field(default_factory=DataConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    render: RenderConfig = field(default_factory=RenderConfig)
    losses: LossConfig = field(default_factory=LossConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    train: LoopConfig = field(default_factory=LoopConfig)
    debug: DebugConfig = field(default_factory=DebugConfig)
    speed: SpeedConfig = field(default_factory=SpeedConfig)

    def validate(self) -> None:
        """The checks between sections (each section checked its own ranges and choices when it was made:
        nothing is checked twice)."""
        if self.losses.silhouette > 0 and not self.render.antialias:
            raise ConfigError("losses.silhouette needs render.antialias: true (the paper's renderer gives the coverage "
                              "no gradient); add `render.antialias=true`, or `losses.silhouette=0`", key="losses.silhouette", value=self.losses.silhouette)
        if not is_device_name(self.device):
            raise ConfigError.about("device", self.device, "must be 'auto', 'cpu', 'cuda' or 'cuda:N', e.g. `device=cpu`")
        if self.losses.cross_view == "own" and self.losses.cross_view_warmup >= self.train.steps:
            raise ConfigError.about("losses.cross_view_warmup", self.losses.cross_view_warmup,
                                    f"must be less than train.steps ({self.train.steps}), or the own cross view never "
                                    "runs", f"`losses.cross_view_warmup={self.train.steps // 10}`")

    def check_memory(self, image_size: int, device: object = "cpu") -> None:
        """Refuse (:class:`ConfigError` naming the setting, the estimate and the limit) a training whose memory
        exceeds what ``device`` has, before anything is allocated.

        The estimate is a lower bound, counted from what every step must hold (float32, values and gradients):
        per input pixel of the quadruplets (``train.batch_size`` × 4 images of ``image_size``², px) its 3
        channels and the first convolution's ``model.width / 4`` channels; per part face of each rendering (2 per
        image) the 25 numbers of its triangle set-up; per weight (float32: its value, gradient and Adam's two
        moments) the ResNet's about ``1800 * model.width²`` (its 3x3 convolutions of up to ``8 * width``
        channels) and the shape head's ``model.shape_latent_dim * (8 * width + 3 * vertices * num_parts)``.

        Args:
            image_size: the training resolution (px; ``data.image_size`` or the dataset's).
        """
        from cerberus_core.plumbing.machine import check_memory

        m = self.model
        images = self.train.batch_size * 4
        part_faces = 20 * 4 ** m.sphere_level  # an icosphere's faces at its subdivision level
        pixels = images * image_size ** 2 * (3 + m.width / 4) * 4 * 2
        faces = images * 2 * m.num_parts * part_faces * 25 * 4 * 2
        trunk, head = 1800 * m.width ** 2, m.shape_latent_dim * (8 * m.width + 3 * (part_faces // 2 + 2) * m.num_parts)
        weights = (trunk + head) * 4 * 4
        if weights >= max(pixels, faces):
            key, value = ("model.width", m.width) if trunk >= head else ("model.shape_latent_dim", m.shape_latent_dim)
            check_memory(key, value, pixels + faces + weights, f"about {(trunk + head) / 1e6:,.0f} million weights, "
                         "each with its gradient and the optimizer's two moments", device)
        elif pixels >= faces:
            check_memory("data.image_size", image_size, pixels + faces + weights, f"{images} images of {image_size}x{image_size} "
                         f"pixels per step at train.batch_size = {self.train.batch_size}", device)
        else:
            check_memory("model.num_parts", m.num_parts, pixels + faces + weights, f"{2 * images} renderings of "
                         f"{m.num_parts} parts of {part_faces} faces per step", device)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrainConfig:
        return build(cls, d)  # constructing it checks it (fields.Checked)

    @classmethod
    def from_yaml(cls, text: str, source: object, overrides: Sequence[str] = ()) -> TrainConfig:
        """The config a run saved (its ``config.yaml``, a checkpoint's or a model file's ``config``), plus
        ``overrides`` (``section.key=value`` strings): the one reader of a saved config (resuming a run, loading
        weights).

        Args:
            source: the file it came from, named in messages.
        Raises:
            ConfigError: the text is not valid YAML (``SOURCE:LINE``), or holds a key or value this version does
                not take (a key an earlier version wrote under another name is read as its new one:
                :func:`cerberus_core.config.upgrade`).
        """
        raw = upgrade(cls, load_yaml(text, source, "the saved config is damaged"))
        return cls.from_dict(deep_merge(raw or {}, parse_overrides(overrides)) if overrides else raw)


# ------------------------------------------------------------------ presets, files, overrides
PRESETS = Presets("configs", kind="preset")
"""The bundled training recipes, ``cerberus_core/configs/*.yaml``."""


def preset_names() -> list[str]:
    """Names of the bundled presets."""
    return PRESETS.names()


def resume_config(run_dir: str | Path, overrides: list[str] | None = None) -> TrainConfig | None:
    """The config a resumed run continues with: the run's own saved ``config.yaml`` (or, where that file is gone,
    the config its last checkpoint holds) plus ``overrides`` (``section.key=value`` strings); ``None`` when the
    run folder holds neither.

    Raises:
        ConfigError: a damaged saved config, or a relative ``data.root`` (written by an older version)
            that does not exist from the current directory.
        CheckpointError: no ``config.yaml`` and a damaged last checkpoint.
    """
    saved = Path(run_dir) / "config.yaml"
    if saved.is_file():
        text = saved.read_text()
    elif (last := Path(run_dir) / "checkpoints" / "last.pt").is_file():  # a preset's defaults would be another run
        from cerberus_core.train.checkpoint import load_checkpoint

        saved, text = last, str(load_checkpoint(last)["config"])
    else:
        return None
    config = TrainConfig.from_yaml(text, saved, overrides or ())
    root = Path(config.data.root)
    if not root.is_absolute() and not root.exists():
        raise ConfigError(f"the run's data.root {str(root)!r} is relative (saved by an older version) and does not "
                          f"exist from {Path.cwd()}; set data.root to the dataset's absolute path", key="data.root", value=str(root))
    return config


def default_preset(device: str | None = None) -> tuple[str, str]:
    """The preset ``cerberus train`` uses when none is given, and why, for the device it will run on.

    ``paper`` (100,000 steps at batch 16) where training runs on a GPU (``device`` ``cuda...``, or
    ``auto``/``None`` with CUDA available), else ``cpu`` (the recipe every doc recommends on a CPU:
    about an hour on 2 cores). Returns ``(name, reason)``.
    """
    import torch

    wants_gpu = device is not None and str(device).startswith("cuda")
    if wants_gpu or (device in (None, "auto") and torch.cuda.is_available()):
        return "paper", "training runs on a GPU"
    return "cpu", "no GPU: the paper preset's 100,000 steps at batch 16 would take days on a CPU"


def load_config(path: str | Path | None = None, *, preset: str | list[str] | None = None,
                overrides: list[str] | None = None) -> TrainConfig:
    """Build a :class:`TrainConfig` from a YAML file or bundled preset(s), plus ``--set`` overrides.

    ``preset`` may be a list, merged left to right like ``extends: [a, b]`` (``["cpu", "nmrr"]``:
    the CPU schedule with the NMRr baseline's changes). With neither ``path`` nor ``preset`` the
    defaults (the paper's settings) are used. Errors are :class:`~cerberus_core.errors.ConfigError`.
    """
    return TrainConfig.from_dict(load_raw(PRESETS, path, preset=preset, overrides=overrides or ()))


def config_diff(a: TrainConfig, b: TrainConfig) -> list[str]:
    """Dotted keys whose values differ between two configs."""
    fa, fb = flatten(a.to_dict()), flatten(b.to_dict())
    return sorted(k for k in fa.keys() | fb.keys() if fa.get(k) != fb.get(k))
