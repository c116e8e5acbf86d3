"""docs/backends.md's worked minimal backend, run as written through the conformance suite of the installed
core (python -m cerberus_core.testing), registered through a real entry point like a third-party package."""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.support.paths import REPO


def _guide_backend() -> str:
    text = (REPO / "docs" / "backends.md").read_text()
    block = re.search(r"```python\n(# minimal_backend\.py\n.*?)```", text, re.S)
    assert block, "docs/backends.md lost its worked backend"
    return block.group(1)


@pytest.mark.slow
def test_the_guides_minimal_backend_passes_the_whole_suite(tmp_path: Path, fake_dist):
    """Issue 34: the whole suite, as the guide tells its reader to run it (no face, degenerate faces included)."""
    site = fake_dist("minimal-backend", {"cerberus.renderers": {"minimal": "minimal_backend:MinimalRenderer"}},
                     {"minimal_backend": _guide_backend()})
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(site), os.environ.get("PYTHONPATH", "")]),
           "OMP_NUM_THREADS": "1"}
    listed = subprocess.run([sys.executable, "-m", "cerberus_core.cli", "renderers"], capture_output=True, text=True,
                            env=env, timeout=300)
    assert re.search(r"^\s+minimal\s+minimal-backend\s+0\.1\s+ok$", listed.stdout, re.M), listed.stdout + listed.stderr
    res = subprocess.run([sys.executable, "-m", "cerberus_core.testing", "--renderer", "minimal", "-q"],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=1800)
    tail = res.stdout.strip().splitlines()[-1]
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-2000:]
    assert re.search(r"\d+ passed", tail) and "failed" not in tail, tail


def test_the_suite_has_its_own_help():
    res = subprocess.run([sys.executable, "-m", "cerberus_core.testing", "--help"], capture_output=True, text=True,
                         timeout=120)
    assert res.returncode == 0 and res.stdout.startswith("usage: python -m cerberus_core.testing")
    assert "--renderer NAME" in res.stdout and len(res.stdout.splitlines()) < 30
