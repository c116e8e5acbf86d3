"""Training configuration: one YAML file with data, model, renderer, losses, optimiser, schedule, device.

A config file holds any subset of the sections below; missing keys take the defaults (which are the
paper's settings). ``extends: NAME`` (a bundled preset) or ``extends: path/to/other.yaml`` (relative
to the file) loads that config first and applies this file on top; ``extends: [cpu, nmrr]`` merges
several, left to right, each shared ancestor once (the CPU schedule with the NMRr changes). ``--set section.key=value``
overrides apply last; values are parsed as YAML (``--set optim.lr=1e-4``,
``--set losses.pose_consistency=false``, ``--set optim.betas=[0.9,0.99]``).

Bundled presets (``cerberus_core/configs/*.yaml``, listed by :func:`preset_names`): ``paper``,
``cpu``, ``free_cerberus``, ``nmrr``, ``tiny``. See ``docs/training.md``.
"""
from __future__ import annotations

import types
import typing
from dataclasses import asdict, dataclass, field, fields, is_dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from cerberus_core.losses import LossConfig
from cerberus_core.model.cerberus import ModelConfig
from cerberus_core.train.speed import SpeedConfig


@dataclass
class DataConfig:
    """Attributes:
        root: dataset folder (read by ``cerberus_core.data.dataset.QuadrupletDataset``).
        split: the split to train on.
        image_size: train at this resolution (images are resized, antialiased); ``null``: the
            dataset's own size.
        num_workers: DataLoader worker processes (0: load in the training process).
    """

    root: str = "data/human"
    split: str = "train"
    image_size: int | None = None
    num_workers: int = 0


@dataclass
class OptimConfig:
    """Adam and its learning-rate schedule.

    Attributes:
        lr: peak learning rate (paper: 0.0005).
        betas, eps, weight_decay: Adam's.
        grad_clip: clip the global gradient norm to this (``null``: no clipping).
        schedule: ``constant`` (paper) or ``cosine`` (decays to ``min_lr_ratio * lr`` at the end).
        warmup_steps: linear warm-up from 0 over this many steps.
        min_lr_ratio: final learning rate of the cosine schedule, relative to ``lr``.
    """

    lr: float = 0.0005
    betas: list[float] = field(default_factory=lambda: [0.9, 0.999])
    eps: float = 1e-8
    weight_decay: float = 0.0
    grad_clip: float | None = None
    schedule: str = "constant"
    warmup_steps: int = 0
    min_lr_ratio: float = 0.0


@dataclass
class LoopConfig:
    """The training loop.

    Attributes:
        steps: optimisation steps (paper: 100,000).
        batch_size: quadruplets per step, summed over all data-parallel processes (paper: 16).
        checkpoint_every: write ``checkpoints/last.pt`` every this many steps (and at the end).
        keep_every: also keep a copy ``checkpoints/step_XXXXXXX.pt`` every this many steps (0: never).
        log_every: scalar logs (CSV, TensorBoard) every this many steps.
        image_every: PNG grid of inputs, reconstructions and parts every this many steps (0: never).
        on_nonfinite: ``stop`` (raise, keeping the last good checkpoint) or ``skip`` (drop the
            step's update) when the loss or the gradient is NaN or infinite.
        max_consecutive_skips: with ``skip``, stop after this many non-finite steps in a row.
        tensorboard: also write TensorBoard event files when ``tensorboard`` is importable.
        progress: show a progress bar.
    """

    steps: int = 100_000
    batch_size: int = 16
    checkpoint_every: int = 1000
    keep_every: int = 0
    log_every: int = 10
    image_every: int = 1000
    on_nonfinite: str = "stop"
    max_consecutive_skips: int = 20
    tensorboard: bool = True
    progress: bool = True


@dataclass
class DebugConfig:
    """Test hooks. ``poison_steps``: steps whose input images are replaced by NaN (to exercise the
    non-finite handling)."""

    poison_steps: list[int] = field(default_factory=list)


