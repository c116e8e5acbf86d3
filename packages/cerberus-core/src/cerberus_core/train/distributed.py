"""Data-parallel training with ``torchrun`` and DistributedDataParallel.

Launch ``torchrun --nproc_per_node K -m cerberus_core.cli train ...`` (or ``cerberus train`` under
``torchrun``): every process reads ``RANK`` / ``WORLD_SIZE`` / ``LOCAL_RANK`` from the environment,
joins a process group (``gloo`` on CPU, ``nccl`` on CUDA), draws its own ``1/K`` slice of each
global batch and averages gradients with the others. Rank 0 writes logs, pictures and checkpoints.
"""
from __future__ import annotations

import os
from dataclasses import dataclass

import torch
import torch.distributed as dist

from cerberus_core.devices import check_device
from cerberus_core.errors import ConfigError


@dataclass(frozen=True)
class DistInfo:
    """This process's place in the data-parallel group (``world_size == 1``: not distributed)."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0
    owns_group: bool = False  # this module created the process group (and so destroys it)

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    @property
    def enabled(self) -> bool:
        return self.world_size > 1


def launch_environment() -> DistInfo:
    """This process's place as the ``torchrun`` environment says (``WORLD_SIZE``, ``RANK``, ``LOCAL_RANK``; none
    set: one process). :class:`ConfigError` naming the variable when one is not a whole number in its range or
    ``RANK`` is missing for a group (set by hand, not by ``torchrun``)."""
    def number(name: str, default: int | None, low: int, high: int | None) -> int:
        text = os.environ.get(name)
        if text is None and default is not None:
            return default
        try:
            value = int(text) if text is not None else None
        except ValueError:
            value = None
        if value is None or value < low or (high is not None and value >= high):
            shown = "unset" if text is None else repr(text)
            upper = "" if high is None else f" below {high}"
            raise ConfigError(f"the environment variable {name} is {shown}, not a whole number {low} or more{upper}; "
                              "launch with torchrun (which sets WORLD_SIZE, RANK and LOCAL_RANK) or unset them", key=name)
        return value

    world = number("WORLD_SIZE", 1, 1, None)
    rank = number("RANK", 0 if world == 1 else None, 0, world)
    return DistInfo(rank, world, number("LOCAL_RANK", rank, 0, None))


def resolve_device(name: str, local_rank: int = 0) -> torch.device:
    """``auto`` → CUDA (this process's local GPU) if available, else CPU; ``cpu``; ``cuda[:N]``.

    The name is checked by :func:`cerberus_core.devices.check_device` (the config key ``device``)."""
    check_device(name)
    if name == "auto":
        name = "cuda" if torch.cuda.is_available() else "cpu"
    if name.startswith("cuda"):
        return torch.device(name if ":" in name else f"cuda:{local_rank}")
    return torch.device(name)


def init_distributed(device: torch.device) -> DistInfo:
    """Join the process group described by the ``torchrun`` environment (no-op for one process)."""
    env = launch_environment()
    if not env.enabled:
        return DistInfo()
    rank, world, local = env.rank, env.world_size, env.local_rank
    if dist.is_initialized():
        return DistInfo(rank, world, local)
    if device.type == "cuda":
        torch.cuda.set_device(device)
    dist.init_process_group(backend="nccl" if device.type == "cuda" else "gloo")
    return DistInfo(rank, world, local, owns_group=True)


def any_true(flag: bool, info: DistInfo, device: torch.device) -> bool:
    """``flag`` OR-ed over all processes (so every rank takes the same branch)."""
    if not info.enabled:
        return flag
    t = torch.tensor([1.0 if flag else 0.0], device=device)
    dist.all_reduce(t, op=dist.ReduceOp.MAX)
    return bool(t.item() > 0)


def mean_over_ranks(values: dict[str, torch.Tensor], info: DistInfo) -> dict[str, float]:
    """Average scalar tensors over all processes; returns Python floats."""
    keys = sorted(values)
    t = torch.stack([values[k].detach().float().reshape(()) for k in keys])
    if info.enabled:
        dist.all_reduce(t, op=dist.ReduceOp.SUM)
        t = t / info.world_size
    return {k: float(x) for k, x in zip(keys, t.cpu().tolist(), strict=False)}


def barrier(info: DistInfo) -> None:
    if info.enabled:
        dist.barrier()


def shutdown(info: DistInfo) -> None:
    """Leave the process group if :func:`init_distributed` created it."""
    if info.owns_group and dist.is_initialized():
        dist.destroy_process_group()
