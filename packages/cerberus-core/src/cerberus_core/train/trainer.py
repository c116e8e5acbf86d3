"""The training loop: Adam on the Cerberus objective, with exact resumption and safe failure.

:func:`train` is what ``cerberus train`` calls. Guarantees:

* **Resumption is exact.** Data order and the pose-consistency draws are pure functions of
  ``(seed, step[, rank])``; checkpoints hold the model, optimiser, scheduler and every RNG state.
  A run killed and resumed with ``resume=True`` ends with the same weights as one never
  interrupted.
* **Non-finite steps never reach the weights.** The loss and the global gradient norm are checked
  (on every rank, agreed with an all-reduce) before ``optimizer.step()``. With
  ``train.on_nonfinite: stop`` the run raises :class:`NonFiniteError` and the last checkpoint stays
  as it was; with ``skip`` the update is dropped (and the run stops after
  ``train.max_consecutive_skips`` in a row).
* **Interrupts are clean.** SIGINT/SIGTERM finish the current step, write a checkpoint and return
  a result with ``interrupted`` set and ``stop_signal`` the signal (``cerberus train`` then exits
  130 or 143, so scripts know the run did not finish).
* **One writer per run folder.** The main process holds ``RUN/.cerberus.lock``
  (:mod:`cerberus_core.plumbing.lock`) for the whole run; a second training into the same folder is refused
  with the holder's pid. A fresh run starts only in a new or empty folder.
* **A run is usable from anywhere.** ``data.root`` is stored as an absolute path, and the training
  data's scene set-up is stored in every checkpoint and in ``model.safetensors``.
* **The data is checked once at start:** every shard of the training split against its sha256 in the
  manifest (a corrupt shard would otherwise train silently on garbage).
"""
from __future__ import annotations

import dataclasses
import json
import math
import random
import shutil
import signal
import time
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
from torch.nn.parallel import DistributedDataParallel
from torch.utils.data import DataLoader
from tqdm import tqdm

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.looks import look_generator
from cerberus_core.errors import (
    ConfigError,
    LockedError,
    NoCheckpointError,
    NonFiniteError,
    RunExistsError,
)
from cerberus_core.model.cerberus import Cerberus
from cerberus_core.plumbing.atomic import atomic_write, atomic_write_text, is_temporary
from cerberus_core.plumbing.lock import acquire, check_unlocked, is_lock_file
from cerberus_core.plumbing.machine import capped_to_cores
from cerberus_core.plumbing.outputs import MARKER, check_output, output_kind, resolved, write_marker
from cerberus_core.plumbing.signals import interrupt_for
from cerberus_core.render.backends import make_renderer, resolve_renderer
from cerberus_core.train.checkpoint import (
    LAST,
    checkpoint_dir,
    export_weights,
    load_checkpoint,
    restore_rng,
    save_checkpoint,
)
from cerberus_core.train.data import (
    StepBatchSampler,
    build_dataset,
    check_dataset,
    quadruplet_batch,
    with_input_look,
)
from cerberus_core.train.distributed import (
    DistInfo,
    any_true,
    barrier,
    init_distributed,
    launch_environment,
    mean_over_ranks,
    resolve_device,
    shutdown,
)
from cerberus_core.train.logs import AllocationProbe, MetricsLog, plot_loss_curves, save_progress_grid
from cerberus_core.train.objective import quadruplet_objective
from cerberus_core.train.settings import OptimConfig, TrainConfig, config_diff
from cerberus_core.train.speed import apply_speed, release_speed, resolve_autocast

RESUMABLE_CHANGES = frozenset({
    "threads", "train.steps", "train.log_every", "train.image_every", "train.checkpoint_every", "train.keep_every",
    "train.progress", "train.tensorboard", "data.num_workers", "data.root", "device", "renderer",
    "debug.poison_steps", "speed.autocast", "speed.channels_last", "speed.compile",
    "speed.smoothness_once",
})
"""Config keys a resumed run may change; any other difference is refused (it would not be the same run)."""


