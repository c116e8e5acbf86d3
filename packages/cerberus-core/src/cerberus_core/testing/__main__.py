"""``python -m cerberus_core.testing [--renderer NAME ...] [pytest options]``: run the conformance suite of
the installed core against installed backends (see :mod:`cerberus_core.testing`)."""
from __future__ import annotations

import sys
from pathlib import Path


def main(argv: list[str] | None = None) -> int:
    try:
        import pytest
    except ImportError:
        print("the conformance suite needs pytest: pip install pytest (or cerberus-core[testing])", file=sys.stderr)
        return 2
    here = Path(__file__).resolve().parent
    args = list(sys.argv[1:] if argv is None else argv)
    return int(pytest.main([str(here), "-p", "no:cacheprovider", *args]))


if __name__ == "__main__":
    sys.exit(main())
