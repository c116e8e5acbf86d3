"""Fake installed distributions for the plugin-discovery tests (the ``fake_dist`` fixture of ``tests/conftest.py``
lays them out in a temporary folder)."""
from __future__ import annotations

import textwrap
from pathlib import Path

# top-level modules of fake renderer distributions: one that fails to import, one that works
BROKEN = {"fake_broken_backend": "raise ImportError('libfake.so: cannot open shared object file')\n"}
WORKING = {"fake_good_backend": """
    from cerberus_core.render.interface import Renderer

    class GoodRenderer(Renderer):
        name = "good"

        def rasterize(self, clip, faces, height, width, near):
            raise NotImplementedError
    """}


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
