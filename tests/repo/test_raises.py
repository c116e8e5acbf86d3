"""Every error raised on purpose is a ``CerberusError`` subclass (docs/architecture.md, "Errors"): read from the
sources with ``ast`` (nothing imported), no toolkit module raises a bare ``ValueError``, ``TypeError`` or
``RuntimeError``. The vendored files are not ours; argparse type functions raise ``argparse``'s own error."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGES = Path(__file__).resolve().parents[2] / "packages"

BARE = {"ValueError", "TypeError", "RuntimeError"}


def bare_raises(source: str) -> list[tuple[int, str]]:
    """``(line, name)`` of every ``raise ValueError(...)`` (or ``TypeError``, ``RuntimeError``, or the bare name)."""
    found = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Raise) and node.exc is not None:
            target = node.exc.func if isinstance(node.exc, ast.Call) else node.exc
            if isinstance(target, ast.Name) and target.id in BARE:
                found.append((node.lineno, target.id))
    return sorted(found)


def _modules() -> dict[str, Path]:
    out = {}
    for path in sorted(PACKAGES.glob("*/src/*/**/*.py")):
        name = path.relative_to(path.parents[len(path.relative_to(PACKAGES).parts) - 3]).as_posix()
        if "/vendor/" not in name:
            out[name] = path
    return out


def test_no_bare_builtin_error_is_raised_on_purpose():
    modules = _modules()
    assert "cerberus_core/datasets/dataset.py" in modules
    found = {name: bare_raises(path.read_text(encoding="utf-8")) for name, path in modules.items()}
    offenders = [f"{name}:{line}: raise {kind}" for name, hits in found.items() for line, kind in hits]
    assert not offenders, "raise a CerberusError subclass (in cerberus_metrics a MetricsError) that says the problem and the fix:\n" + "\n".join(offenders)


def test_the_scan_sees_every_form_of_a_bare_raise():
    src = '''
def f(x):
    if x:
        raise ValueError("a")
    raise TypeError
def g():
    try:
        pass
    except KeyError:
        raise RuntimeError(f"b") from None
    raise ConfigError("typed")
'''
    assert [kind for _, kind in bare_raises(src)] == ["ValueError", "TypeError", "RuntimeError"]
