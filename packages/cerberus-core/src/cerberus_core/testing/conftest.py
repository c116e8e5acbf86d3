"""Fixtures of the conformance suite: one parametrisation per installed renderer backend.

* ``--renderer NAME`` (repeatable; or ``CERBERUS_RENDERERS=a,b``): the backends to check, default
  every installed one;

* ``backend_name`` / ``renderer``: every backend found by
  :func:`cerberus_core.render.backends.available_renderers` (narrowed by ``--renderer`` or
  ``CERBERUS_RENDERERS``); a test that takes ``renderer`` runs once per backend.
* ``other_backend_name``: every selected backend except the reference one (``torch``), for the
  cross-backend comparisons; those tests are skipped when only one backend is installed.
* ``grad_dtype``: float64 if the backend's full render path keeps float64 end to end, else float32.
"""
from __future__ import annotations

import os

import pytest
import torch

from cerberus_core.errors import PluginError
from cerberus_core.plugins import RENDERER_GROUP, get_plugin
from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import available_renderers, make_renderer

from .scenes import body_scene, double_camera

REFERENCE_BACKEND = "torch"
"""The backend the others are compared with (the pure-torch one, itself checked against numpy)."""


_SELECTED = pytest.StashKey[list]()


def pytest_addoption(parser: pytest.Parser) -> None:
    parser.addoption("--renderer", action="append", default=None, metavar="NAME",
                     help="run the renderer conformance suite against this backend only (repeatable; "
                     "default: every installed backend; env CERBERUS_RENDERERS=a,b does the same)")


def selected_backends(config: pytest.Config) -> list[str]:
    """Backends to run: the ``--renderer`` / ``CERBERUS_RENDERERS`` selection or all installed
    (worked out once per session)."""
    if _SELECTED not in config.stash:
        config.stash[_SELECTED] = _select(config)
    return config.stash[_SELECTED]


def _select(config: pytest.Config) -> list[str]:
    requested = config.getoption("--renderer", default=None)
    if not requested and os.environ.get("CERBERUS_RENDERERS"):
        requested = [n.strip() for n in os.environ["CERBERUS_RENDERERS"].split(",") if n.strip()]
    if not requested:
        return available_renderers()
    for name in requested:
        try:
            get_plugin(RENDERER_GROUP, name)
        except PluginError as exc:
            raise pytest.UsageError(f"conformance suite: cannot use renderer '{name}': {exc}") from exc
    return list(dict.fromkeys(requested))


def pytest_configure(config: pytest.Config) -> None:
    selected_backends(config)  # a bad --renderer stops the run here, once, with the plugin error


def pytest_generate_tests(metafunc: pytest.Metafunc) -> None:
    names = None
    if "backend_name" in metafunc.fixturenames:
        names = selected_backends(metafunc.config)
        metafunc.parametrize("backend_name", names, scope="session")
    if "other_backend_name" in metafunc.fixturenames:
        names = names if names is not None else selected_backends(metafunc.config)
        installed = available_renderers()
        others = [n for n in names if n != REFERENCE_BACKEND] if REFERENCE_BACKEND in installed else []
        metafunc.parametrize("other_backend_name", others, scope="session")


@pytest.fixture(scope="session")
def renderer(backend_name: str):
    return make_renderer(backend_name)


@pytest.fixture(scope="session")
def other_renderer(other_backend_name: str):
    return make_renderer(other_backend_name)


@pytest.fixture(scope="session")
def reference_renderer():
    if REFERENCE_BACKEND not in available_renderers():
        pytest.skip(f"the reference backend '{REFERENCE_BACKEND}' (cerberus-render-torch) is not installed")
    return make_renderer(REFERENCE_BACKEND)


@pytest.fixture(scope="session")
def grad_dtype(renderer) -> torch.dtype:
    """float64 when rendering float64 geometry with this backend stays float64 (images, depths and
    gradients), so finite differences can use a tiny step; float32 otherwise."""
    parts, faces, camera = body_scene(1, num_parts=1, image_size=16, level=1, dtype=torch.float64)
    parts.requires_grad_(True)
    try:
        out = render_parts(renderer, parts, faces, double_camera(camera))
        out.image.sum().backward()
    except (TypeError, ValueError, RuntimeError):
        return torch.float32
    ok = out.image.dtype == out.depth.dtype == parts.grad.dtype == torch.float64
    return torch.float64 if ok else torch.float32
