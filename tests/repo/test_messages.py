"""No library message names a command-line flag (docs/architecture.md, "Errors"): the library says a setting
in Python terms (its config key, parameter or field) and only ``cerberus_core.cli`` says flags
(:class:`cerberus_core.cli.flags.FlagNames`). Read from the sources with ``ast``, nothing imported: every string of a
library module but its docstrings (documentation may name the command line), so a message built in pieces, returned or appended is checked too.
"""
from __future__ import annotations

import ast
import re
from pathlib import Path

PACKAGES = Path(__file__).resolve().parents[2] / "packages"

#: A command-line flag: ``--word`` not inside a longer word or a longer dash run.
FLAG = re.compile(r"(?<![\w-])--[a-z][a-z0-9-]*")

#: Another tool's command, quoted whole (its options are not ours): removed before looking for a flag.
OTHER_TOOLS = re.compile(r"pip install.*")

#: Only the command line: the ``cerberus`` and ``cerberus-metrics`` commands, ``python -m`` entry points.
COMMAND_LINE = ("cerberus_core/cli/", "cerberus_metrics/cli.py", "__main__.py")


#: Strings that are not messages, by module and the function or name that holds them: the conformance
#: suite's own pytest option.
NOT_MESSAGES = {("cerberus_core/testing/conftest.py", "pytest_addoption"),
                ("cerberus_core/testing/conftest.py", "_select")}


def library_modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGES.glob("*/src/*/**/*.py")):
        name = path.relative_to(path.parents[len(path.relative_to(PACKAGES).parts) - 3]).as_posix()
        if not any(part in name for part in COMMAND_LINE):
            out[name] = path
    return out


def _docstrings(tree: ast.AST) -> set[int]:
    """The strings that are statements of their own: docstrings of modules, classes, functions and attributes."""
    return {id(n.value) for n in ast.walk(tree) if isinstance(n, ast.Expr) and isinstance(n.value, ast.Constant)}


def flags_named(name: str, source: str) -> list[str]:
    """``"module:line: --flag in 'text'"`` for each flag a string of ``source`` names."""
    tree = ast.parse(source)
    docs, found = _docstrings(tree), []

    def walk(node: ast.AST, scope: str) -> None:
        for child in ast.iter_child_nodes(node):
            inner = scope
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)) and not scope:
                inner = child.name
            elif isinstance(child, (ast.Assign, ast.AnnAssign)) and not scope:
                targets = child.targets if isinstance(child, ast.Assign) else [child.target]
                inner = next((t.id for t in targets if isinstance(t, ast.Name)), "")
            if (name, inner) in NOT_MESSAGES:
                continue
            if isinstance(child, ast.Constant) and isinstance(child.value, str) and id(child) not in docs:
                found.extend(f"{name}:{child.lineno}: {flag} in {child.value!r}"
                             for flag in FLAG.findall(OTHER_TOOLS.sub("", child.value)))
            walk(child, inner)

    walk(tree, "")
    return found


def test_no_library_message_names_a_flag():
    modules = library_modules()
    assert "cerberus_core/run.py" in modules and "cerberus_metrics/api.py" in modules
    assert not any("/cli/" in m or m.endswith("__main__.py") for m in modules)
    found = [hit for name, path in modules.items() for hit in flags_named(name, path.read_text(encoding="utf-8"))]
    assert not found, "library messages say settings in Python terms; the CLI says flags:\n" + "\n".join(found)


def test_the_scan_finds_a_flag_however_the_message_is_built():
    src = '''
"""A docstring may name --out."""
def f(x):
    """So may this one: --resume."""
    warn(f"x is {x}; pass --overwrite")
    lines = ["ok"]
    lines.append("run it with " + "--data DIR")
    return f"{x} (--set a.b=VALUE)"
def pytest_addoption():
    return ["--out"]
HINT = "pip install --force-reinstall cerberus-core"
'''
    found = flags_named("cerberus_core/testing/conftest.py", src)
    assert [h.split(": ")[1].split(" in ")[0] for h in found] == ["--overwrite", "--data", "--set"], found
