"""The tests run the linter: ``ruff check .`` over the repository, with its configuration in the root
``pyproject.toml`` (style, imports, bugbear, and the C901 complexity limit)."""
from __future__ import annotations

import importlib.util
import shutil
import subprocess
import sys

import pytest

from tests.support.paths import REPO


def _ruff() -> list[str] | None:
    if importlib.util.find_spec("ruff") is not None:
        return [sys.executable, "-m", "ruff"]
    exe = shutil.which("ruff")
    return [exe] if exe else None


def test_ruff_check_passes() -> None:
    ruff = _ruff()
    if ruff is None:
        pytest.skip("ruff is not installed (pip install ruff)")
    res = subprocess.run([*ruff, "check", "--no-cache", "."], cwd=REPO, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr


def test_the_complexity_limit_is_configured() -> None:
    text = (REPO / "pyproject.toml").read_text(encoding="utf-8")
    assert '"C901"' in text and "max-complexity = " in text
