"""Cerberus: a multi-headed derenderer (Deng, Kornblith, Hinton).

The core package: camera, mesh templates, the renderer interface and its shared differentiable
shading, plugin discovery, and (in sub-packages) data, model, training and evaluation. Renderer
backends live in separate packages found through the ``cerberus.renderers`` entry-point group.

The two objects a notebook starts from: :class:`~cerberus_core.run.Run` (a trained run:
``Run.load("human")``, ``run.model``, ``run.evaluate(...)``) and
:class:`~cerberus_core.datasets.format.Manifest` (a dataset's manifest: ``Manifest.read(root)``).
"""
import importlib
from typing import Any

from cerberus_core.release import VERSION
from cerberus_core.render.api import render, render_parts
from cerberus_core.render.backends import available_renderers, make_renderer, resolve_renderer
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Light, Renderer, RenderOutput
from cerberus_core.render.templates import MeshTemplate, icosphere

__version__ = VERSION

#: Exported names loaded on first use: they bring the data, model and evaluation stack (scipy, trimesh),
#: and ``import cerberus_core.render`` must need torch alone (tests/core/test_core_imports.py).
_LAZY = {"Run": "cerberus_core.run", "Manifest": "cerberus_core.datasets.format"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        return getattr(importlib.import_module(_LAZY[name]), name)
    raise AttributeError(f"module 'cerberus_core' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted([*globals(), *_LAZY])


__all__ = [
    "Camera",
    "Light",
    "Manifest",
    "MeshTemplate",
    "RenderOutput",
    "Renderer",
    "Run",
    "available_renderers",
    "icosphere",
    "make_renderer",
    "resolve_renderer",
    "render",
    "render_parts",
]
