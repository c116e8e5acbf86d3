"""SIGTERM as an exception: :class:`Terminated` is a ``KeyboardInterrupt`` (so every ``finally`` and
``except KeyboardInterrupt`` cleanup runs as for Ctrl-C) that the ``cerberus`` command turns into
exit status 143 instead of 130."""
from __future__ import annotations

import signal


class Terminated(KeyboardInterrupt):
    """The process received SIGTERM."""


def interrupt_for(signum: int) -> KeyboardInterrupt:
    """The exception that stands for ``signum``: :class:`Terminated` for SIGTERM, else ``KeyboardInterrupt``."""
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()
