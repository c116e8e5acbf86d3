"""Markdown for evaluation reports: names shown literally, tables, numbers; what every report section uses
(:func:`cerberus_core.eval.report.markdown_report` and each diagnostic's section)."""
from __future__ import annotations

import html
import math
import re
from collections.abc import Mapping, Sequence
from typing import Any

from cerberus_core.plumbing.names import printable

_MD_SPECIAL = re.compile(r"([\\`|\[\]*])")


def md_text(text: object) -> str:
    """A name (subject, part, path) as Markdown text that shows it literally: control characters and
    undecodable bytes escaped (:func:`cerberus_core.plumbing.names.printable`), ``& < >`` as HTML character
    references (no raw HTML reaches a renderer), and ``\\ ` | [ ] *`` backslash-escaped (no code span,
    link, emphasis or broken table cell).

    Example:
        >>> md_text("a|b <c>")
        'a\\\\|b &lt;c&gt;'
    """
    return _MD_SPECIAL.sub(r"\\\1", html.escape(printable(text), quote=False))


def fmt(v: Any, digits: int = 4) -> str:
    """A table cell: a float with ``digits`` decimals, ``-`` for ``None``/NaN/infinity, else the text
    (:func:`md_text`).

    Example:
        >>> fmt(0.123456), fmt(0.5, digits=2), fmt(None), fmt(float("nan")), fmt(3), fmt("s|1")
        ('0.1235', '0.50', '-', '-', '3', 's\\\\|1')
    """
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return md_text(v)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]], digits: int = 4) -> str:
    """A GitHub-flavoured Markdown table; floats get ``digits`` decimals, ``None``/NaN show as ``-``.

    Example:
        >>> print(markdown_table(["Subject", "IoU"], [["s|1", 0.5], ["s2", None]]))
        | Subject | IoU |
        |:---|---:|
        | s\\|1 | 0.5000 |
        | s2 | - |
    """
    lines = ["| " + " | ".join(md_text(h) for h in header) + " |",
             "|" + "|".join(":---" if i == 0 else "---:" for i in range(len(header))) + "|"]
    lines += ["| " + " | ".join(fmt(v, digits) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def sentence(line: str) -> str:
    """A summary line as the start of a sentence (its first letter upper-case)."""
    return line[:1].upper() + line[1:]


def scored_part_quality(result: Mapping[str, Any]) -> Mapping[str, Any] | None:
    """A result's part quality when it was scored (``None``: not run, or data without part labels)."""
    pq = result.get("part_quality")
    return pq if pq and pq.get("part_labels") is not False else None


def part_labels(result: Mapping[str, Any]) -> dict[int, str | None]:
    """``{learned part: its majority ground-truth part}`` from a result's part quality (empty when not scored).

    Example:
        >>> parts = [{"part": 0, "label": "head"}, {"part": 1, "label": None}]
        >>> scored = {"part_quality": {"part_labels": True, "parts": parts}}
        >>> part_labels(scored), part_labels({"part_quality": {"part_labels": False, "parts": []}}), part_labels({})
        ({0: 'head', 1: None}, {}, {})
    """
    pq = scored_part_quality(result)
    return {p["part"]: p["label"] for p in pq["parts"]} if pq else {}
