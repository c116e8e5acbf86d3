"""Renderer backends by name (cerberus_core.render.backends): options checked, and ``auto`` picks warp, then
torch, then others, skipping broken ones."""
from __future__ import annotations

import sys

import pytest

from cerberus_core.errors import UnknownPluginError
from cerberus_core.plugins import RENDERER_GROUP
from cerberus_core.render.backends import available_renderers, make_renderer
from tests.support.dists import BROKEN, WORKING


def test_backend_options_are_checked() -> None:
    with pytest.raises(TypeError, match="unknown options.*bogus"):
        make_renderer("torch", bogus=1)
    assert make_renderer("torch", device="cpu").name == "torch"


def test_auto_picks_warp_then_torch_then_others_skipping_broken_ones(fake_dist, monkeypatch, tmp_path) -> None:
    from cerberus_core.render.backends import resolve_renderer

    assert resolve_renderer("torch") == "torch"  # a plain name is taken as it is
    expected = "warp" if "warp" in available_renderers() else "torch"
    assert resolve_renderer("auto") == expected and make_renderer().name == expected
    # Only non-preferred backends installed: the first by name that imports; a broken one is skipped.
    root = fake_dist("fake-broken-render", {RENDERER_GROUP: {"aaa": "fake_broken_backend:Renderer"}}, BROKEN)
    fake_dist("fake-good-render", {RENDERER_GROUP: {"good": "fake_good_backend:GoodRenderer"}}, WORKING)
    monkeypatch.syspath_prepend(str(root))
    assert resolve_renderer("auto", path=[str(root)]) == "good"
    sys.modules.pop("fake_good_backend", None)
    with pytest.raises(UnknownPluginError, match=r"renderer 'auto': no renderer backend.*pip install cerberus-render"):
        resolve_renderer("auto", path=[str(tmp_path / "empty")])
