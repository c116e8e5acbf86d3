"""The training tests run on one intra-op thread (``one_thread``, from ``tests/core/conftest.py``), each
of them; the tests of the ``cerberus train`` command and of ``Run`` ask for it by name."""
from __future__ import annotations

import pytest


@pytest.fixture(autouse=True)
def _one_thread(one_thread):
    yield
