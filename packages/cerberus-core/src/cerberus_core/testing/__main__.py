"""``python -m cerberus_core.testing [--renderer NAME ...] [pytest options]``: run the conformance suite of
the installed core against installed backends (see :mod:`cerberus_core.testing`)."""
from __future__ import annotations

import sys
from pathlib import Path

HELP = """\
usage: python -m cerberus_core.testing [--renderer NAME ...] [PYTEST OPTIONS]

Run the renderer conformance suite of the installed cerberus-core against installed backends: the
rasterization contract, an independent reference renderer, analytic scenes, finite-difference gradients,
edge cases (no faces, degenerate faces, huge coordinates) and, where cerberus-render-torch is installed,
the reference backend. docs/backends.md says what each file holds a backend to.

options:
  -h, --help       show this message and exit (pytest's own: python -m pytest --help)
  --renderer NAME  test this backend (an entry point of the group cerberus.renderers); repeat for several;
                   default: every installed backend
  any other        passed to pytest, e.g. -q, -x, -k contract

examples:
  python -m cerberus_core.testing --renderer minimal
  python -m cerberus_core.testing --renderer warp -k "contract or gradients" -q
"""


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if "-h" in args or "--help" in args:
        print(HELP, end="")
        return 0
    try:
        import pytest
    except ImportError:
        print("the conformance suite needs pytest: pip install pytest (or cerberus-core[testing])", file=sys.stderr)
        return 2
    here = Path(__file__).resolve().parent
    return int(pytest.main([str(here), "-p", "no:cacheprovider", *args]))


if __name__ == "__main__":
    sys.exit(main())
