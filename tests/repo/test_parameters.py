"""Short parameter lists where they had grown longest (issue 40): no function of the evaluation wing
(``cerberus_core/eval/``) or the reconstruction wing (``cerberus_core/reconstruct/``) takes more than
:data:`MAX_PARAMETERS` parameters (``self`` and ``cls`` not counted); what belongs together travels as one
small dataclass (``ViewerPage``, ``CardDetails``, ``PictureStyle``, ``FigureModels``, ``TrainedModel``,
``ImageInputs``). Read with ``ast``: nothing is imported."""
from __future__ import annotations

import ast

from tests.support.paths import REPO

CORE = REPO / "packages" / "cerberus-core" / "src" / "cerberus_core"
WINGS = ("eval", "reconstruct")
MAX_PARAMETERS = 8


def parameter_count(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """Every parameter a call can pass (positional, keyword-only, ``*args``, ``**kwargs``), less ``self``/``cls``."""
    a = node.args
    names = [p.arg for p in (*a.posonlyargs, *a.args)]
    count = len(names) + len(a.kwonlyargs) + (a.vararg is not None) + (a.kwarg is not None)
    return count - (1 if names and names[0] in ("self", "cls") else 0)


def long_signatures(source: str) -> list[tuple[int, str, int]]:
    """``(line, function, parameters)`` of each function of ``source`` over the limit."""
    return [(node.lineno, node.name, parameter_count(node)) for node in ast.walk(ast.parse(source))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and parameter_count(node) > MAX_PARAMETERS]


def test_no_function_of_the_evaluation_or_reconstruction_wing_takes_more_than_eight_parameters():
    found = [f"{path.relative_to(CORE)}:{line} {name} takes {n}"
             for wing in WINGS for path in sorted((CORE / wing).glob("*.py"))
             for line, name, n in long_signatures(path.read_text(encoding="utf-8"))]
    assert not found, f"more than {MAX_PARAMETERS} parameters; group them in a small dataclass:\n" + "\n".join(found)


def test_the_count_sees_a_long_signature():
    assert long_signatures("def f(a, b, c, d, e, f, g, h): ...") == []
    assert long_signatures("def f(self, a, b, c, d, e, f, g, h): ...") == []
    assert long_signatures("def f(a, b, c, d, e, f, g, *, h, i): ...") == [(1, "f", 9)]
    assert long_signatures("def f(a, b, c, d, e, f, g, h, **kw): ...") == [(1, "f", 9)]
