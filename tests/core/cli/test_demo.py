"""The ``cerberus demo`` command (cerberus_core.cli.demo)."""
from __future__ import annotations

from PIL import Image

from cerberus_core.cli import main


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
