"""JSON text from outside (a dataset's manifest, a weights file's metadata, a lock file) parsed by one rule:
every way the text can be malformed is a :class:`ValueError` whose message says what is wrong
(:class:`json.JSONDecodeError` for its syntax, :class:`~cerberus_core.errors.TextFormatError` otherwise).

Python's :func:`json.loads` fails in three ways, not one: :class:`json.JSONDecodeError` for bad syntax, a plain
:class:`ValueError` for an integer longer than :func:`sys.get_int_max_str_digits` digits (naming an interpreter
setting as the fix), and :class:`RecursionError` for deep nesting. A reader that catches only the first lets the
others out as tracebacks.
"""
from __future__ import annotations

import json
import sys
from typing import Any

from cerberus_core.errors import TextFormatError


def loads(text: str | bytes) -> Any:
    """``text`` parsed as JSON.

    Raises:
        json.JSONDecodeError: malformed text (its syntax error).
        TextFormatError: a number too long to read, or nesting too deep.
    """
    try:
        return json.loads(text)
    except json.JSONDecodeError:
        raise
    except RecursionError:
        raise TextFormatError("nested too deeply to be read") from None
    except ValueError as exc:  # an integer of too many digits: CPython's text names an interpreter setting
        if "integer string conversion" in str(exc):
            raise TextFormatError(f"holds a number of more than {sys.get_int_max_str_digits()} digits") from None
        raise


__all__ = ["loads"]
