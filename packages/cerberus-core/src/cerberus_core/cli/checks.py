"""Argument checks shared by the sub-commands: argparse types for numbers, and path checks that raise
:class:`~cerberus_core.errors.ConfigError` before a command writes anything (the device check is
:func:`cerberus_core.devices.check_device`, which library code uses too)."""
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


def output_folder(path: Path, option: str = "--out", *, dataset_ok: bool = False) -> Path:
    """``path`` may be created as a folder: not an existing file, nor under one, nor (unless
    ``dataset_ok``: ``data generate`` resumes there) a dataset folder, whose files are not results."""
    for p in (path, *path.parents):
        if p.exists():
            if not p.is_dir():
                what = "is a file" if p == path else f"is under {p}, which is a file"
                raise ConfigError(f"{option} {path} {what}; pass a folder path")
            break
    if not dataset_ok and is_dataset(path):
        raise ConfigError(f"{option} {path} is a dataset folder; write results to another folder")
    return path


def output_file(path: Path, option: str = "--out") -> Path:
    """``path`` may be written as a file: not an existing folder, nor under a file."""
    if path.is_dir():
        raise ConfigError(f"{option} {path} is a folder; pass a file path")
    for p in path.parents:
        if p.exists():
            if not p.is_dir():
                raise ConfigError(f"{option} {path} is under {p}, which is a file; pass a path inside a folder")
            break
    return path


def is_dataset(path: Path) -> bool:
    return (Path(path) / MANIFEST_NAME).is_file()
