"""Rendering: the camera and the pixel-centre rule (:mod:`.camera`), the light (:mod:`.light`), the
backend contract (:mod:`.interface`), the shared differentiable shading and anti-aliasing
(:mod:`.shading`, :mod:`.antialias`), the ops as free functions over a backend, after nvdiffrast
(:mod:`.ops`: ``rasterize``, ``interpolate``, ``vertex_normals``, ``shade``, ``antialias``) and the
user-facing entry points :func:`render` / :func:`render_parts` (:mod:`.api`), which compose them.

Within the package imports point one way: camera, light, templates <- shading <- antialias <-
interface <- ops <- api."""
from cerberus_core.render import ops
from cerberus_core.render.api import render, render_parts
from cerberus_core.render.interface import Renderer, RenderOutput
from cerberus_core.render.light import Light

__all__ = ["Light", "RenderOutput", "Renderer", "ops", "render", "render_parts"]
