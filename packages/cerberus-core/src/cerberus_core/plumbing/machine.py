"""What this machine can honour: its cores and its memory, and the checks that hold a setting to them
before anything is allocated.

* :func:`capped_to_cores` — a count of threads or worker processes above the machine's cores is
  lowered to them, with a warning naming the setting (going on is right: the run is the same);
* :func:`check_memory` — a setting whose memory estimate exceeds the machine's memory is a
  :class:`~cerberus_core.errors.ConfigError` naming the setting, the estimate and the limit.
"""
from __future__ import annotations

import os
import warnings
from pathlib import Path

from cerberus_core.errors import ConfigError

__all__ = ["MAX_WORKERS", "capped_to_cores", "check_memory", "cores", "memory_bytes", "size_text"]

MAX_WORKERS = 256
"""The most data-loading worker processes a setting may ask for (more than the machine's cores are lowered to
them when the work starts: :func:`capped_to_cores`)."""


def cores() -> int:
    """The cores this process may run on (its CPU affinity where the system says, else all)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):
        return max(1, os.cpu_count() or 1)


def memory_bytes(device: object = "cpu") -> int | None:
    """The memory a run on ``device`` may use, in bytes: a CUDA device's own memory, else the machine's
    physical memory or, when smaller, the control group's limit (a container's); ``None`` where the system
    does not say (no ``sysconf``)."""
    if str(device).startswith("cuda"):
        import torch

        return int(torch.cuda.get_device_properties(torch.device(str(device))).total_memory)
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return None
    for limit in ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory/memory.limit_in_bytes"):
        try:
            text = Path(limit).read_text().strip()
        except OSError:
            continue
        if text.isdigit():
            total = min(total, int(text))
    return int(total)


def size_text(n: float) -> str:
    """``1536`` → ``"1.5 KiB"`` (powers of 1024, one decimal)."""
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if n < 1024:
            return f"{n:.1f} {unit}" if unit != "B" else f"{int(n)} B"
        n /= 1024
    return f"{n:.1f} PiB"


def check_memory(key: str, value: object, need: float, what: str, device: object = "cpu") -> None:
    """:class:`ConfigError` when ``need`` bytes (what ``key = value`` implies, ``what`` says how) exceed
    the memory of ``device`` (:func:`memory_bytes`); nothing has been allocated yet."""
    limit = memory_bytes(device)
    if limit is not None and need > limit:
        raise ConfigError.about(key, value, f"needs at least {size_text(need)} of memory ({what}), more than the "
                                f"{size_text(limit)} this machine has; choose a smaller `{key}`")


def capped_to_cores(key: str, value: int) -> int:
    """``value`` (threads or worker processes of ``key``), or the machine's cores where it is more, with a
    warning naming the setting."""
    n = cores()
    if value > n:
        warnings.warn(f"{key}={value} is more than this machine's {n} cores: using {n} (`{key}={n}`)", stacklevel=3)
        return n
    return value
