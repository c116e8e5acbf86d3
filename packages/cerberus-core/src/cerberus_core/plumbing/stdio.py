"""The process's standard streams.

* :func:`announce` — what a one-time cost (a cache built, kernels compiled) says before it starts;
* :func:`printable_streams` — a command's output never fails to print: a character the stream's encoding
  cannot say (a non-ASCII path under ``LANG=C`` or ``PYTHONIOENCODING=ascii``) is written escaped;
* :func:`call_dropping_stderr` — standard-error filtering for libraries whose C code writes straight to fd 2:
  the Warp start-up of the ``warp`` backend and of the ``anny`` body model print a "Could not find or load
  the NVIDIA CUDA driver" note on machines without one; it runs a call with file descriptor 2 captured and
  writes back what was not asked to be dropped (it knows nothing about Warp).
"""
from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Callable
from typing import TypeVar

T = TypeVar("T")


def announce(text: str) -> None:
    """Say ``text`` on standard error now, on a line of its own: how a one-time cost (a cache built, kernels
    compiled) says what it is and about how long it takes before it starts. A progress bar being drawn
    (tqdm) is cleared, the line written above it and the bar drawn again, so the text never runs into it."""
    from tqdm import tqdm

    tqdm.write(text, file=sys.stderr)
    sys.stderr.flush()


def printable_streams() -> None:
    """Make ``sys.stdout`` and ``sys.stderr`` escape what their encoding cannot write (``errors="backslashreplace"``)
    instead of raising :class:`UnicodeEncodeError` midway through a command."""
    for stream in (sys.stdout, sys.stderr):
        reconfigure = getattr(stream, "reconfigure", None)  # a replaced stream (a test's capture) may not have it
        if reconfigure is not None:
            try:
                reconfigure(errors="backslashreplace")
            except (ValueError, OSError):  # a closed or detached stream: nothing will be printed to it anyway
                pass


def call_dropping_stderr(fn: Callable[[], T], drop: str) -> T:
    """Call ``fn()`` with file descriptor 2 captured; re-emit every captured line not containing
    ``drop``. Exceptions propagate after the captured text is written back."""
    sys.stderr.flush()
    saved = os.dup(2)
    with tempfile.TemporaryFile(mode="w+b") as capture:
        os.dup2(capture.fileno(), 2)
        try:
            return fn()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
            capture.seek(0)
            lines = capture.read().decode("utf-8", "replace").splitlines(keepends=True)
            rest = "".join(line for line in lines if drop not in line)
            if rest:
                sys.stderr.write(rest)
