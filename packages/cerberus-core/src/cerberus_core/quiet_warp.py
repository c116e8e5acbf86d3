"""Quiet start-up of NVIDIA Warp, for the code paths that run on it (the ``warp`` renderer backend,
and the ``anny`` body model behind the human datasets, whose skinning is a Warp kernel).

Warp prints a banner, per-module "loaded" lines and, on machines without an NVIDIA driver, a
"Could not find or load the NVIDIA CUDA driver" warning written by C code straight to file
descriptor 2. :func:`init_warp_quietly` turns the first two off (log level: warnings) and initialises
Warp with that one warning dropped when torch has no CUDA either; anything else Warp writes passes.
Core does not depend on Warp: the import happens only when this function is called.
"""
from __future__ import annotations

import os
import sys
import tempfile
import threading

CUDA_DRIVER_NOTE = "Could not find or load the NVIDIA CUDA driver"
"""The start of Warp's warning on machines without an NVIDIA driver (dropped when torch has no CUDA)."""

_lock = threading.Lock()
_done = False


def quiet_warp_logging(wp) -> None:
    """No banner on init and no "module loaded/compiled" lines (warnings and errors still show)."""
    if hasattr(wp.config, "log_level") and hasattr(wp, "LOG_WARNING"):
        wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
    if hasattr(wp.config, "quiet"):  # older Warp
        wp.config.quiet = True


def init_warp_quietly() -> None:
    """Import and initialise Warp once, quietly (thread-safe; later calls return at once).

    Raises:
        ImportError: Warp is not installed.
        Exception: whatever ``wp.init()`` raises.
    """
    global _done
    if _done:
        return
    import torch
    import warp as wp

    with _lock:
        if _done:
            return
        quiet_warp_logging(wp)
        if torch.cuda.is_available():  # ``wp.init`` is a no-op if another user of Warp ran it already
            wp.init()
            _done = True
            return
        sys.stderr.flush()
        saved = os.dup(2)
        with tempfile.TemporaryFile(mode="w+b") as capture:
            os.dup2(capture.fileno(), 2)
            try:
                wp.init()
            finally:
                os.dup2(saved, 2)
                os.close(saved)
            capture.seek(0)
            lines = capture.read().decode("utf-8", "replace").splitlines(keepends=True)
        rest = "".join(line for line in lines if CUDA_DRIVER_NOTE not in line)
        if rest:
            sys.stderr.write(rest)
        _done = True
