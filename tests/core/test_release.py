"""cerberus_core.release: one lock-step version no public index can hold, checked when a backend loads."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
import tomllib

from cerberus_core import __version__
from cerberus_core.errors import ReleaseMismatchError
from cerberus_core.release import DISTRIBUTIONS, VERSION, require_lockstep
from tests.support.paths import REPO


def test_every_package_and_sibling_requirement_is_this_release_with_a_local_label():
    """The local label is what keeps the public index out: PyPI refuses versions that carry one."""
    assert "+" in VERSION and __version__ == VERSION
    for dist in DISTRIBUTIONS:
        project = tomllib.loads((REPO / "packages" / dist / "pyproject.toml").read_text())["project"]
        assert project.get("version", VERSION) == VERSION, dist
        reqs = [*project.get("dependencies", []), *(r for extra in project.get("optional-dependencies", {}).values()
                                                     for r in extra)]
        siblings = {r for r in reqs if r.split("=")[0].split("[")[0].strip() in DISTRIBUTIONS}
        assert siblings <= {f"{d}=={VERSION}" for d in DISTRIBUTIONS}, (dist, siblings)
    core = tomllib.loads((REPO / "packages" / "cerberus-core" / "pyproject.toml").read_text())
    assert core["tool"]["setuptools"]["dynamic"]["version"] == {"attr": "cerberus_core.release.VERSION"}


def test_require_lockstep_names_what_is_installed_and_the_fix():
    require_lockstep("cerberus-render-warp")  # the dev install is one release
    with pytest.raises(ReleaseMismatchError, match=r"cerberus-no-such \(not installed\).*wheelhouse"):
        require_lockstep("cerberus-no-such")


def test_a_foreign_cerberus_core_makes_a_backend_fail_in_one_line(tmp_path: Path):
    """The unrelated project on the public index installs a `cerberus_core` module too: importing our
    backend over it must say so, not fail deep inside with 'No module named cerberus_core.render'."""
    foreign = tmp_path / "site"
    (foreign / "cerberus_core").mkdir(parents=True)
    (foreign / "cerberus_core" / "__init__.py").write_text('"""shared utilities of another project"""\n')
    info = foreign / "cerberus_core-0.1.1.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: cerberus-core\nVersion: 0.1.1\n")
    code = ("import sys; sys.path.insert(0, sys.argv[1]); sys.path.insert(1, sys.argv[2]); "
            "import cerberus_render_torch")
    res = subprocess.run([sys.executable, "-c", code, str(foreign), str(REPO / "packages" / "cerberus-render-torch" / "src")],
                         capture_output=True, text=True, env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"},
                         timeout=120)
    assert res.returncode != 0
    last = res.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: cerberus-render-torch: the installed cerberus-core is not the Cerberus toolkit's")
    assert "pip uninstall cerberus-core" in last
