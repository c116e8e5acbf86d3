"""Standard error: what one-time costs say before they start (:func:`announce`), and process-level
filtering for libraries whose C code writes straight to fd 2 (:func:`call_dropping_stderr`).

The filter is used by the Warp start-up of the ``warp`` backend and of the ``anny`` body model, which
print a "Could not find or load the NVIDIA CUDA driver" note on machines without one; this module knows
nothing about Warp: it runs a call with file descriptor 2 captured and writes back what was not
asked to be dropped.
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
