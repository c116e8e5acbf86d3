"""Every error raised on purpose is a ``CerberusError`` subclass (docs/architecture.md, "Errors"): read from the
sources with ``ast`` (nothing imported), no toolkit module raises a bare ``ValueError``, ``TypeError``,
``RuntimeError``, ``KeyError`` or ``NotImplementedError`` (an abstract method says so with ``abstractmethod``);
every error class of cerberus-core is defined in ``errors.py``; every ``ConfigError`` names its key (one dialect:
``ConfigError.about``). The vendored files are not ours; argparse type functions raise ``argparse``'s own error."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGES = Path(__file__).resolve().parents[2] / "packages"

BARE = {"ValueError", "TypeError", "RuntimeError", "KeyError", "NotImplementedError"}


def bare_raises(source: str) -> list[tuple[int, str]]:
    """``(line, name)`` of every ``raise ValueError(...)`` (or another name of :data:`BARE`, or the bare name)."""
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
def h():
    raise NotImplementedError
'''
    assert [kind for _, kind in bare_raises(src)] == ["ValueError", "TypeError", "RuntimeError", "NotImplementedError"]


CORE = PACKAGES / "cerberus-core" / "src" / "cerberus_core"

#: Exception classes of cerberus-core that are not errors, so not in errors.py: SIGTERM as a KeyboardInterrupt.
NOT_ERRORS = {"cerberus_core/plumbing/signals.py": {"Terminated"}}


def exception_classes(source: str) -> list[str]:
    """Names of the classes defined in ``source`` that derive from an exception (a base named ``...Error``,
    ``...Exception`` or ``...Interrupt``, or from another such class of the same source)."""
    found: list[str] = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.ClassDef):
            bases = [b.id if isinstance(b, ast.Name) else b.attr if isinstance(b, ast.Attribute) else "" for b in node.bases]
            if any(b.endswith(("Error", "Exception", "Interrupt")) or b in found for b in bases):
                found.append(node.name)
    return found


def test_every_error_class_of_the_core_is_defined_in_errors_py():
    modules = {name: path for name, path in _modules().items() if name.startswith("cerberus_core/")}
    elsewhere = [f"{name}: class {cls}" for name, path in modules.items() if name != "cerberus_core/errors.py"
                 for cls in exception_classes(path.read_text(encoding="utf-8")) if cls not in NOT_ERRORS.get(name, ())]
    assert not elsewhere, "define it in cerberus_core/errors.py, as a CerberusError subclass:\n" + "\n".join(elsewhere)
    assert len(exception_classes((CORE / "errors.py").read_text(encoding="utf-8"))) >= 28


def test_the_class_scan_sees_an_error_class():
    src = "class A(CerberusError, ValueError):\n    pass\nclass B(A):\n    pass\nclass W(UserWarning):\n    pass\n"
    assert exception_classes(src) == ["A", "B"]


def keyless_config_errors(source: str) -> list[int]:
    """Lines of every ``ConfigError(...)`` made without a key: a call of the class itself (not ``ConfigError.about``)
    that passes no ``key=``."""
    lines = []
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id == "ConfigError":
            if not any(k.arg == "key" for k in node.keywords):
                lines.append(node.lineno)
    return sorted(lines)


def test_every_config_error_names_its_key():
    """One dialect: ``ConfigError.about(key, value, problem, fix)``, so that a front end can say the key in its own
    terms (the ``cerberus`` command: its flag, or ``--set``)."""
    found = {name: keyless_config_errors(path.read_text(encoding="utf-8")) for name, path in _modules().items()}
    offenders = [f"{name}:{line}" for name, lines in found.items() for line in lines]
    assert not offenders, "raise ConfigError.about(key, value, problem, fix):\n" + "\n".join(offenders)


def test_the_key_scan_sees_a_keyless_config_error():
    src = 'raise ConfigError("no key")\nraise ConfigError.about("a", 1, "bad")\nraise ConfigError("m", key="a")\n'
    assert keyless_config_errors(src) == [1]
