"""Fixtures of the Warp backend's own tests (skipped as a whole when Warp is not installed)."""
from __future__ import annotations

import pytest

pytest.importorskip("warp", reason="the warp backend tests need warp-lang")


@pytest.fixture(scope="session")
def warp_renderer():
    from cerberus_core import make_renderer

    return make_renderer("warp")
