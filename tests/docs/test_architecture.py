"""docs/architecture.md's "One way in, per concept" table holds, read against the sources (nothing of the
packages is imported but the command's parser): every name in backticks in the middle column exists, and
every one in the last column is gone, so re-adding `make_source` or `read_manifest` fails here."""
from __future__ import annotations

import ast
import re
from functools import cache
from pathlib import Path

import pytest

from cerberus_core.cli import build_parser
from tests.support.paths import REPO

DOC = REPO / "docs" / "architecture.md"
CORE = REPO / "packages" / "cerberus-core" / "src" / "cerberus_core"
SOURCES = sorted(p for p in (REPO / "packages").glob("*/src/**/*.py") if "vendor" not in p.parts)


def rows() -> list[tuple[str, str, str]]:
    """``(concept, the one way in, not there any more)`` of each row of the table."""
    table = DOC.read_text().split("### One way in, per concept", 1)[1].split("\n###", 1)[0]
    lines = [line for line in table.splitlines() if line.startswith("| ") and not line.startswith("| ---")][1:]
    return [tuple(cell.strip() for cell in line.strip("|").split(" | ")) for line in lines]


def ticked(cell: str) -> list[str]:
    """The names in backticks, without call arguments: `Run.load(path or name)` is ``Run.load``."""
    return [re.sub(r"\(.*\)$", "", name) for name in re.findall(r"`([^`]+)`", cell)]


@cache
def _tree(path: Path) -> ast.Module:
    return ast.parse(path.read_text(encoding="utf-8"))


def _bound(nodes: list[ast.stmt]) -> set[str]:
    """The names a block of statements binds: functions, classes, assignments, annotated fields, imports."""
    names: set[str] = set()
    for node in nodes:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.Assign):
            names.update(t.id for t in node.targets if isinstance(t, ast.Name))
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
    return names


@cache
def defined() -> tuple[dict[str, set[str]], dict[str, set[str]]]:
    """``({module stem: names it binds at module level}, {class name: its members, instance attributes
    included})`` over the packages."""
    modules: dict[str, set[str]] = {}
    classes: dict[str, set[str]] = {}
    for path in SOURCES:
        tree = _tree(path)
        modules.setdefault(path.stem, set()).update(_bound(tree.body))
        for node in ast.walk(tree):
            if isinstance(node, ast.ClassDef):  # its statements, and the attributes its methods set on self
                members = classes.setdefault(node.name, set())
                members.update(_bound(node.body))
                members.update(t.attr for t in ast.walk(node) if isinstance(t, ast.Attribute)
                               and isinstance(t.ctx, ast.Store) and isinstance(t.value, ast.Name) and t.value.id == "self")
    return modules, classes


@cache
def command_line() -> tuple[set[str], set[str]]:
    """``(sub-commands, flags)`` of the ``cerberus`` command, sub-sub-commands included."""
    commands, flags, todo = set(), set(), [build_parser()]
    while todo:
        parser = todo.pop()
        for action in parser._actions:
            flags.update(s for s in action.option_strings if s.startswith("--"))
            if isinstance(action.choices, dict):
                commands.update(action.choices)
                todo.extend(action.choices.values())
    return commands, flags


def exists(name: str, row_class: str | None) -> bool:
    """Whether a name of the middle column is there (see the module docstring of what each form means)."""
    modules, classes = defined()
    everywhere = set().union(*modules.values(), *classes.values())
    if name.startswith("cerberus "):
        return all(word in command_line()[0] for word in name.split()[1:])
    if name.startswith("--"):
        return name in command_line()[1]
    if re.fullmatch(r"cerberus\.[a-z]+", name):  # an entry-point group the core's pyproject registers or reads
        return f'"{name}"' in (CORE.parents[1] / "pyproject.toml").read_text() or name in (CORE / "plugins.py").read_text()
    if "/" in name or name.endswith(".py"):
        return (CORE / name).exists()
    if name.startswith("."):
        return row_class is not None and name[1:] in classes.get(row_class, set())
    owner, _, member = name.rpartition(".")
    if owner:
        return member in classes.get(owner, set()) or member in modules.get(owner, set())
    return name in everywhere


def gone(name: str) -> bool:
    """Whether a name of the last column is gone: a path, no such file; ``module.name``, no module of that
    name binds it; a bare name, no word of the packages' sources says it."""
    if "/" in name or name.endswith(".py"):
        return not (CORE / name).exists()
    module, _, member = name.rpartition(".")
    if module:
        return all(member not in _bound(_tree(p).body) for p in SOURCES if p.stem == module)
    word = re.compile(rf"\b{re.escape(name)}\b")
    return not any(word.search(p.read_text(encoding="utf-8")) for p in SOURCES)


def test_the_table_is_read():
    table = rows()
    assert len(table) >= 12 and all(len(row) == 3 for row in table), table
    assert sum(len(ticked(row[1])) for row in table) >= 50 and sum(len(ticked(row[2])) for row in table) >= 15


@pytest.mark.parametrize("concept, way_in", [(row[0], row[1]) for row in rows()])
def test_every_way_in_exists(concept, way_in):
    names = ticked(way_in)
    row_class = next((n.split(".")[0] for n in names if re.fullmatch(r"[A-Z]\w*\.\w+", n)), None)
    missing = [name for name in names if not exists(name, row_class)]
    assert not missing, f"{concept}: docs/architecture.md names what the code lacks: {missing}"


@pytest.mark.parametrize("concept, replaced", [(row[0], row[2]) for row in rows() if ticked(row[2])])
def test_what_was_replaced_is_gone(concept, replaced):
    back = [name for name in ticked(replaced) if not gone(name)]
    assert not back, f"{concept}: the old way in is back beside the new one: {back}"


def test_the_checks_can_fail():
    """Each check tells a name that is there from one that is not."""
    assert exists("Dataset.open", None) and not exists("Dataset.read_manifest", None)
    assert exists(".evaluate", "Run") and not exists(".reconstruct", "Run")
    assert exists("datasets/dataset.py", None) and not exists("train/config.py", None)
    assert exists("cerberus data", None) and exists("--set", None) and not exists("cerberus datasets", None)
    assert not gone("Dataset") and not gone("dataset.Dataset") and not gone("render/ops.py")
    assert gone("make_source") and gone("plan.generate_command") and gone("train/config.py")
