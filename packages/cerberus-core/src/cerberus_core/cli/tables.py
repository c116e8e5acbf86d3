"""The tables the commands print (``cerberus renderers``, ``cerberus models``): each column as wide as its widest
cell, the table as wide as the terminal at most, long cells wrapped in their column.

A third-party backend named ``my_very_long_backend_name_xyz`` or a model's one-line summary of 200
characters no longer pushes the next column out of line: the widest columns give way first (never below
:data:`MIN_COLUMN` characters), and their cells wrap at spaces (:mod:`textwrap`; a word longer than its
column, a path, is broken, between folders where it can). Every cell is shown through :func:`~cerberus_core.plumbing.names.printable`.
"""
from __future__ import annotations

import shutil
import textwrap
from collections.abc import Sequence

from cerberus_core.plumbing.names import printable

#: The narrowest a column is made to fit the terminal (a narrower natural width is kept).
MIN_COLUMN = 12
#: Spaces between two columns.
GAP = 2


def column_widths(natural: Sequence[int], room: int) -> list[int]:
    """Widths for columns whose widest cells are ``natural`` characters, in ``room`` characters (gaps left out):
    the natural widths if they fit, else the widest column narrowed one character at a time (to
    :data:`MIN_COLUMN` at least) until they fit or none can give way."""
    widths = list(natural)
    while sum(widths) > room:
        k = max(range(len(widths)), key=lambda i: widths[i])
        if widths[k] <= MIN_COLUMN:
            break
        widths[k] -= 1
    return widths


def _paragraphs(cell: object) -> list[str]:
    """A cell as its paragraphs, each shown with ``printable`` (a line break inside a string is escaped too)."""
    items = [cell] if isinstance(cell, str) or not isinstance(cell, (list, tuple)) else cell
    return [printable(item) for item in items]


def _broken(word: str, width: int) -> list[str]:
    """A word longer than ``width`` in pieces of at most ``width``, each ending after a ``/`` where one falls in
    it (a path breaks between its folders)."""
    pieces = []
    while len(word) > width:
        cut = word.rfind("/", 0, width) + 1 or width
        pieces.append(word[:cut])
        word = word[cut:]
    return [*pieces, word]


def _lines(paragraphs: Sequence[str], width: int) -> list[str]:
    """A cell's paragraphs wrapped to ``width`` at spaces, a longer word broken (:func:`_broken`); an empty
    paragraph stays one line."""
    out = []
    for text in paragraphs:
        for line in textwrap.wrap(text, width, break_long_words=False, break_on_hyphens=False) or [""]:
            out += _broken(line, width) if len(line) > width else [line]
    return out


def table(rows: Sequence[Sequence[object]], *, indent: str = "", width: int | None = None) -> list[str]:
    """``rows`` as aligned text lines.

    Args:
        rows: each a sequence of cells: any object, or a list of paragraphs, each starting a new line in its
            cell; shown with ``printable``. Rows may be shorter than the longest (the missing cells are empty).
        indent: put before every line.
        width: the characters a line may take (default: the terminal's, ``shutil.get_terminal_size``, which
            reads ``COLUMNS`` and is 80 where standard output is not a terminal).
    Returns:
        The lines, without trailing spaces; a wrapped row takes several.
    """
    if not rows:
        return []
    width = shutil.get_terminal_size().columns if width is None else width
    n = max(len(r) for r in rows)
    cells = [[_paragraphs(c) for c in r] + [[""]] * (n - len(r)) for r in rows]
    natural = [max(len(text) for r in cells for text in r[k]) for k in range(n)]
    widths = column_widths(natural, width - len(indent) - GAP * (n - 1))
    out = []
    for r in cells:
        wrapped = [_lines(c, w) for c, w in zip(r, widths, strict=True)]
        for i in range(max(len(w) for w in wrapped)):
            parts = [(w[i] if i < len(w) else "").ljust(widths[k]) for k, w in enumerate(wrapped)]
            out.append((indent + (" " * GAP).join(parts)).rstrip())
    return out
