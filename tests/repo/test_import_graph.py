"""An honest import graph, read from the sources with ``ast`` (nothing is imported):

* no import cycle among the toolkit's modules at module level (``if TYPE_CHECKING:`` imports count:
  a cycle hidden from the interpreter is still one for the reader);
* at most :data:`MAX_LOCAL_IMPORTS` function-local imports of ``cerberus_*`` modules outside
  ``cli/`` (the commands import their pipelines lazily so that ``cerberus --help`` stays fast; the
  library itself imports at the top, and keeps local imports for optional heavy dependencies).
"""
from __future__ import annotations

import ast
from pathlib import Path

from tests.support.paths import REPO

PACKAGES = REPO / "packages"
MAX_LOCAL_IMPORTS = 5


def _modules() -> dict[str, Path]:
    """``{dotted module name: file}`` of every module under ``packages/*/src``."""
    out = {}
    for path in sorted(PACKAGES.glob("*/src/cerberus_*/**/*.py")):
        parts = path.relative_to(path.parents[len(path.relative_to(PACKAGES).parts) - 3]).with_suffix("").parts
        name = ".".join(parts[:-1] if parts[-1] == "__init__" else parts)
        out[name] = path
    return out


MODULES = _modules()


def _targets(module: str, node: ast.Import | ast.ImportFrom) -> list[str]:
    """The toolkit modules an import statement loads (``from pkg import mod`` names ``pkg.mod``)."""
    if isinstance(node, ast.Import):
        names = [alias.name for alias in node.names]
    else:
        base = node.module or ""
        if node.level:
            package = module.split(".") if MODULES[module].name == "__init__.py" else module.split(".")[:-1]
            package = package[:len(package) - (node.level - 1)]
            base = ".".join(package + ([node.module] if node.module else []))
        names = [base] + [f"{base}.{alias.name}" for alias in node.names]
    return [n for n in names if n in MODULES]


def _imports(module: str) -> tuple[set[str], list[tuple[int, str]]]:
    """``(modules imported at module level, [(line, statement)] of function-local toolkit imports)``."""
    top: set[str] = set()
    local: list[tuple[int, str]] = []

    def walk(node: ast.AST, in_function: bool) -> None:
        for child in ast.iter_child_nodes(node):
            inside = in_function or isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda))
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                targets = _targets(module, child)
                if inside and targets:
                    local.append((child.lineno, ast.unparse(child)))
                elif not inside:
                    top.update(targets)
            walk(child, inside)

    walk(ast.parse(MODULES[module].read_text(encoding="utf-8")), False)
    return top, local


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan), or a module importing itself."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1 or v in graph.get(v, ()):
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_sources_are_found() -> None:
    assert {"cerberus_core.render.interface", "cerberus_core.bodies.sources", "cerberus_render_warp._runtime",
            "cerberus_metrics.api"} <= set(MODULES)


def test_no_import_cycle_at_module_level() -> None:
    graph = {m: {t for t in _imports(m)[0] if t != m} for m in MODULES}
    assert _cycles(graph) == [], "import cycles: move the shared piece to one module both can import"


def test_few_function_local_imports_of_our_own_modules_outside_cli() -> None:
    local = [f"{m}:{line}: {text}" for m in MODULES if ".cli" not in f".{m}"
             for line, text in _imports(m)[1]]
    assert len(local) <= MAX_LOCAL_IMPORTS, "\n".join(local)


def test_the_cycle_finder_finds_cycles() -> None:
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []


#: The layers of cerberus_core, lowest first (docs/architecture.md, "Dependencies point one way"): a module
#: imports only modules of its own layer or of lower ones. The first matching prefix gives a module's layer.
LAYERS: list[tuple[str, ...]] = [
    ("cerberus_core.errors",),  # every layer raises its errors; they import nothing of the toolkit
    ("cerberus_core.release", "cerberus_core.plumbing", "cerberus_core.shapes", "cerberus_core.fields",
     "cerberus_core.config", "cerberus_core.devices", "cerberus_core.plugins", "cerberus_core.viz",
     "cerberus_core.vendor"),
    ("cerberus_core.render",),
    ("cerberus_core.bodies",),
    ("cerberus_core.datasets", "cerberus_core.parts", "cerberus_core.model", "cerberus_core.losses"),
    ("cerberus_core.train", "cerberus_core.eval", "cerberus_core.reconstruct", "cerberus_core.photo_mask"),
    ("cerberus_core.run", "cerberus_core.weights", "cerberus_core.zoo", "cerberus_core.testing"),
    ("cerberus_core.cli", "cerberus_core.__main__", "cerberus_core"),
]


