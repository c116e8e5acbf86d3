"""A real install of ``cerberus-core`` + ``cerberus-render-warp`` alone (no torch backend, no metrics)
gives a working renderer: built as wheels by pip from the local paths into a fresh folder, then used
from an interpreter whose path holds that folder and the third-party dependencies only."""
from __future__ import annotations

import os
import subprocess
import sys
import sysconfig
import textwrap
from pathlib import Path

import pytest

from tests.support.paths import REPO

pytestmark = pytest.mark.slow


USE = textwrap.dedent("""
    import site, sys
    site.addsitedir(sys.argv[1]); site.addsitedir(sys.argv[2])
    import torch
    from cerberus_core import Camera, available_renderers, icosphere, make_renderer, render_parts
    from cerberus_core.plugins import UnknownPluginError
    print("renderers", available_renderers())
    r = make_renderer()  # auto
    sphere = icosphere(2)
    parts = 0.2 * sphere.vertices.expand(1, 2, -1, -1) + torch.tensor([[-.3, 0, 0], [.3, 0, 0]]).view(1, 2, 1, 3)
    parts.requires_grad_(True)
    out = render_parts(r, parts, sphere.faces, Camera.look_at(30.0, 10.0, 2.5, image_size=32))
    out.image.mean().backward()
    print("auto", r.name, "covered", int(out.alpha.sum()), "grad", bool(parts.grad.abs().sum() > 0))
    try:
        make_renderer("torch")
    except UnknownPluginError as exc:
        print("torch missing:", exc)
""")


def test_core_and_warp_alone_render(tmp_path: Path) -> None:
    target = tmp_path / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--disable-pip-version-check", "--no-deps",
                    "--no-build-isolation", "--no-index", "--target", str(target),
                    str(REPO / "packages" / "cerberus-core"), str(REPO / "packages" / "cerberus-render-warp")],
                   check=True, capture_output=True, text=True, env={**os.environ, "PIP_NO_INPUT": "1"})
    installed = sorted(p.name for p in target.glob("*.dist-info"))
    assert [n.split("-")[0] for n in installed] == ["cerberus_core", "cerberus_render_warp"]
    # The dependencies (torch, warp, ...) without any cerberus distribution of the dev environment.
    deps = tmp_path / "deps"
    deps.mkdir()
    for entry in Path(sysconfig.get_paths()["purelib"]).iterdir():
        if not entry.name.lower().replace("-", "_").lstrip("_").removeprefix("editable__.").startswith("cerberus"):
            (deps / entry.name).symlink_to(entry)
    res = subprocess.run([sys.executable, "-S", "-c", USE, str(target), str(deps)], capture_output=True, text=True,
                         cwd=tmp_path, env={k: v for k, v in os.environ.items() if k != "PYTHONPATH"}, timeout=600)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert "renderers ['warp']" in lines
    auto = next(line for line in lines if line.startswith("auto"))
    assert auto.startswith("auto warp covered") and auto.endswith("grad True") and int(auto.split()[3]) > 50
    assert any("torch missing:" in line and "pip install cerberus-render-torch" in line for line in lines)


def test_the_wheelhouse_builds_from_a_clean_copy(tmp_path: Path) -> None:
    """Issue 34: a module left in a package's stale ``build/lib`` (deleted from ``src/`` since) never ships."""
    import zipfile

    stale = REPO / "packages" / "cerberus-metrics" / "build" / "lib" / "cerberus_metrics"
    made = not stale.exists()
    stale.mkdir(parents=True, exist_ok=True)
    (stale / "stale_module.py").write_text("STALE = 1\n")
    try:
        subprocess.run(["bash", str(REPO / "scripts" / "wheelhouse.sh"), str(tmp_path)], check=True,
                       capture_output=True, text=True, env={**os.environ, "PYTHON": sys.executable})
    finally:
        (stale / "stale_module.py").unlink()
        if made:
            import shutil

            shutil.rmtree(REPO / "packages" / "cerberus-metrics" / "build")
    wheel = next(tmp_path.glob("cerberus_metrics-*.whl"))
    names = zipfile.ZipFile(wheel).namelist()
    assert "cerberus_metrics/cli.py" in names and not any("stale_module" in n for n in names)
