"""The lists of training presets and dataset sizes agree between the bundled files, the command's --help and
the docs, and every preset or size a page names exists (issue 34: they differed)."""
from __future__ import annotations

import re

from cerberus_core.cli import build_parser
from cerberus_core.plugins import BODY_GROUP, get_plugin, plugin_names
from cerberus_core.train.settings import preset_names
from tests.support.paths import REPO

PAGES = [REPO / "README.md", REPO / "benchmarks" / "README.md", *sorted((REPO / "docs").glob("*.md"))]


def _sub(parser, *names):
    for name in names:
        parser = next(a for a in parser._actions if a.dest in ("command", "data_command")).choices[name]
    return parser


def test_every_training_preset_is_in_the_help_and_in_the_preset_table():
    table = (REPO / "docs" / "training.md").read_text().split("## Presets", 1)[1].split("\n\n", 2)[1]
    rows = set(re.findall(r"^\| `([a-z0-9_]+)` \|", table, re.M))
    assert rows == set(preset_names())
    helptext = " ".join(_sub(build_parser(), "train").format_help().split())
    assert all(name in helptext for name in preset_names())


def test_every_dataset_size_is_in_the_help_and_in_the_data_docs():
    helptext = " ".join(_sub(build_parser(), "data", "generate").format_help().split())
    docs = (REPO / "docs" / "data_format.md").read_text()
    for dataset in plugin_names(BODY_GROUP):
        for size in get_plugin(BODY_GROUP, dataset).sizes():
            assert size in helptext, (dataset, size)
            assert f"`{size}`" in docs, (dataset, size)


def test_every_preset_and_size_a_page_names_exists():
    """A page names presets and sizes in commands (`--preset cpu`, `--size small`); each must be one that exists."""
    sizes = {size for dataset in plugin_names(BODY_GROUP) for size in get_plugin(BODY_GROUP, dataset).sizes()}
    named = {"preset": set(), "size": set()}
    for page in PAGES:
        for kind, name in re.findall(r"--(preset|size)[ =]([a-z0-9_]+)", page.read_text()):
            named[kind].add((page.name, name))
    assert named["preset"] and named["size"]
    assert [(page, n) for page, n in named["preset"] if n not in preset_names()] == []
    assert [(page, n) for page, n in named["size"] if n not in sizes] == []
