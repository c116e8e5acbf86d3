"""Argument checks shared by the sub-commands: the argparse type of a count, and the one-line usage error (the
path checks are :mod:`cerberus_core.plumbing.outputs`, the device check :func:`cerberus_core.devices.check_device`,
which library code uses too)."""
from __future__ import annotations

import argparse

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


class OneLineParser(argparse.ArgumentParser):
    """An ArgumentParser whose usage errors are one line (exit 2), like every other CLI error."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.exit(2, f"{self.prog}: {message}{_choice_hint(message)}; see {self.prog} --help\n")


def _choice_hint(message: str) -> str:
    """`` (did you mean 'a'?)`` for an argparse "invalid choice: 'x' (choose from 'a', 'b')" message."""
    import re

    from cerberus_core.plumbing.names import did_you_mean

    found = re.search(r"invalid choice: '([^']*)' \(choose from (.*)\)", message)
    return did_you_mean(found.group(1), re.findall(r"'([^']*)'", found.group(2))) if found else ""
