"""The ``cerberus`` command. Each sub-command lives beside the code it drives and contributes a
``configure(parser)`` function (its arguments, description and examples); this module lists them in
:data:`COMMANDS`, imports only the one that runs (``cerberus --help``, ``--version`` and ``cerberus compare`` do
not import torch), and owns the one error path:

* a typed error (:class:`cerberus_core.errors.CerberusError`, a plugin error) → one line
  ``cerberus COMMAND: message`` on standard error, exit status 2 (or the error's ``exit_code``), said in
  this command's flags (:class:`FlagNames`);
* any other ``OSError`` (a full disk, a read-only or missing folder, whatever its errno) → one line
  naming the path and the system's reason, exit 2;
* Ctrl-C (SIGINT) at any moment, imports included → exit 130; SIGTERM → exit 143 (a training writes
  its checkpoint first); never as an exception inside an import
  (:class:`~cerberus_core.plumbing.signals.CommandSignals`);
* warnings → one line ``cerberus COMMAND: warning: message``, without Python source lines, in this
  command's flags too.

The library says a setting in Python terms (docs/architecture.md, "Errors"): a
:class:`~cerberus_core.errors.ConfigError`'s ``key``, and in any message a parameter, field or config key
in backticks (`` `resume=True` ``, `` `data` ``, `` `train.steps=VALUE` ``). :class:`FlagNames` is the one
place that says each as the flag of the command that was run, or as ``--set KEY=VALUE``.

Sub-commands validate every argument before they write anything, and raise typed errors instead of
printing and returning a status.
"""
from __future__ import annotations

import argparse
import contextlib
import dataclasses
import importlib
import signal
import sys
import warnings
from collections.abc import Iterator

from cerberus_core.cli.flags import FlagNames, typed_flags
from cerberus_core.errors import CerberusError, IncompleteDatasetError
from cerberus_core.plumbing.signals import CommandSignals, Terminated, exit_at_once

#: The sub-commands in the order ``--help`` lists them: the name, the module whose ``configure(parser)`` builds
#: its parser (imported only when that command runs) and the line ``cerberus --help`` shows for it.
COMMANDS = [
    ("renderers", "cerberus_core.cli.renderers", "list installed renderer backends (and metrics) with their versions"),
    ("demo", "cerberus_core.cli.demo", "render a demo scene with every installed renderer backend"),
    ("data", "cerberus_core.cli.data", "generate, check and show training/test datasets"),
    ("train", "cerberus_core.cli.train", "train Cerberus (or a baseline) on a quadruplet dataset"),
    ("eval", "cerberus_core.cli.eval", "evaluate a trained run on a test split: voxel IoU, the diagnostics, figures"),
    ("compare", "cerberus_core.cli.compare", "compare evaluations of one test set, paired image by image with the first"),
    ("reconstruct", "cerberus_core.cli.reconstruct", "3D part meshes (GLB, OBJ) and pictures from one or more images"),
    ("models", "cerberus_core.cli.models", "list the pretrained models shipped with the toolkit"),
]

EXIT_ERROR = 2
EXIT_SIGINT = 128 + signal.SIGINT  # 130
EXIT_SIGTERM = 128 + signal.SIGTERM  # 143
#: What the one line says for each signal.
_SIGNAL_LINES = {signal.SIGINT: "interrupted", signal.SIGTERM: "terminated (SIGTERM)"}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The ``cerberus`` parser. Every sub-command is listed; only ``command``'s module is imported and its parser
    built (all of them when ``command`` is None: the documentation's tests read every flag)."""
    from cerberus_core.cli.checks import OneLineParser

    parser = OneLineParser(
        prog="cerberus",
        description="Cerberus: a multi-headed derenderer. Learn 3D part-based models of articulated bodies "
        "from images alone: generate data, train, evaluate, reconstruct.",
    )
    from cerberus_core.release import VERSION

    parser.add_argument("--version", action="version", version=f"cerberus {VERSION}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, module, line in COMMANDS:
        p = sub.add_parser(name, help=line)
        if command is None or command == name:
            importlib.import_module(module).configure(p)
    return parser


def one_line(text: object) -> str:
    """A message on one line: inner newlines become '; ', and any other control character or undecodable
    byte of a file name is shown escaped (:func:`cerberus_core.plumbing.names.printable`), never sent raw."""
    from cerberus_core.plumbing.names import printable

    return printable("; ".join(part.strip() for part in str(text).strip().splitlines() if part.strip()))


@contextlib.contextmanager
def _one_line_warnings(command: str, names: FlagNames) -> Iterator[None]:
    """Warnings print as one line, in the command's flags; restored on exit."""
    saved_format = warnings.formatwarning
    warnings.formatwarning = lambda message, *a, **k: f"cerberus {command}: warning: {one_line(names.text(str(message)))}\n"
    try:
        yield
    finally:
        warnings.formatwarning = saved_format


def _os_error_line(exc: OSError) -> str:
    """Any OSError as one line: what failed, on which path, and the system's reason."""
    from cerberus_core.plumbing.names import printable

    where = " -> ".join(printable(f) for f in (exc.filename, exc.filename2) if f is not None)
    reason = exc.strerror or str(exc) or type(exc).__name__
    return f"{reason}: {where}" if where else reason


def _said(exc: CerberusError, names: FlagNames) -> str:
    """The message of ``exc`` in this command's flags (:meth:`FlagNames.error`); an incomplete dataset's names the
    ``cerberus data generate`` command that finishes it (:mod:`cerberus_core.cli.datasets`), whichever command ran."""
    if isinstance(exc, IncompleteDatasetError):
        from cerberus_core.cli.datasets import incomplete_message

        return incomplete_message(exc)
    return names.error(exc)


def main(argv: list[str] | None = None) -> int:
    """Run one command. Every way out is one line on standard error and an exit status: a typed error or
    any OSError (2), Ctrl-C at any moment, even while the command's modules are still importing (130),
    SIGTERM (143)."""
    def exit_now(signum: int) -> None:  # a signal while the command's modules import: nothing is written yet
        exit_at_once(f"cerberus {command}: {_SIGNAL_LINES[signum]}", 128 + signum)

    from cerberus_core.plumbing.stdio import printable_streams

    printable_streams()
    words = sys.argv[1:] if argv is None else argv
    command = next((a for a in words if not a.startswith("-")), "")
    names = FlagNames()
    with CommandSignals(exit_now) as signals:
        try:
            parser = build_parser(command)
            args = parser.parse_args(argv)
            signals.started = True
            command = args.command
            names = dataclasses.replace(getattr(args, "flag_names", names), typed=typed_flags(words))
            with _one_line_warnings(command, names):
                return int(args.func(args) or 0)
        except CerberusError as exc:  # every typed error, plugin and dataset errors included
            print(f"cerberus {command}: {one_line(_said(exc, names))}", file=sys.stderr)
            return int(getattr(exc, "exit_code", EXIT_ERROR))
        except Terminated:
            print(f"cerberus {command}: {_SIGNAL_LINES[signal.SIGTERM]}", file=sys.stderr)
            return EXIT_SIGTERM
        except KeyboardInterrupt:
            print(f"cerberus {command}: {_SIGNAL_LINES[signal.SIGINT]}", file=sys.stderr)
            return EXIT_SIGINT
        except OSError as exc:
            print(f"cerberus {command}: {one_line(_os_error_line(exc))}", file=sys.stderr)
            return EXIT_ERROR


if __name__ == "__main__":
    sys.exit(main())
