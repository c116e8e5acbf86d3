"""The one check of a torch device name, for every layer that takes one (``--device``, a config's
``device``, :func:`cerberus_core.datasets.generate.validate_generation`): it raises
:class:`~cerberus_core.errors.ConfigError` before anything is allocated or written."""
from __future__ import annotations

from cerberus_core.errors import ConfigError


def check_device(name: str, option: str = "--device") -> str:
    """``cpu``, ``cuda`` or ``cuda:N`` that exists here, or ``auto``; returns ``name``.

    Args:
        option: how the message names the setting: a flag (``--device``) or a config key (``device``,
            which the fix then sets with ``--set``).
    """
    import torch

    cpu = f"{option} cpu" if option.startswith("--") else f"--set {option}=cpu"
    if name in ("auto", "cpu"):
        return name
    if name == "cuda" or name.startswith("cuda:"):
        if not torch.cuda.is_available():
            raise ConfigError(f"{option} {name}: CUDA is not available on this machine; use {cpu}")
        index = name.partition(":")[2]
        if index and (not index.isdigit() or int(index) >= torch.cuda.device_count()):
            raise ConfigError(f"{option} {name}: no such GPU (this machine has {torch.cuda.device_count()}); "
                              f"use {option} cuda:0 .. cuda:{torch.cuda.device_count() - 1}")
        return name
    raise ConfigError(f"{option} {name!r}: expected cpu, cuda or cuda:N (or auto)")


__all__ = ["check_device"]