def _layer(module: str) -> int | None:
    for rank, prefixes in enumerate(LAYERS):
        if any(module == p or module.startswith(p + ".") for p in prefixes):
            return rank
    return None


def test_core_dependencies_point_one_way():
    """A lower layer never imports a higher one at module level: render/ nothing above it, bodies/ no
    renderer, datasets/ nothing of training or evaluation, plumbing/ no domain concept."""
    core = [m for m in MODULES if m == "cerberus_core" or m.startswith("cerberus_core.")]
    unplaced = [m for m in core if _layer(m) is None]
    assert not unplaced, f"give these modules a layer in LAYERS: {unplaced}"
    upward = []
    for module in core:
        for target in sorted(_imports(module)[0]):
            if target.startswith("cerberus_core") and _layer(target) > _layer(module):
                upward.append(f"{module} (layer {_layer(module)}) imports {target} (layer {_layer(target)})")
    assert not upward, "imports that point up the layers:\n" + "\n".join(upward)


def test_the_direction_check_sees_an_upward_import():
    assert _layer("cerberus_core.render.api") < _layer("cerberus_core.datasets.readers") < _layer("cerberus_core.run")
    assert _layer("cerberus_core.errors") == 0 < _layer("cerberus_core.plumbing.names")  # plumbing raises errors
    assert _layer("cerberus_core.plumbing.outputs") == 1 and _layer("cerberus_core.cli.data") == len(LAYERS) - 1


#: The layers inside cli/, lowest first: what the commands share (flags, argument checks, tables, a dataset request
#: said in flags), the sub-commands, then the package that assembles them and owns the error boundary. The commands
#: import lazily, so here function-local imports count too.
CLI_LAYERS: list[tuple[str, ...]] = [
    ("cerberus_core.cli.flags", "cerberus_core.cli.checks", "cerberus_core.cli.tables", "cerberus_core.cli.datasets"),
    ("cerberus_core.cli.compare", "cerberus_core.cli.data", "cerberus_core.cli.demo", "cerberus_core.cli.eval",
     "cerberus_core.cli.models",
     "cerberus_core.cli.reconstruct", "cerberus_core.cli.renderers", "cerberus_core.cli.train"),
    ("cerberus_core.cli", "cerberus_core.cli.__main__"),
]


def _cli_layer(module: str) -> int | None:
    return next((rank for rank, names in enumerate(CLI_LAYERS) if module in names), None)


def _all_imports(module: str) -> set[str]:
    """Every toolkit module ``module`` imports, at the top or inside a function."""
    top, local = _imports(module)
    node = ast.parse("\n".join(text for _, text in local)) if local else None
    inner = {t for stmt in (node.body if node else []) for t in _targets(module, stmt)}
    return top | inner


def test_cli_imports_point_one_way_without_cycles():
    """A sub-command never imports the package that assembles the commands (``cli/__init__``), nor another
    sub-command; the error boundary never reaches into one sub-command."""
    cli = [m for m in MODULES if m == "cerberus_core.cli" or m.startswith("cerberus_core.cli.")]
    unplaced = [m for m in cli if _cli_layer(m) is None]
    assert not unplaced, f"give these modules a layer in CLI_LAYERS: {unplaced}"
    graph = {m: {t for t in _all_imports(m) if t in cli and t != m} for m in cli}
    wrong = [f"{m} imports {t}" for m, targets in graph.items() for t in sorted(targets)
             if _cli_layer(t) > _cli_layer(m) or (_cli_layer(t) == _cli_layer(m) == 1)]
    assert not wrong, "imports inside cli/ that point up (or across sub-commands):\n" + "\n".join(wrong)
    assert _cycles(graph) == []