@dataclass
class TrainResult:
    """Attributes:
        run_dir: the run folder.
        step: completed optimisation steps.
        model: the trained (unwrapped) model, on the training device.
        terms: the last logged loss terms (rank means).
        skipped: steps whose update was dropped as non-finite.
        interrupted: stopped early by SIGINT/SIGTERM (a checkpoint was written).
        rank: this process's data-parallel rank (0 when not distributed).
        stop_signal: the signal that stopped it (``signal.SIGINT`` / ``SIGTERM``), 0 if none.
    """

    run_dir: Path
    step: int
    model: Cerberus
    terms: dict[str, float]
    skipped: int
    interrupted: bool = False
    rank: int = 0
    stop_signal: int = 0


def lr_factor(optim: OptimConfig, total_steps: int) -> Callable[[int], float]:
    """Learning-rate multiplier per step: linear warm-up, then constant or cosine decay."""
    def factor(step: int) -> float:
        if optim.warmup_steps and step < optim.warmup_steps:
            return (step + 1) / optim.warmup_steps
        if optim.schedule == "constant":
            return 1.0
        span = max(1, total_steps - optim.warmup_steps)
        progress = min(1.0, (step - optim.warmup_steps) / span)
        return optim.min_lr_ratio + (1 - optim.min_lr_ratio) * 0.5 * (1 + math.cos(math.pi * progress))
    return factor


def make_optimizer(model: torch.nn.Module, optim: OptimConfig) -> torch.optim.Adam:
    """Adam over ``model``'s parameters (on their device), with torch's fused kernel where it has one
    for that device (CPU and CUDA in torch >= 2.4): one kernel for the whole update instead of a few
    dozen ``foreach`` ops, the same algorithm up to float rounding. Its state dict is the same, so
    checkpoints load either way."""
    params = list(model.parameters())
    fused = params[0].device.type in fused_adam_devices()
    return torch.optim.Adam(params, lr=optim.lr, betas=tuple(optim.betas), eps=optim.eps,
                            weight_decay=optim.weight_decay, fused=fused or None)


def fused_adam_devices() -> tuple[str, ...]:
    """The device types torch's fused Adam runs on in this torch (``("cuda",)`` in torch < 2.4)."""
    from torch.utils import _foreach_utils

    return tuple(getattr(_foreach_utils, "_get_fused_kernels_supported_devices", lambda: ["cuda"])())


def step_generator(seed: int, step: int, rank: int) -> torch.Generator:
    """The random source of one step's pose-consistency draws (a pure function of its arguments)."""
    state = np.random.SeedSequence([int(seed), int(step), int(rank), 0x9E37]).generate_state(2, dtype=np.uint32)
    return torch.Generator().manual_seed(int(state[0]) << 32 | int(state[1]))


def seed_everything(seed: int) -> None:
    random.seed(seed)
    np.random.seed(seed % 2**32)
    torch.manual_seed(seed)


class _StopRequest:
    """Turns SIGINT/SIGTERM into a flag checked between steps (main thread only).

    A step normally ends within a second, and then the loop checkpoints and stops. A step still running
    :data:`STEP_GRACE_S` seconds after the signal (a huge batch, a slow device) is abandoned: the signal
    is raised there, the run keeps its last checkpoint, and the command exits 130 / 143 all the same. A
    second signal stops at once.
    """

    def __init__(self) -> None:
        self.requested = False
        self.signum = 0
        self.in_step = False
        self._previous: dict[int, Any] = {}

    def __enter__(self) -> _StopRequest:
        try:
            for sig in (signal.SIGINT, signal.SIGTERM, signal.SIGALRM):
                self._previous[sig] = signal.signal(sig, self._alarm if sig == signal.SIGALRM else self._handle)
        except ValueError:  # not the main thread: leave signals alone
            self._previous.clear()
        return self

    def _handle(self, signum, frame) -> None:  # noqa: ARG002
        if self.requested:  # second signal: give up immediately
            raise interrupt_for(signum)
        self.requested, self.signum = True, signum
        if self.in_step and self._previous:
            signal.setitimer(signal.ITIMER_REAL, STEP_GRACE_S)

    def _alarm(self, signum, frame) -> None:  # noqa: ARG002
        if self.in_step:  # the step outlived its grace: abandon it, keep the last checkpoint
            raise interrupt_for(self.signum)

    def step_done(self) -> None:
        """Between steps: a pending grace alarm is no longer needed."""
        self.in_step = False
        if self.requested and self._previous:
            signal.setitimer(signal.ITIMER_REAL, 0)

    def __exit__(self, *exc) -> None:
        if self._previous:
            signal.setitimer(signal.ITIMER_REAL, 0)
        for sig, handler in self._previous.items():
            signal.signal(sig, handler)


