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
    (:func:`md_text`)."""
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return md_text(v)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]], digits: int = 4) -> str:
    """A GitHub-flavoured Markdown table; floats get ``digits`` decimals, ``None``/NaN show as ``-``."""
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
    """``{learned part: its majority ground-truth part}`` from a result's part quality (empty when not scored)."""
    pq = scored_part_quality(result)
    return {p["part"]: p["label"] for p in pq["parts"]} if pq else {}