@dataclass
class TrainConfig:
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
    """

    seed: int = 0
    device: str = "auto"
    threads: int | None = None
    renderer: str = "auto"
    data: DataConfig = field(default_factory=DataConfig)
    model: ModelConfig = field(default_factory=ModelConfig)
    losses: LossConfig = field(default_factory=LossConfig)
    optim: OptimConfig = field(default_factory=OptimConfig)
    train: LoopConfig = field(default_factory=LoopConfig)
    debug: DebugConfig = field(default_factory=DebugConfig)
    speed: SpeedConfig = field(default_factory=SpeedConfig)

    def validate(self) -> None:
        """Raise ``ValueError`` naming the bad key and what is allowed."""
        self.model.validate()
        self.losses.validate()
        self.speed.validate()
        t, o = self.train, self.optim
        if t.steps < 1 or t.batch_size < 1:
            raise ValueError(f"train.steps and train.batch_size must be positive, got {t.steps}, {t.batch_size}")
        if t.on_nonfinite not in ("stop", "skip"):
            raise ValueError(f"train.on_nonfinite must be 'stop' or 'skip', got {t.on_nonfinite!r}")
        for key in ("checkpoint_every", "log_every"):
            if getattr(t, key) < 1:
                raise ValueError(f"train.{key} must be >= 1, got {getattr(t, key)}")
        if t.image_every < 0 or t.keep_every < 0:
            raise ValueError("train.image_every and train.keep_every must be >= 0 (0 switches them off)")
        if o.lr <= 0 or len(o.betas) != 2:
            raise ValueError(f"optim.lr must be positive and optim.betas two numbers, got {o.lr}, {o.betas}")
        if o.schedule not in ("constant", "cosine"):
            raise ValueError(f"optim.schedule must be 'constant' or 'cosine', got {o.schedule!r}")
        if o.grad_clip is not None and o.grad_clip <= 0:
            raise ValueError(f"optim.grad_clip must be positive or null, got {o.grad_clip}")
        if self.device != "auto" and self.device != "cpu" and not self.device.startswith("cuda"):
            raise ValueError(f"device must be 'auto', 'cpu' or 'cuda[:N]', got {self.device!r}")
        if self.threads is not None and self.threads < 1:
            raise ValueError(f"threads must be a positive integer or null, got {self.threads}")
        if self.data.image_size is not None and self.data.image_size < 32:
            raise ValueError(f"data.image_size must be >= 32 (or null), got {self.data.image_size}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False)

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> TrainConfig:
        cfg = _build(cls, d, "")
        cfg.validate()
        return cfg


# ------------------------------------------------------------------ building from plain dicts
_EXACT = {bool: "true/false", str: "a string", type(None): "null"}
"""Types taken as they are (no conversion), with how an error message names them."""


def _coerce(value: Any, hint: Any, key: str) -> Any:
    """Check/convert one value against a type hint; ``ValueError`` names the key on mismatch."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        for option in typing.get_args(hint):
            try:
                return _coerce(value, option, key)
            except ValueError:
                pass
        raise ValueError(f"{key}: {value!r} fits none of {hint}")
    if hint in _EXACT:
        if isinstance(value, hint):
            return value
        raise ValueError(f"{key}: expected {_EXACT[hint]}, got {value!r}")
    if hint is int:
        if isinstance(value, int) and not isinstance(value, bool):
            return value
        if isinstance(value, float) and value.is_integer():
            return int(value)
        raise ValueError(f"{key}: expected an integer, got {value!r}")
    if hint is float:
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            return float(value)
        if isinstance(value, str):
            try:
                return float(value)  # YAML reads "5e-4" as a string
            except ValueError:
                pass
        raise ValueError(f"{key}: expected a number, got {value!r}")
    if origin is list:
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{key}: expected a list, got {value!r}")
        (item,) = typing.get_args(hint) or (Any,)
        return [v if item is Any else _coerce(v, item, f"{key}[{i}]") for i, v in enumerate(value)]
    if is_dataclass(hint):
        if not isinstance(value, dict):
            raise ValueError(f"{key}: expected a mapping of {sorted(f.name for f in fields(hint))}, got {value!r}")
        return _build(hint, value, key + ".")
    return value


def _build(cls: type, d: dict[str, Any], prefix: str) -> Any:
    hints = typing.get_type_hints(cls)
    known = {f.name for f in fields(cls)}
    unknown = set(d) - known
    if unknown:
        raise ValueError(f"unknown config key(s) {sorted(prefix + k for k in unknown)}; "
                         f"valid keys here: {sorted(prefix + k for k in known)}")
    return cls(**{k: _coerce(v, hints[k], prefix + k) for k, v in d.items()})


# ------------------------------------------------------------------ files, presets, overrides
def _presets_dir():
    return resources.files("cerberus_core").joinpath("configs")


def preset_names() -> list[str]:
    """Names of the bundled presets."""
    return sorted(p.name[:-5] for p in _presets_dir().iterdir() if p.name.endswith(".yaml"))


def _preset_text(name: str) -> str:
    res = _presets_dir().joinpath(f"{name}.yaml")
    if not res.is_file():
        raise ValueError(f"unknown preset {name!r}; bundled presets: {', '.join(preset_names())}")
    return res.read_text()


