"""The repository's root, for tests that read its files (docs, experiments, pyproject.toml, the packages'
sources): ``REPO / "docs" / "training.md"``, the same from any depth of the test tree; and
:func:`load_script`, for tests of the scripts under ``experiments/``, which are not packages."""
from __future__ import annotations

import functools
import importlib.util
from pathlib import Path
from types import ModuleType

REPO = Path(__file__).resolve().parents[2]


@functools.cache
def load_script(relative: str) -> ModuleType:
    """The script ``REPO / relative`` (e.g. ``"experiments/depth/depth_oracle.py"``) imported as a module named
    after its file, once per test session; its ``main`` does not run."""
    path = REPO / relative
    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module
