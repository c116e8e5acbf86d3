"""The torch backend's rasterizer (cerberus_render_torch.rasterize) as users configure it: its options.

Its pictures are held to the reference by the renderer conformance suite (``cerberus_core/testing``), and the
Warp rasterizer to its face ids by ``tests/render_warp/test_rasterize.py``."""
from __future__ import annotations

import pytest
import torch

from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import make_renderer
from tests.support.scenes import two_sphere_scene


def test_torch_backend_options() -> None:
    parts, faces, cam = two_sphere_scene()
    small = make_renderer("torch", max_candidates=500)  # many chunks: the same picture
    chunked = render_parts(small, parts, faces, cam).face_id
    assert torch.equal(chunked, render_parts(make_renderer("torch"), parts, faces, cam).face_id)
    with pytest.raises(ValueError, match="max_candidates"):
        make_renderer("torch", max_candidates=0)