def deep_merge(base: dict[str, Any], top: dict[str, Any]) -> dict[str, Any]:
    """Recursive dict merge: values of ``top`` win; nested mappings merge."""
    out = dict(base)
    for k, v in top.items():
        out[k] = deep_merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def _load_raw(text: str, source: str, base_dir: Path | None) -> dict[str, Any]:
    """A config's mapping with its ``extends`` chain resolved."""
    raw: dict[str, Any] = {}
    for _, layer in _layers(text, source, base_dir):
        raw = deep_merge(raw, layer)
    return raw


def _layers(text: str, source: str, base_dir: Path | None, depth: int = 0) -> list[tuple[str, dict[str, Any]]]:
    """The config and its ancestors as ``(source, mapping)`` layers, most basic first.

    ``extends: [a, b]`` lists a's layers, then b's layers not already listed, then this file's own:
    ``[cpu, nmrr]`` (both extending ``paper``) gives paper, cpu, nmrr, so the variant lands on the CPU
    schedule instead of bringing the paper's settings back.
    """
    if depth > 8:
        raise ValueError(f"{source}: 'extends' chain deeper than 8 (a cycle?)")
    try:
        raw = yaml.safe_load(text) or {}
    except yaml.YAMLError as exc:
        raise ValueError(f"{source} is not valid YAML: {exc}") from exc
    if not isinstance(raw, dict):
        raise ValueError(f"{source} must hold a YAML mapping of config sections")
    parents = raw.pop("extends", None)
    parents = [] if parents is None else parents if isinstance(parents, list) else [parents]
    layers: list[tuple[str, dict[str, Any]]] = []
    for parent in parents:
        for layer in _parent_layers(str(parent), base_dir, depth + 1):
            if layer[0] not in {name for name, _ in layers}:
                layers.append(layer)
    return [*layers, (source, raw)]


def _parent_layers(parent: str, base_dir: Path | None, depth: int) -> list[tuple[str, dict[str, Any]]]:
    """The layers of one ``extends`` entry: a config file (relative to ``base_dir``) or a preset name."""
    if parent.endswith((".yaml", ".yml")):
        path = Path(parent) if base_dir is None or Path(parent).is_absolute() else base_dir / parent
        return _layers(_read(path), str(path.resolve()), path.parent, depth)
    return _layers(_preset_text(parent), f"preset {parent}", None, depth)


def _read(path: Path) -> str:
    try:
        return Path(path).read_text()
    except FileNotFoundError:
        raise ValueError(f"config file {path} does not exist") from None


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``["optim.lr=1e-4", "train.steps=10"]`` → nested dict (values parsed as YAML)."""
    out: dict[str, Any] = {}
    for item in items:
        if "=" not in item:
            raise ValueError(f"--set {item!r}: expected section.key=value, e.g. --set optim.lr=0.0001")
        key, text = item.split("=", 1)
        value = yaml.safe_load(text) if text.strip() else None
        node = out
        parts = key.strip().split(".")
        for p in parts[:-1]:
            node = node.setdefault(p, {})
        node[parts[-1]] = value
    return out


def load_config(path: str | Path | None = None, *, preset: str | list[str] | None = None,
                overrides: list[str] | None = None) -> TrainConfig:
    """Build a :class:`TrainConfig` from a YAML file or bundled preset(s), plus ``--set`` overrides.

    ``preset`` may be a list, merged left to right like ``extends: [a, b]`` (``["cpu", "nmrr"]``:
    the CPU schedule with the NMRr baseline's changes). With neither ``path`` nor ``preset`` the
    defaults (the paper's settings) are used.
    """
    if path is not None and preset is not None:
        raise ValueError("give either a config file or a preset, not both (a file can say 'extends: PRESET')")
    if path is not None:
        raw = _load_raw(_read(Path(path)), str(path), Path(path).parent)
    elif preset is not None:
        names = [preset] if isinstance(preset, str) else list(preset)
        raw = _load_raw(yaml.safe_dump({"extends": names}), "--preset " + " --preset ".join(names), None)
    else:
        raw = {}
    raw = deep_merge(raw, parse_overrides(overrides or []))
    return TrainConfig.from_dict(raw)


def config_diff(a: TrainConfig, b: TrainConfig) -> list[str]:
    """Dotted keys whose values differ between two configs."""
    def flat(d: dict[str, Any], prefix: str = "") -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k, v in d.items():
            if isinstance(v, dict):
                out.update(flat(v, f"{prefix}{k}."))
            else:
                out[prefix + k] = v
        return out

    fa, fb = flat(a.to_dict()), flat(b.to_dict())
    return sorted(k for k in fa.keys() | fb.keys() if fa.get(k) != fb.get(k))
