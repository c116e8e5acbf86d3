"""The repository's root, for tests that read its files (docs, experiments, pyproject.toml, the packages'
sources): ``REPO / "docs" / "training.md"``, the same from any depth of the test tree."""
from __future__ import annotations

from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
