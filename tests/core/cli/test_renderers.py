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
    monkeypatch.setenv("COLUMNS", "200")  # the whole error on the row's one line
    assert main(["renderers"]) == 0
    out = capsys.readouterr().out
    broken = next(line for line in out.splitlines() if line.strip().startswith("broken "))
    assert "fake-broken-render" in broken and "needs a GPU driver" in broken
    assert any(line.strip().startswith("torch ") and line.rstrip().endswith("ok") for line in out.splitlines())


def test_long_backend_names_keep_the_table_in_columns_and_in_the_terminal(fake_dist, monkeypatch, capsys) -> None:
    """Issue 34: a third-party backend named ``my_very_long_backend_name_xyz`` pushed its row's package, version
    and status out of line with the others (fixed widths of 12 and 24 characters)."""
    name, dist = "my_very_long_backend_name_xyz", "my-very-long-distribution-name-for-a-renderer"
    root = fake_dist(dist, {RENDERER_GROUP: {name: "fake_long_render:Renderer"}},
                     {"fake_long_render": "class Renderer:\n    pass\n"})
    monkeypatch.syspath_prepend(str(root))
    for columns in (120, 60):
        monkeypatch.setenv("COLUMNS", str(columns))
        assert main(["renderers"]) == 0
        out = capsys.readouterr().out
        lines = out.splitlines()
        assert all(len(line) <= columns for line in lines), (columns, out)
        group = lines[1:lines.index("metrics:")]  # the renderers' rows
        starts = {line.index("cerberus-render") for line in group if "cerberus-render" in line}
        assert len(starts) == 1, out  # the package column starts at one offset in every row
        package_column = starts.pop()
        # the long name and package are whole, or broken across their rows' lines in their own columns
        assert "".join(line[2:package_column].strip() for line in group if line[2:package_column].strip()
                       and not line.strip().startswith(("torch", "warp"))) == name, out
        assert dist in "".join(line[package_column:].split("  ")[0] for line in group), out
