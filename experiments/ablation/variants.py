"""Read an ablation variants file (run.sh's format: ``NAME | DATA | TRAIN``) without a shell: run.sh used to
``eval`` each row, so a name or argument holding ``$(...)``, backticks or ``;`` ran commands, and spaces, globs or
``..`` sent a training outside RUNS (issue 39).

    python experiments/ablation/variants.py rows FILE    # the rows, checked: NAME|DATA|TRAIN per line
    python experiments/ablation/variants.py argv TEXT    # TEXT split as a shell would (quotes), NUL-separated

A name is letters, digits, ``_``, ``.`` and ``-`` (``[A-Za-z0-9_.-]+``), starts with a letter, digit or ``_``
and holds no ``..``; arguments are split with :func:`shlex.split` (quotes group words; nothing is expanded or
run). A bad row is one line on stderr naming the file, the line and the fix, and exit status 2.
"""
from __future__ import annotations

import re
import shlex
import sys
from pathlib import Path

NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")


class RowError(Exception):
    """A row run.sh must not run."""


def split_args(text: str) -> list[str]:
    """``text`` split into arguments as a shell splits words (quotes group them), nothing expanded."""
    try:
        return shlex.split(text)
    except ValueError as exc:
        raise RowError(f"cannot split {text!r} into arguments ({exc}); close the quotes") from None


def rows(path: Path) -> list[tuple[str, str, str]]:
    """The rows of a variants file ``(name, data, train)``, stripped; comments and blank lines skipped."""
    out = []
    for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
        if not line.strip() or line.lstrip().startswith("#"):
            continue
        try:
            name, data, train = (line.split("|", 2) + ["", ""])[:3]
            name, data, train = name.strip(), data.strip(), train.strip()
            if not NAME.fullmatch(name) or ".." in name:
                raise RowError(f"the name {name!r} is not a plain name; use letters, digits, _, . and - "
                               "(starting with a letter, digit or _, no '..')")
            if data.startswith("@"):
                if not data[1:] or any(c in data for c in "\n\0"):
                    raise RowError(f"the data {data!r} names no dataset folder; write @PATH")
            else:
                split_args(data)
            split_args(train)
        except RowError as exc:
            raise RowError(f"{path}:{number}: {exc}") from None
        out.append((name, data, train))
    return out


def main(argv: list[str]) -> int:
    try:
        if len(argv) == 2 and argv[0] == "rows":
            for row in rows(Path(argv[1])):
                print("|".join(row))
            return 0
        if len(argv) == 2 and argv[0] == "argv":
            sys.stdout.write("".join(a + "\0" for a in split_args(argv[1])))
            return 0
    except (RowError, OSError, UnicodeDecodeError) as exc:
        print(f"variants.py: {exc}", file=sys.stderr)
        return 2
    print("usage: variants.py rows FILE | variants.py argv TEXT", file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
