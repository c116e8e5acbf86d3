"""Argument checks shared by the sub-commands: the argparse type of a count, and the one-line usage error (the
path checks are :mod:`cerberus_core.plumbing.outputs`, the device check :func:`cerberus_core.devices.check_device`,
which library code uses too)."""
from __future__ import annotations

import argparse
import textwrap

#: What every command that writes a folder says about --out in its --help (the rule: docs/outputs.md).
OVERWRITE_HELP = ("it may be new, empty or an earlier output of this command; a folder holding anything else is "
                  "refused, --overwrite or not (what --out may replace: docs/outputs.md)")


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number >= 1, got {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {value}")
    return value


class HelpFormatter(argparse.HelpFormatter):
    r"""``--help`` text as people write it: each paragraph of a description or epilog (blocks between blank lines)
    filled to the terminal's width, and a block with an indented line (``examples:`` and its commands) kept line
    for line as written.

    >>> f = HelpFormatter("cerberus", width=30)
    >>> print(f._fill_text("A paragraph long enough to be filled to the width.\n\nexamples:\n  cerberus x   # as is",
    ...                    30, ""))
    A paragraph long enough to be
    filled to the width.
    <BLANKLINE>
    examples:
      cerberus x   # as is
    """

    def _fill_text(self, text: str, width: int, indent: str) -> str:
        blocks = []
        for block in text.strip("\n").split("\n\n"):
            lines = block.splitlines()
            if any(line[:1].isspace() for line in lines):
                blocks.append("\n".join(indent + line for line in lines))
            else:  # a flag or path is never broken at its hyphens
                blocks.append(textwrap.fill(" ".join(block.split()), width, initial_indent=indent,
                                            subsequent_indent=indent, break_on_hyphens=False, break_long_words=False))
        return "\n\n".join(blocks)


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line (exit 2), like every other CLI error, and whose help is
    laid out by :class:`HelpFormatter` (its sub-command parsers too)."""

    def __init__(self, *args, **kwargs) -> None:
        kwargs.setdefault("formatter_class", HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: {message}{_choice_hint(message)}; see {self.prog} --help\n")


def _choice_hint(message: str) -> str:
    """`` (did you mean 'a'?)`` for an argparse "invalid choice: 'x' (choose from 'a', 'b')" message."""
    import re

    from cerberus_core.plumbing.names import did_you_mean

    found = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
    return did_you_mean(found.group(1), re.findall(r"'([^']*)'", found.group(2))) if found else ""
