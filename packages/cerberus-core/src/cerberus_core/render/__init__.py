"""Rendering: the backend contract (:mod:`.interface`), the shared differentiable shading
(:mod:`.shading`) and the user-facing entry points :func:`render` / :func:`render_parts` (:mod:`.api`)."""
from cerberus_core.render.api import render, render_parts
from cerberus_core.render.interface import Light, Renderer, RenderOutput

__all__ = ["Light", "RenderOutput", "Renderer", "render", "render_parts"]
