"""SIGTERM as an exception: :class:`Terminated` is a ``KeyboardInterrupt`` (so every ``finally`` and
``except KeyboardInterrupt`` cleanup runs as for Ctrl-C) that the ``cerberus`` command turns into
exit status 143 instead of 130.

An exception must not be raised while a module imports: there it may cross a C++ extension's initialisation
(torch's and pymeshlab's pybind11 modules), which cannot pass it on and aborts the process (``terminate called
after throwing an instance of 'pybind11::error_already_set'``, exit -6). :class:`CommandSignals` keeps it out:
while the command's own modules import nothing is written yet, so it exits at once; later it raises the
exception as soon as the import is over.
"""
from __future__ import annotations

import contextlib
import os
import signal
from collections.abc import Callable
from types import FrameType

#: The code files of CPython's import system: a frame of either on the stack means a module is importing.
_IMPORT_SYSTEM = ("<frozen importlib._bootstrap>", "<frozen importlib._bootstrap_external>")
#: Seconds between looks at whether the import a signal arrived in is over.
_RECHECK_S = 0.05


class Terminated(KeyboardInterrupt):
    """The process received SIGTERM."""


def interrupt_for(signum: int) -> KeyboardInterrupt:
    """The exception that stands for ``signum``: :class:`Terminated` for SIGTERM, else ``KeyboardInterrupt``."""
    return Terminated() if signum == signal.SIGTERM else KeyboardInterrupt()


def importing(frame: FrameType | None) -> bool:
    """Whether the stack that ``frame`` tops (a signal handler's second argument) is importing a module.

    >>> import sys
    >>> importing(sys._getframe())
    False
    """
    while frame is not None:
        if frame.f_code.co_filename in _IMPORT_SYSTEM:
            return True
        frame = frame.f_back
    return False


class CommandSignals:
    """SIGINT and SIGTERM for a command, as :func:`interrupt_for`'s exception, never raised inside an import.

    Until :attr:`started` is set (the command's modules import and its arguments are read) a signal that
    lands inside an import calls ``exit_now(signum)``, which must end the process; once the command runs, the
    signal waits for the import to finish (a SIGALRM handler, installed then, looks again every 50 ms) and its
    exception is raised there. In the main thread only; elsewhere the handlers are left alone.
    """

    def __init__(self, exit_now: Callable[[int], None]) -> None:
        self.exit_now = exit_now
        self.started = False
        self._pending: int | None = None  # the signal waiting for its import to end
        self._previous: dict[int, object] = {}

    def __enter__(self) -> CommandSignals:
        with contextlib.suppress(ValueError):  # not the main thread
            for sig in (signal.SIGINT, signal.SIGTERM):
                self._previous[sig] = signal.signal(sig, self._handle)
        return self

    def _handle(self, signum: int, frame: FrameType | None) -> None:
        if not importing(frame):
            raise interrupt_for(signum)
        if not self.started:
            self.exit_now(signum)
        if signal.SIGALRM not in self._previous:
            self._previous[signal.SIGALRM] = signal.signal(signal.SIGALRM, self._recheck)
        self._pending = signum
        signal.setitimer(signal.ITIMER_REAL, _RECHECK_S)

    def _recheck(self, signum: int, frame: FrameType | None) -> None:  # noqa: ARG002
        if self._pending is None:
            return
        if importing(frame):
            signal.setitimer(signal.ITIMER_REAL, _RECHECK_S)
            return
        pending, self._pending = self._pending, None
        raise interrupt_for(pending)

    def __exit__(self, *exc: object) -> None:
        if signal.SIGALRM in self._previous:  # our timer, not a caller's
            signal.setitimer(signal.ITIMER_REAL, 0)
        for sig, handler in self._previous.items():
            with contextlib.suppress(ValueError, TypeError):
                signal.signal(sig, handler)


def exit_at_once(line: str, status: int) -> None:
    """Write ``line`` to standard error and end the process with ``status``, running no Python cleanup."""
    with contextlib.suppress(OSError):
        os.write(2, f"{line}\n".encode(errors="backslashreplace"))
    os._exit(status)
