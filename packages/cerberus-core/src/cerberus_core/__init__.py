"""Cerberus: a multi-headed derenderer (Deng, Kornblith, Hinton).

The core package: camera, mesh templates, the renderer interface and its shared differentiable
shading, plugin discovery, and (in sub-packages) data, model, training and evaluation. Renderer
backends live in separate packages found through the ``cerberus.renderers`` entry-point group.
"""
from cerberus_core.plugins import available_renderers, make_renderer, resolve_renderer
from cerberus_core.render.api import render, render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Light, Renderer, RenderOutput
from cerberus_core.render.templates import MeshTemplate, icosphere

__version__ = "0.1.0"

__all__ = [
    "Camera",
    "Light",
    "MeshTemplate",
    "RenderOutput",
    "Renderer",
    "available_renderers",
    "icosphere",
    "make_renderer",
    "resolve_renderer",
    "render",
    "render_parts",
]
