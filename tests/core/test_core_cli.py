"""The ``cerberus renderers`` and ``cerberus demo`` commands."""
from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest
from PIL import Image

from cerberus_core.cli import main
from cerberus_core.plugins import RENDERER_GROUP
from cerberus_core.release import VERSION


def test_renderers_table(capsys) -> None:
    assert main(["renderers"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("renderers:") and "metrics:" in out
    line = next(line for line in out.splitlines() if line.strip().startswith("torch "))
    assert "cerberus-render-torch" in line and VERSION in line and line.rstrip().endswith("ok")


def test_renderers_json(capsys) -> None:
    assert main(["renderers", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    torch_row = next(r for r in data["renderers"] if r["name"] == "torch")
    assert torch_row == {"name": "torch", "package": "cerberus-render-torch", "version": VERSION,
                         "target": "cerberus_render_torch:TorchRenderer", "status": "ok"}


def test_renderers_lists_a_broken_backend_with_its_error(fake_dist, monkeypatch, capsys) -> None:
    root = fake_dist("fake-broken-render", {RENDERER_GROUP: {"broken": "fake_cli_broken:Renderer"}},
                     {"fake_cli_broken": "raise RuntimeError('needs a GPU driver')\n"})
    monkeypatch.syspath_prepend(str(root))
    assert main(["renderers"]) == 0
    out = capsys.readouterr().out
    broken = next(line for line in out.splitlines() if line.strip().startswith("broken "))
    assert "fake-broken-render" in broken and "needs a GPU driver" in broken
    assert any(line.strip().startswith("torch ") and line.rstrip().endswith("ok") for line in out.splitlines())


def test_demo_writes_pictures(tmp_path, capsys) -> None:
    assert main(["demo", "--out", str(tmp_path / "demo"), "--image-size", "32", "--renderer", "torch"]) == 0
    png = tmp_path / "demo" / "demo_torch.png"
    with Image.open(png) as im:
        assert im.format == "PNG" and im.width > 4 * 32 and im.height > 2 * 32
    assert "demo_torch.png" in capsys.readouterr().out
    assert not list((tmp_path / "demo").glob("*.tmp")), "no temporary files left behind"


def test_demo_with_an_unknown_renderer_names_the_known_ones(tmp_path, capsys) -> None:
    """A plugin error is a message and exit code 2, not a traceback."""
    assert main(["demo", "--out", str(tmp_path), "--renderer", "nope"]) == 2
    err = capsys.readouterr().err
    assert "unknown renderer 'nope'" in err and "torch" in err and "Traceback" not in err


@pytest.mark.slow  # a fresh interpreter importing torch: seconds
@pytest.mark.skipif(shutil.which("cerberus") is None, reason="the cerberus console script is not installed")
def test_console_script_help() -> None:
    proc = subprocess.run(["cerberus", "--help"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0 and "renderers" in proc.stdout and "demo" in proc.stdout



def test_a_warning_prints_as_one_line_without_a_source_line() -> None:
    """Issue 11: warnings printed the Python source line that raised them."""
    script = ("import sys, warnings\n"
              "import cerberus_core.cli as cli, cerberus_core.cli.renderers as r\n"
              "def run(args):\n"
              "    warnings.warn('a first line\\nand a second', UserWarning)\n"
              "    return 0\n"
              "r.run = run\n"
              "sys.exit(cli.main(['renderers']))\n")
    proc = subprocess.run([sys.executable, "-W", "always", "-c", script], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "cerberus renderers: warning: a first line; and a second\n"