STEP_GRACE_S = 3.0
"""Seconds a running step may still take after SIGINT/SIGTERM before it is abandoned."""


#: What a training writes before its first checkpoint: a run folder marked as a run (:data:`MARKER`) holding only
#: these and no checkpoint or ``model.safetensors`` is a start that never reached a checkpoint.
UNFINISHED_START_NAMES = frozenset({MARKER, "config.yaml", "metrics.csv", "tensorboard", "images", "checkpoints",
                                    "loss_curves.png"})


def unfinished_start(run_dir: Path) -> list[Path]:
    """The entries of ``run_dir`` when it holds a training that stopped (crashed, was killed) before its
    first checkpoint, else ``[]``: marked as a run by the toolkit (:data:`MARKER`; an earlier version's
    unmarked start is not recognised: delete it by hand), only names of :data:`UNFINISHED_START_NAMES`, no
    ``model.safetensors``, and a ``checkpoints/`` folder (if any) holding nothing but an atomic writer's
    temporary. Nothing there can be resumed, so a fresh run may clear it."""
    if output_kind(run_dir) != "run":
        return []
    entries = [p for p in run_dir.iterdir() if not is_lock_file(p) and not is_temporary(p)]
    if any(p.name not in UNFINISHED_START_NAMES for p in entries):
        return []
    ckdir = checkpoint_dir(run_dir)
    if ckdir.exists() and (not ckdir.is_dir() or ckdir.is_symlink() or any(not is_temporary(p)
                                                                           for p in ckdir.iterdir())):
        return []
    return entries


def _clear_unfinished_start(run_dir: Path, entries: list[Path]) -> None:
    """Remove what a start that never checkpointed left (the marker last, ``config.yaml`` just before: until
    they go, the folder still reads as such a start to a rank that looks meanwhile, or to a rerun)."""

    names = ", ".join(sorted(p.name for p in entries))
    warnings.warn(f"{run_dir} holds a training that stopped before its first checkpoint ({names}); nothing there "
                  "can be resumed, so it is cleared and the training starts again", UserWarning, stacklevel=3)
    for p in sorted(entries, key=lambda p: (p.name == MARKER, p.name == "config.yaml")):
        if p.is_dir() and not p.is_symlink():
            shutil.rmtree(p)
        else:
            p.unlink(missing_ok=True)


def _earlier_run(run_dir: Path) -> bool:
    """An unmarked run folder of an earlier version that may be resumed: it holds a last checkpoint."""
    return (checkpoint_dir(run_dir) / LAST).is_file()


def check_run_folder(run_dir: Path, resume: bool, *, holding_lock: bool = False) -> None:
    """The one output rule (:func:`~cerberus_core.plumbing.outputs.check_output`: new, empty or a run the
    toolkit wrote; never a folder of other files), then: a fresh run needs a new or empty folder, or one
    holding only a start that never reached a checkpoint (:func:`unfinished_start`); a resumed one a
    checkpoint (checked before the lock is taken, so a refused run does not even touch the folder, and
    again under the lock)."""
    last = checkpoint_dir(run_dir) / LAST
    if run_dir.exists() and not run_dir.is_dir():
        raise RunExistsError(f"{run_dir} is a file, not a folder; pass a folder as `run_dir`")
    if not holding_lock:
        check_unlocked(run_dir)  # a live writer is the first thing to name
    ours = check_output(run_dir, "run", "run_dir", legacy=_earlier_run, holding_lock=holding_lock)
    if not resume:
        if last.exists():
            raise RunExistsError(f"{run_dir} already holds a training run ({last}); pass `resume=True` to continue "
                                 "it, or another `run_dir` to start a new run")
        if ours and not unfinished_start(run_dir):
            held = sorted(p.name for p in run_dir.iterdir() if not is_lock_file(p) and not is_temporary(p))
            shown = ", ".join(held[:4]) + (f" and {len(held) - 4} more" if len(held) > 4 else "")
            raise RunExistsError(f"{run_dir} is not empty (it holds {shown}) and is not a resumable run; training "
                                 "starts only in a new or empty folder: pass another `run_dir`")
        return
    if not last.exists():
        if run_dir.is_dir() and unfinished_start(run_dir):
            raise NoCheckpointError(f"`resume=True`: the training in {run_dir} stopped before its first checkpoint, "
                                    "so there is nothing to resume; start it anew (`resume=False`: what it left is "
                                    "cleared)")
        raise NoCheckpointError(f"`resume=True`: no checkpoint at {last}; start the training anew (`resume=False`)")


