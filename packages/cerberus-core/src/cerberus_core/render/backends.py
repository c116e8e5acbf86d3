"""Renderer backends by name: the one place a :class:`~cerberus_core.render.interface.Renderer` is
built (:func:`make_renderer`), and what ``auto`` picks (:func:`resolve_renderer`).

Backends are found through the ``cerberus.renderers`` entry points (:mod:`cerberus_core.plugins`);
core never imports a backend package by name.
"""
from __future__ import annotations

from typing import Any

from cerberus_core.errors import PluginLoadError, UnknownPluginError
from cerberus_core.plugins import KNOWN_PACKAGES, RENDERER_GROUP, get_plugin, plugin_table
from cerberus_core.render.interface import Renderer

__all__ = ["AUTO_RENDERER", "RENDERER_PREFERENCE", "available_renderers", "make_renderer", "resolve_renderer"]


def available_renderers(path: list[str] | None = None) -> list[str]:
    """Names of renderer backends that are installed and import cleanly."""
    return [r["name"] for r in plugin_table(RENDERER_GROUP, path) if r["status"] == "ok"]


AUTO_RENDERER = "auto"
"""The renderer name that means "the best installed backend" (the default everywhere)."""

RENDERER_PREFERENCE = ("warp", "torch")
"""The order in which ``auto`` picks a backend: Warp's compiled kernels first (several times faster
on a CPU, see ``benchmarks/bench_render.py``), then pure PyTorch, then any other by name. Backends
agree to 1e-5 (the conformance suite), so the choice changes speed, not results."""


def resolve_renderer(name: str = AUTO_RENDERER, path: list[str] | None = None) -> str:
    """The backend a renderer name stands for: ``name`` itself, or, for ``"auto"``, the first backend
    in :data:`RENDERER_PREFERENCE` order that is installed and imports cleanly.

    Raises:
        UnknownPluginError: ``"auto"`` with no working backend installed.
    """
    if name != AUTO_RENDERER:
        return name
    ok = available_renderers(path)
    order = [n for n in RENDERER_PREFERENCE if n in ok] + sorted(n for n in ok if n not in RENDERER_PREFERENCE)
    if not order:
        packages = " or ".join(f"`pip install {p}`" for p in KNOWN_PACKAGES[RENDERER_GROUP].values())
        raise UnknownPluginError(f"renderer 'auto': no renderer backend is installed and working "
                                 f"(`cerberus renderers` shows why); install one: {packages}.")
    return order[0]


def make_renderer(name: str = AUTO_RENDERER, **options: Any):
    """Build a renderer backend by name (as a config file or ``--renderer`` flag names it).

    Args:
        name: entry-point name, e.g. ``"torch"`` or ``"warp"``, or ``"auto"``
            (:func:`resolve_renderer`: Warp if it works, else torch).
        **options: passed to the backend's constructor.
    """
    name = resolve_renderer(name)
    cls = get_plugin(RENDERER_GROUP, name)
    renderer = cls(**options)
    if not isinstance(renderer, Renderer):
        raise PluginLoadError(f"renderer plugin '{name}' built {type(renderer).__name__}, which is not a cerberus_core Renderer")
    return renderer
