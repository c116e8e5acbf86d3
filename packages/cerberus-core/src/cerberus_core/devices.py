"""The one check of a torch device name, for every layer that takes one (a ``device`` parameter, a
config's ``device``, :func:`cerberus_core.datasets.generate.validate_generation`): it raises
:class:`~cerberus_core.errors.ConfigError` before anything is allocated or written."""
from __future__ import annotations

from cerberus_core.errors import ConfigError


def is_device_name(name: object) -> bool:
    """Whether ``name`` is written as a device: ``auto``, ``cpu``, ``cuda`` or ``cuda:N`` (whether that
    device exists here is :func:`check_device`'s question, asked where it is used)."""
    return isinstance(name, str) and (name in ("auto", "cpu", "cuda") or
                                      (name.startswith("cuda:") and name[5:].isdigit()))


def check_device(name: str) -> str:
    """``cpu``, ``cuda`` or ``cuda:N`` that exists here, or ``auto``; returns ``name``. A
    :class:`ConfigError` otherwise, about the setting ``device`` (every layer's name for it)."""
    import torch

    if name in ("auto", "cpu"):
        return name
    if not is_device_name(name):
        raise ConfigError.about("device", name, "expected cpu, cuda or cuda:N (or auto)")
    if not torch.cuda.is_available():  # name is cuda or cuda:N from here on
        raise ConfigError.about("device", name, "CUDA is not available on this machine; use `device=cpu`")
    index, count = name.partition(":")[2], torch.cuda.device_count()
    if index and int(index) >= count:
        raise ConfigError.about("device", name, f"no such GPU (this machine has {count}); use cuda:0 .. cuda:{count - 1}")
    return name


def cpu_flags() -> frozenset[str]:
    """The processor's feature flags as Linux reports them (``/proc/cpuinfo``: x86 ``flags``, Arm
    ``Features``), lower case; empty where that file does not exist (macOS, Windows)."""
    try:
        text = open("/proc/cpuinfo", encoding="ascii", errors="replace").read()
    except OSError:
        return frozenset()
    flags: set[str] = set()
    for line in text.splitlines():
        key, _, value = line.partition(":")
        if key.strip().lower() in ("flags", "features"):
            flags.update(value.lower().split())
    return frozenset(flags)


NATIVE_BF16_FLAGS = ("avx512_bf16", "amx_bf16", "bf16")
"""CPU flags of native bfloat16 arithmetic: AVX512_BF16 and AMX (x86), BF16 (Arm v8.6). Without one,
oneDNN emulates bfloat16 matrix products and they run slower than float32 (docs/training.md, "Speed")."""


def native_bf16(device: str = "cpu", flags: frozenset[str] | None = None) -> tuple[bool, str]:
    """Whether ``device`` computes bfloat16 natively, and why, in words.

    Args:
        device: ``cpu``, ``cuda`` or ``cuda:N``.
        flags: the CPU's flags (default: :func:`cpu_flags`; given by tests).
    Returns:
        ``(native, reason)``, e.g. ``(True, "this CPU has avx512_bf16")``.
    """
    import torch

    if str(device).startswith("cuda"):
        ok = torch.cuda.is_available() and torch.cuda.is_bf16_supported()
        return ok, "this GPU " + ("supports" if ok else "does not support") + " bfloat16"
    have = [f for f in NATIVE_BF16_FLAGS if f in (cpu_flags() if flags is None else flags)]
    if have:
        return True, f"this CPU has {'/'.join(have)}"
    return False, f"this CPU has none of {'/'.join(NATIVE_BF16_FLAGS)} (bfloat16 would be emulated, slower than float32)"


__all__ = ["check_device", "cpu_flags", "native_bf16"]