def check_not_shorter(run_dir: Path, config: TrainConfig) -> None:
    """A resumed run may not end before the step its last checkpoint reached (its saved config would say fewer
    steps than it ran): :class:`ConfigError` naming ``train.steps``, before the run folder is locked or written.
    Without a checkpoint there is nothing to compare (:func:`check_run_folder` says so)."""
    last = checkpoint_dir(run_dir) / LAST
    if last.is_file() and config.train.steps < (reached := int(load_checkpoint(last)["step"])):
        raise ConfigError.about("train.steps", config.train.steps, f"the run in {run_dir} already reached step "
                                f"{reached}; a resumed run cannot end before it", f"`train.steps={reached}` or more, "
                                "or leave it out to keep the run's own")


def prepare_run_dir(run_dir: Path, resume: bool, config: TrainConfig, *, clear: bool = True) -> dict[str, Any] | None:
    """Check the run folder against ``resume``; return the checkpoint to resume from (or ``None``).
    A fresh run clears what a start that never checkpointed left (``clear``: the main process only)."""
    check_run_folder(run_dir, resume, holding_lock=True)
    if not resume:
        if clear and run_dir.is_dir() and (entries := unfinished_start(run_dir)):
            _clear_unfinished_start(run_dir, entries)
        return None
    last = checkpoint_dir(run_dir) / LAST
    payload = load_checkpoint(last)
    saved = TrainConfig.from_yaml(payload["config"], last)
    changed = [k for k in config_diff(saved, config) if k not in RESUMABLE_CHANGES]
    if changed:
        raise ConfigError.about("resume", True, f"the config differs from the run's saved config in {changed}; only "
                                f"{sorted(RESUMABLE_CHANGES)} may change when resuming")
    return payload


def train(config: TrainConfig, run_dir: str | Path, *, resume: bool = False, dataset: Any = None) -> TrainResult:
    """Train Cerberus.

    Args:
        config: the training config (validated here).
        run_dir: where config, checkpoints, logs and pictures go.
        resume: continue from ``run_dir/checkpoints/last.pt``.
        dataset: a quadruplet dataset to use instead of the one ``config.data`` names (any object
            following the contract of :mod:`cerberus_core.train.data`).
    Returns:
        A :class:`TrainResult`.
    Raises:
        RunExistsError, NoCheckpointError, LockedError: the run folder does not fit ``resume`` or is in use
            (:func:`check_run_folder`: before anything is built).
        NonFiniteError: with ``train.on_nonfinite: stop``, when a step's loss or gradient is not finite.
    """
    check_run_folder(Path(run_dir), resume)  # before anything is built or written (checked again under the lock)
    # Shallow copies (the caller's object is not mutated below); making them checks them (fields.Checked).
    config = dataclasses.replace(config)
    config.model = dataclasses.replace(config.model)
    if dataset is None:  # stored absolute: eval, reconstruct and --resume work from any directory
        config.data = dataclasses.replace(config.data, root=str(resolved(config.data.root, "data.root")))
    device = resolve_device(config.device, launch_environment().local_rank)
    if config.threads is not None:
        config.threads = capped_to_cores("threads", config.threads)
        torch.set_num_threads(config.threads)
    config.data = dataclasses.replace(config.data, num_workers=capped_to_cores("data.num_workers", config.data.num_workers))
    if resume:
        check_not_shorter(Path(run_dir), config)
    info = init_distributed(device)
    try:
        return _Trainer(config, Path(run_dir), info, device, dataset).run(resume)
    finally:
        shutdown(info)


