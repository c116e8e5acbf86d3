"""Argument checks shared by the sub-commands: argparse types for numbers, and path / device checks
that raise :class:`~cerberus_core.errors.ConfigError` before a command writes anything."""
from __future__ import annotations

import argparse
import math
from pathlib import Path

from cerberus_core.errors import ConfigError

MANIFEST_NAME = "manifest.json"


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


def finite_float(text: str) -> float:
    """argparse type: a finite number (no nan / inf)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line (exit 2), like every other CLI error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: {message}; see {self.prog} --help\n")


def output_folder(path: Path, option: str = "--out") -> Path:
    """``path`` may be created as a folder: not an existing file, nor under one."""
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                what = "is a file" if p == path else f"is under {p}, which is a file"
                raise ConfigError(f"{option} {path} {what}; pass a folder path")
            break
    return path


def check_device(name: str, option: str = "--device") -> str:
    """``cpu``, ``cuda`` or ``cuda:N`` that exists here, or ``auto``."""
    import torch

    if name in ("auto", "cpu"):
        return name
    if name == "cuda" or name.startswith("cuda:"):
        if not torch.cuda.is_available():
            raise ConfigError(f"{option} {name}: CUDA is not available on this machine; use {option} cpu")
        index = name.partition(":")[2]
        if index and (not index.isdigit() or int(index) >= torch.cuda.device_count()):
            raise ConfigError(f"{option} {name}: no such GPU (this machine has {torch.cuda.device_count()}); "
                              f"use {option} cuda:0 .. cuda:{torch.cuda.device_count() - 1}")
        return name
    raise ConfigError(f"{option} {name!r}: expected cpu, cuda or cuda:N")


def is_dataset(path: Path) -> bool:
    return (Path(path) / MANIFEST_NAME).is_file()
