"""The ``cerberus`` command. Each sub-command lives beside the code it drives and contributes an
``add_parser(subparsers)`` function; this module only assembles them."""
from __future__ import annotations

import argparse
import importlib
import sys

from cerberus_core.datasets.format import DatasetError
from cerberus_core.plugins import PluginError

#: Modules that contribute sub-commands, in the order ``--help`` lists them.
COMMAND_MODULES = [
    "cerberus_core.cli.renderers",
    "cerberus_core.cli.demo",
    "cerberus_core.cli.data",
    "cerberus_core.cli.train",
    "cerberus_core.cli.eval",
    "cerberus_core.cli.reconstruct",
    "cerberus_core.cli.models",
]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="cerberus",
        description="Cerberus: a multi-headed derenderer. Learn 3D part-based models of articulated bodies "
        "from images alone: generate data, train, evaluate, reconstruct.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name in COMMAND_MODULES:
        importlib.import_module(name).add_parser(sub)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except (PluginError, DatasetError) as exc:
        print(f"cerberus {args.command}: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