def verify_split(root: str | Path, split: str) -> None:
    """Check every shard file of ``split`` against the sha256 the manifest records (once, at the start
    of a run: the reader only checks sizes on every open). :class:`DatasetError` names the bad file."""
    Dataset.open(root).quadruplets(split, verify=True)


class _Trainer:
    def __init__(self, config: TrainConfig, run_dir: Path, info: DistInfo, device: torch.device, dataset: Any) -> None:
        self.config, self.run_dir, self.info, self.device = config, run_dir, info, device
        self.dataset = dataset if dataset is not None else build_dataset(config.data.root, config.data.split)
        self.dataset_is_own = dataset is None  # the allocation probe reads the test split of config.data.root
        check_dataset(self.dataset)
        if config.train.batch_size > len(self.dataset):
            raise ConfigError.about("train.batch_size", config.train.batch_size,
                                    f"more than the {len(self.dataset)} quadruplets of the training data "
                                    f"{config.data.root}: every step would repeat them; use at most {len(self.dataset)}",
                                    f"`train.batch_size={len(self.dataset)}`")
        if dataset is None and info.is_main:
            verify_split(config.data.root, config.data.split)
        self.scene = self.dataset.scene
        if config.model.depth_offset == "auto":
            config.model.depth_offset = self.scene.distance
        self.image_size = config.data.image_size or int(self.dataset.image_size)
        config.check_memory(self.image_size, device)
        config.renderer = resolve_renderer(config.renderer)  # the saved config names the backend used
        self.renderer = make_renderer(config.renderer)
        autocast, why = resolve_autocast(config.speed.autocast, device)  # saved resolved, like the renderer
        config.speed = dataclasses.replace(config.speed, autocast=autocast)
        self.speed_note = f"speed.autocast: {autocast or 'off (float32)'} ({why})"

    # ------------------------------------------------------------------ set-up
    def _build(self, payload: dict[str, Any] | None) -> int:
        cfg = self.config
        seed_everything(cfg.seed)
        self.model = apply_speed(Cerberus(cfg.model).to(self.device), cfg.speed)
        self.optimizer = make_optimizer(self.model, cfg.optim)
        self.scheduler = torch.optim.lr_scheduler.LambdaLR(self.optimizer, lr_factor(cfg.optim, cfg.train.steps))
        start, self.skipped = 0, 0
        if payload is not None:
            self.model.load_state_dict(payload["model"])
            self.optimizer.load_state_dict(payload["optimizer"])
            self.scheduler.load_state_dict(payload["scheduler"])
            start = int(payload["step"])
            self.skipped = int(payload["extra"].get("skipped", 0))
            restore_rng(payload["rng"])
        self.net: torch.nn.Module = self.model
        if self.info.enabled:
            ids = [self.device.index] if self.device.type == "cuda" else None
            self.net = DistributedDataParallel(self.model, device_ids=ids,
                                               find_unused_parameters=not self.model.trains_every_parameter)
        return start

    def _checkpoint(self, step: int) -> None:
        if self.info.is_main:
            ckdir = checkpoint_dir(self.run_dir)
            path = save_checkpoint(ckdir / LAST, model=self.model, optimizer=self.optimizer, scheduler=self.scheduler,
                                   step=step, config_yaml=self.config_yaml,
                                   extra={"skipped": self.skipped, "scene": json.dumps(self.scene.to_dict())})
            keep = self.config.train.keep_every
            if keep and step % keep == 0:
                with open(path, "rb") as kept:  # atomic: a kept step is whole or absent, like last.pt
                    atomic_write(ckdir / f"step_{step:07d}.pt", lambda fh, src=kept: shutil.copyfileobj(src, fh))
        barrier(self.info)

    # ------------------------------------------------------------------ loop
    def _due(self, done: int, every: int) -> bool:
        """Whether a periodic action (every ``every`` steps, and at the last step) is due."""
        return bool(every) and (done % every == 0 or done == self.config.train.steps)

    def _loader(self, start: int) -> DataLoader:
        cfg, info = self.config, self.info
        sampler = StepBatchSampler(len(self.dataset), cfg.seed, cfg.train.batch_size, start, cfg.train.steps,
                                   info.rank, info.world_size)
        return DataLoader(self.dataset, batch_sampler=sampler, num_workers=cfg.data.num_workers,
                          pin_memory=self.device.type == "cuda")

    def run(self, resume: bool) -> TrainResult:
        """Hold the run folder's lock (main process) around :meth:`_run`; every rank learns of a refusal."""
        # Only the main process checks for a live writer: the others may look after it has taken the lock.
        check_run_folder(self.run_dir, resume, holding_lock=not self.info.is_main)
        lock, refused = None, None
        if self.info.is_main:
            try:
                lock = acquire(self.run_dir, "cerberus train")
            except LockedError as exc:
                refused = exc
        if any_true(refused is not None, self.info, self.device):
            raise refused or LockedError(f"{self.run_dir} is in use by another process (see rank 0)")
        try:
            return self._run(resume)
        finally:
            if lock is not None:
                lock.release()

    def _run(self, resume: bool) -> TrainResult:
        cfg, info, loop = self.config, self.info, self.config.train
        payload = prepare_run_dir(self.run_dir, resume, cfg, clear=info.is_main)
        barrier(info)  # every rank has checked the folder before rank 0 writes into it
        start = self._build(payload)
        self.config_yaml = cfg.to_yaml()
        log = None
        if info.is_main:
            self.run_dir.mkdir(parents=True, exist_ok=True)
            write_marker(self.run_dir, "run")  # before anything else: what proves the folder is a run
            atomic_write_text(self.run_dir / "config.yaml", self.config_yaml)
            log = MetricsLog(self.run_dir, start, loop.tensorboard)
        probe = AllocationProbe.for_data(cfg.data.root, self.renderer) if self._probing() else None
        bar = self._progress_bar(start)
        terms: dict[str, float] = {}
        consecutive, done, interrupted, stop_signal = 0, start, False, 0
        window = [time.perf_counter(), 0]  # start time and steps of the current logging window
        t0 = window[0]
        poison = set(cfg.debug.poison_steps)
        try:
            with _StopRequest() as stop:
                for step, raw in zip(range(start, loop.steps), self._loader(start), strict=False):
                    batch = quadruplet_batch(raw, self.device, self.scene, self.image_size)
                    if step in poison:
                        batch.images = torch.full_like(batch.images, float("nan"))
                    look = cfg.data.input_look  # the network sees it; the losses keep the stored renders
                    batch = with_input_look(batch, look, self.scene, look_generator(cfg.seed, step, self.info.rank)
                                            if look == "random" else None)
                    stop.in_step = True
                    ok, out, grad_norm = self._step(batch, step)
                    stop.step_done()
                    consecutive = 0 if ok else consecutive + 1
                    if not ok:
                        self.skipped += 1
                        message = self._nonfinite_message(step, out.terms, grad_norm)
                        if loop.on_nonfinite == "stop" or consecutive > loop.max_consecutive_skips:
                            raise NonFiniteError(message)
                        bar.write(f"warning: {message}; update skipped ({consecutive} in a row)")
                    self.scheduler.step()
                    done, window[1] = step + 1, window[1] + 1
                    row = self._allocation(probe, done, window)  # the step's log row: these, then the losses
                    if self._due(done, loop.log_every):
                        terms = mean_over_ranks(out.terms, info)
                        now = time.perf_counter()
                        row |= terms | {"lr": self.optimizer.param_groups[0]["lr"], "grad_norm": grad_norm,
                                        "steps_per_s": window[1] / max(now - window[0], 1e-9),
                                        "skipped": self.skipped, "elapsed_s": now - t0}
                        window = [now, 0]
                        bar.set_postfix({k: f"{v:.3g}" for k, v in terms.items()})
                    if log is not None and row:
                        log.log(done, row)
                    if info.is_main and ok and self._due(done, loop.image_every):
                        self._pictures(batch, out, done)
                    bar.update(1)
                    if self._due(done, loop.checkpoint_every):
                        self._checkpoint(done)
                    if any_true(stop.requested, info, self.device):
                        if not self._due(done, loop.checkpoint_every):
                            self._checkpoint(done)
                        bar.write(f"interrupted: checkpoint written at step {done} (a resumed training continues from it)")
                        interrupted, stop_signal = True, stop.signum or signal.SIGINT
                        break
        finally:
            bar.close()
            if log is not None:
                log.close()
        if info.is_main and not interrupted:
            export_weights(self.model, self.run_dir / "model.safetensors", self.config_yaml, done,
                           scene=self.scene.to_dict())
            plot_loss_curves(self.run_dir / "metrics.csv", self.run_dir / "loss_curves.png")
        barrier(info)
        return TrainResult(self.run_dir, done, release_speed(self.model), terms, self.skipped, interrupted, info.rank,
                           stop_signal)

    def _probing(self) -> bool:
        """Whether this process logs the allocation diagnostics: the main one, when asked, on the data of
        ``data.root`` (not a dataset object passed in)."""
        return self.info.is_main and bool(self.config.train.allocation_every) and self.dataset_is_own

    def _allocation(self, probe: AllocationProbe | None, done: int, window: list) -> dict[str, float]:
        """The allocation diagnostics when due (every ``train.allocation_every`` steps, else ``{}``); their
        time is left out of the logging window's steps/s."""
        if probe is None or done % self.config.train.allocation_every:
            return {}
        before = time.perf_counter()
        values = probe.measure(self.model)
        window[0] += time.perf_counter() - before
        return values

    def _progress_bar(self, start: int) -> tqdm:
        """The main process's progress bar (when ``train.progress``), opened with a line that says what
        runs where (the renderer, the device and the network's precision)."""
        show = self.info.is_main and self.config.train.progress
        bar = tqdm(total=self.config.train.steps, initial=start, desc="train", unit="step", dynamic_ncols=True,
                   mininterval=1.0, disable=not show)
        if show:
            bar.write(f"renderer: {self.config.renderer}, device: {self.device}, {self.speed_note}")
        return bar

    def _step(self, batch, step: int):
        """One optimisation step; returns ``(ok, objective output, gradient norm)``."""
        self.net.train()
        # Batch-norm statistics change in the forward pass: keep them to undo a non-finite step.
        buffers = [b.detach().clone() for b in self.model.buffers()]
        gen = step_generator(self.config.seed, step, self.info.rank)
        out = quadruplet_objective(self.net, self.renderer, batch, self.scene, self.config.losses, gen,
                                   smoothness_once=self.config.speed.smoothness_once,
                                   antialias=self.config.render.antialias, step=step)
        self.optimizer.zero_grad(set_to_none=True)
        grad_norm = float("nan")
        ok = not any_true(not out.finite, self.info, self.device)
        if ok:
            out.total.backward()
            grads = [p.grad for p in self.model.parameters() if p.grad is not None]
            norm = torch.nn.utils.get_total_norm(grads)
            grad_norm = float(norm)
            ok = not any_true(not math.isfinite(grad_norm), self.info, self.device)
        if not ok:
            self.optimizer.zero_grad(set_to_none=True)
            with torch.no_grad():
                for b, saved in zip(self.model.buffers(), buffers, strict=True):
                    b.copy_(saved)
            return False, out, grad_norm
        if self.config.optim.grad_clip is not None:
            torch.nn.utils.clip_grads_with_norm_(grads, self.config.optim.grad_clip, norm)
        self.optimizer.step()
        return True, out, grad_norm

    def _nonfinite_message(self, step: int, terms: dict[str, torch.Tensor], grad_norm: float) -> str:
        values = ", ".join(f"{k}={float(v):.4g}" for k, v in terms.items())
        last = checkpoint_dir(self.run_dir) / LAST
        where = f"the last good checkpoint is {last}" if last.exists() else "no checkpoint was written yet"
        return (f"non-finite loss or gradient at step {step} ({values}, grad_norm={grad_norm:.4g}); the weights were "
                f"not updated and {where}. Lower optim.lr, set optim.grad_clip, check the data, or set "
                "train.on_nonfinite=skip")

    @torch.no_grad()
    def _pictures(self, batch, out, step: int) -> None:
        k = min(8, batch.images.shape[0] * 4)
        images = batch.network_inputs.flatten(0, 1)[:k]  # what the network saw
        save_progress_grid(self.run_dir / "images" / f"step_{step:07d}.png", self.renderer, images,
                           out.renders.flatten(0, 1)[:k], out.parts.flatten(0, 1)[:k], self.model.faces,
                           batch.camera.index(slice(0, k)), self.scene)
