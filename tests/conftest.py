"""Repository-wide pytest set-up. (The renderer conformance suite, and its ``--renderer`` option, ship in
the core package: ``cerberus_core/testing``, collected by the suite through ``testpaths``.)

The ``chromium`` fixture runs headless Chromium for the 3D viewer's tests (skipped where it is missing);
``fake_dist`` lays out fake installed distributions for the plugin-discovery tests.
"""
from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from tests.support.dists import write_distribution


# ------------------------------------------------------------------ headless Chromium (the 3D viewer's tests)
class HeadlessChromium:
    """Debian's ``chromium`` run headless, with WebGL on SwiftShader (no GPU needed) and a profile of its own.

    ``dump_dom`` and ``screenshot`` return the page's console messages too (``--enable-logging``)."""

    def __init__(self, exe: str, workdir) -> None:
        self.exe, self.workdir, self.runs = exe, workdir, 0

    def _run(self, url: str, *args: str, timeout: float = 180):
        import re
        import subprocess

        self.runs += 1
        cmd = [self.exe, "--headless", "--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
               "--no-first-run", "--disable-extensions", "--hide-scrollbars", "--mute-audio",
               f"--user-data-dir={self.workdir / f'profile{self.runs}'}", "--virtual-time-budget=30000",
               "--enable-logging=stderr", "--v=0", *args, url]
        proc = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
        console = [m.group(1) for m in re.finditer(r":CONSOLE[^\]]*\] (.*)", proc.stderr)]
        return proc, console

    def dump_dom(self, url: str, size: tuple[int, int] = (1100, 900)) -> tuple[str, list[str]]:
        proc, console = self._run(url, "--dump-dom", f"--window-size={size[0]},{size[1]}",
                                  "--force-device-scale-factor=1")
        assert proc.returncode == 0, f"chromium failed ({proc.returncode}): {proc.stderr[-2000:]}"
        return proc.stdout, console

    def screenshot(self, url: str, path, size: tuple[int, int] = (1100, 900)) -> list[str]:
        proc, console = self._run(url, f"--screenshot={path}", f"--window-size={size[0]},{size[1]}",
                                  "--force-device-scale-factor=1")
        assert proc.returncode == 0 and path.is_file(), f"chromium failed ({proc.returncode}): {proc.stderr[-2000:]}"
        return console


@pytest.fixture(scope="session")
def chromium(tmp_path_factory) -> HeadlessChromium:
    """Headless Chromium, or a skip saying how to get it (``.ci/run`` installs Debian's ``chromium`` and sets
    ``CERBERUS_REQUIRE_CHROMIUM``, which turns the skip into a failure); ``CERBERUS_CHROMIUM`` names another
    executable."""
    import os
    import shutil

    names = [os.environ.get("CERBERUS_CHROMIUM", ""), "chromium", "chromium-browser", "google-chrome"]
    exe = next((shutil.which(n) for n in names if n and shutil.which(n)), None)
    if exe is None and os.environ.get("CERBERUS_REQUIRE_CHROMIUM"):
        pytest.fail("headless Chromium not found but CERBERUS_REQUIRE_CHROMIUM is set (as .ci/run does): "
                    "install it with `apt-get install chromium`")
    if exe is None:
        pytest.skip("headless Chromium not found, so the 3D viewer's browser tests are skipped: "
                    "install it with `apt-get install chromium` (CI does) or set CERBERUS_CHROMIUM")
    return HeadlessChromium(exe, tmp_path_factory.mktemp("chromium"))


# ------------------------------------------------------------------ fake installed distributions (plugin discovery)
@pytest.fixture
def fake_dist(tmp_path: Path) -> Callable[..., Path]:
    """``fake_dist(dist, entry_points, modules, folder="site")`` writes a fake distribution into
    ``tmp_path / folder`` and returns that folder (pass ``path=[str(it)]`` to the discovery
    functions, or put it on sys.path)."""

    def make(dist: str, entry_points: dict[str, dict[str, str]], modules: dict[str, str] | None = None,
             folder: str = "site") -> Path:
        root = tmp_path / folder
        write_distribution(root, dist, entry_points, modules)
        return root

    return make
