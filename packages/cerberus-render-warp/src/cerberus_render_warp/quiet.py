"""Quiet start-up of NVIDIA Warp for this backend.

Warp prints a banner, per-module "loaded" lines and, on machines without an NVIDIA driver, a
"Could not find or load the NVIDIA CUDA driver" warning written by C code straight to file
descriptor 2. :func:`init_warp_quietly` turns the first two off (log level: warnings) and initialises
Warp with that one warning dropped when torch has no CUDA either; anything else Warp writes passes.
"""
from __future__ import annotations

import threading

import torch
import warp as wp

from cerberus_core.plumbing.stdio import announce, call_dropping_stderr

CUDA_DRIVER_NOTE = "Could not find or load the NVIDIA CUDA driver"
"""The start of Warp's warning on machines without an NVIDIA driver (dropped when torch has no CUDA)."""

_lock = threading.Lock()
_done = False


def quiet_warp_logging() -> None:
    """No banner on init and no "module loaded/compiled" lines (warnings and errors still show)."""
    if hasattr(wp.config, "log_level") and hasattr(wp, "LOG_WARNING"):
        wp.config.log_level = max(wp.config.log_level, wp.LOG_WARNING)
    if hasattr(wp.config, "quiet"):  # older Warp
        wp.config.quiet = True


def init_warp_quietly() -> None:
    """Initialise Warp once, quietly (thread-safe; later calls return at once).

    Raises:
        Exception: whatever ``wp.init()`` raises.
    """
    global _done
    if _done:
        return
    with _lock:
        if _done:
            return
        quiet_warp_logging()
        if torch.cuda.is_available():  # ``wp.init`` is a no-op if another user of Warp ran it already
            wp.init()
        else:
            call_dropping_stderr(wp.init, CUDA_DRIVER_NOTE)
        announce_first_compile()
        _done = True


def announce_first_compile() -> None:
    """Say on standard error, before it starts, that this backend's kernels compile now: the first use on a
    machine compiles them into Warp's kernel cache (measured 4-8 s on a 2-core CPU with an empty cache,
    ``WARP_CACHE_PATH`` pointed at an empty folder), silently otherwise. Nothing is said once the cache holds
    them. The line goes above any progress bar being drawn (:func:`~cerberus_core.plumbing.stdio.announce`)."""
    from pathlib import Path

    cache = getattr(wp.config, "kernel_cache_dir", None)
    if cache and not any(Path(cache).glob("wp_cerberus_render_warp.*")):
        announce(f"cerberus-render-warp: compiling the Warp renderer's kernels into {cache} (once per machine and "
                 "Warp version: about 5 s on 2 CPU cores, longer on a busy machine)")
