"""The ``cerberus renderers`` command (cerberus_core.cli.renderers): the installed backends, as a table or JSON."""
from __future__ import annotations

import json

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
