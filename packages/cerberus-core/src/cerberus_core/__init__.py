"""Cerberus: a multi-headed derenderer (Deng, Kornblith, Hinton).

The core package: camera, mesh templates, the renderer interface and its shared differentiable
shading, plugin discovery, and (in sub-packages) data, model, training and evaluation. Renderer
backends live in separate packages found through the ``cerberus.renderers`` entry-point group.

The two objects a notebook starts from: :class:`~cerberus_core.run.Run` (a trained run:
``Run.load("human")``, ``run.model``, ``run.evaluate(...)``) and
:class:`~cerberus_core.datasets.dataset.Dataset` (a dataset folder: ``Dataset.open(root)``,
``Dataset.generate(config, out)``).
"""
import importlib
from typing import Any

from cerberus_core.release import VERSION

__version__ = VERSION

#: Every exported name, loaded on first use: ``import cerberus_core`` itself imports nothing heavy (no
#: torch), so the ``cerberus`` command can take charge of Ctrl-C before anything slow is imported, and
#: ``import cerberus_core.render`` needs torch alone (tests/core/render/test_init.py). The function
#: ``render`` is ``cerberus_core.render.render`` (``cerberus_core.render`` is its sub-package).
_LAZY = {
    "render_parts": "cerberus_core.render.api",
    "available_renderers": "cerberus_core.render.backends", "make_renderer": "cerberus_core.render.backends",
    "resolve_renderer": "cerberus_core.render.backends", "Camera": "cerberus_core.render.camera",
    "Light": "cerberus_core.render.interface", "Renderer": "cerberus_core.render.interface",
    "RenderOutput": "cerberus_core.render.interface", "MeshTemplate": "cerberus_core.render.templates",
    "icosphere": "cerberus_core.render.templates", "Run": "cerberus_core.run",
    "Dataset": "cerberus_core.datasets.dataset",
}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'cerberus_core' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])


__all__ = [
    "Camera",
    "Dataset",
    "Light",
    "MeshTemplate",
    "RenderOutput",
    "Renderer",
    "Run",
    "available_renderers",
    "icosphere",
    "make_renderer",
    "resolve_renderer",
    "render_parts",
]
