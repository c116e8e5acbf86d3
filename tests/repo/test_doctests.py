"""The examples in the packages' docstrings run, and say what they print (doctests, collected here)."""
from __future__ import annotations

import doctest
import importlib

import pytest

from tests.support.paths import REPO

SOURCES = REPO / "packages"


def _modules_with_examples() -> list[str]:
    names = []
    for path in sorted(SOURCES.glob("*/src/cerberus_*/**/*.py")):
        if "vendor" in path.parts or ">>>" not in path.read_text(encoding="utf-8"):
            continue
        parts = path.relative_to(path.parents[len(path.relative_to(SOURCES).parts) - 3]).with_suffix("").parts
        names.append(".".join(p for p in parts if p != "__init__"))
    return names


MODULES = _modules_with_examples()


def test_the_docstring_examples_are_found():
    assert {"cerberus_core.render.ops", "cerberus_core.render.api", "cerberus_core.shapes", "cerberus_core.run",
            "cerberus_core.weights", "cerberus_metrics.api", "cerberus_metrics.scoring", "cerberus_core.eval.standard",
            "cerberus_core.eval.hard", "cerberus_core.eval.report", "cerberus_core.eval.markdown",
            "cerberus_core.eval.runner", "cerberus_core.eval.depth", "cerberus_core.eval.part_quality",
            "cerberus_core.eval.diagnostics", "cerberus_core.eval.export",
            "cerberus_core.eval.accumulators"} <= set(MODULES)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples_run(name):
    pytest.importorskip(name.split(".")[0])
    result = doctest.testmod(importlib.import_module(name), optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.attempted > 0, f"{name} has '>>>' but no doctest ran"
    assert result.failed == 0, f"{result.failed} of {result.attempted} examples of {name} failed (see the output above)"
