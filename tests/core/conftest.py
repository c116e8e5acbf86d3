"""Fixtures of the core unit tests: fake installed distributions for plugin discovery."""
from __future__ import annotations

import textwrap
from collections.abc import Callable
from pathlib import Path

import pytest


def write_distribution(root: Path, dist: str, entry_points: dict[str, dict[str, str]],
                       modules: dict[str, str] | None = None, version: str = "0.1") -> Path:
    """Lay out an installed distribution the way pip does: ``NAME-VERSION.dist-info/`` with METADATA
    and entry_points.txt, plus top-level modules, under ``root``.

    Args:
        dist: distribution name (``fake-render``).
        entry_points: ``{group: {name: "module:object"}}``.
        modules: ``{module_name: source}`` written as ``root/module_name.py``.
    """
    info = root / f"{dist.replace('-', '_')}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {dist}\nVersion: {version}\n")
    lines = []
    for group, eps in entry_points.items():
        lines.append(f"[{group}]")
        lines += [f"{name} = {target}" for name, target in eps.items()]
    (info / "entry_points.txt").write_text("\n".join(lines) + "\n")
    for name, source in (modules or {}).items():
        (root / f"{name}.py").write_text(textwrap.dedent(source))
    return info


@pytest.fixture
def fake_dist(tmp_path: Path) -> Callable[..., Path]:
    """``fake_dist(dist, entry_points, modules, folder="site")`` writes a fake distribution into
    ``tmp_path / folder`` and returns that folder (pass ``path=[str(it)]`` to the discovery
    functions, or put it on sys.path)."""

    def make(dist: str, entry_points: dict[str, dict[str, str]], modules: dict[str, str] | None = None,
             folder: str = "site") -> Path:
        root = tmp_path / folder
        write_distribution(root, dist, entry_points, modules)
        return root

    return make
