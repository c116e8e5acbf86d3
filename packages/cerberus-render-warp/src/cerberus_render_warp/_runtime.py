"""Lazy, quiet access to NVIDIA Warp: import check, one-time initialisation, device and stream mapping.

Importing this module imports ``warp`` (so a missing install fails early, with the package to
install in the message) but does not initialise it; :func:`ensure_init` does that on first use.
"""
from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import torch

from cerberus_core.errors import BackendError, DeviceError, MissingPackageError

WARP_REQUIREMENT = "warp-lang>=1.19"

try:
    import warp as wp
except ImportError as exc:  # pragma: no cover - exercised only without warp installed
    raise MissingPackageError(
        f"the 'warp' renderer needs NVIDIA Warp, which could not be imported ({exc}). "
        f"Install it with `pip install '{WARP_REQUIREMENT}'`, or use the 'torch' renderer."
    ) from exc

from cerberus_render_warp.quiet import init_warp_quietly, quiet_warp_logging  # noqa: E402 (after the import check)

quiet_warp_logging()  # no banner on init, no "module loaded/compiled" lines
_pool_lock = threading.Lock()


class WarpInitError(BackendError):
    """Warp is installed but its runtime could not be initialised."""


def ensure_init() -> None:
    """Initialise the Warp runtime once (thread-safe, quiet: :func:`cerberus_render_warp.quiet.init_warp_quietly`,
    which returns at once after the first success)."""
    try:
        init_warp_quietly()
    except Exception as exc:  # noqa: BLE001 - any init failure gets the same hint
        raise WarpInitError(
            f"NVIDIA Warp failed to initialise ({type(exc).__name__}: {exc}). Reinstall it with "
            f"`pip install --force-reinstall '{WARP_REQUIREMENT}'`, or use the 'torch' renderer."
        ) from exc


def warp_device(device: torch.device):
    """The Warp device for a torch device (``cpu`` or the matching ``cuda:N``)."""
    ensure_init()
    if device.type not in ("cpu", "cuda"):
        raise DeviceError(f"the 'warp' renderer runs on cpu or cuda tensors, got device {device}; move the tensors "
                          "there, or use the 'torch' renderer")
    try:
        return wp.device_from_torch(device)
    except RuntimeError as exc:
        raise BackendError(
            f"Warp has no device matching torch device {device} ({exc}); check the NVIDIA driver, "
            "or move the tensors to the CPU"
        ) from exc


def launch_stream(device: torch.device):
    """Warp stream aliasing torch's current stream on a CUDA device (``None`` on the CPU)."""
    if device.type != "cuda":
        return None
    return wp.stream_from_torch(torch.cuda.current_stream(device))


def as_warp(t: torch.Tensor | None, dtype=None):
    """Zero-copy Warp view of a torch tensor (strides kept, no gradient attached); ``None`` stays
    ``None`` (an absent optional kernel argument). With a vector ``dtype`` the last dimension
    becomes the vector (it must be contiguous)."""
    if t is None:
        return None
    ensure_init()
    return wp.from_torch(t, dtype=dtype, requires_grad=False)


ONE_ITEM_PER_THREAD = False
"""Force the CUDA thread layout (one Warp thread per pixel / face / vertex) on the CPU too; the
tests use it to run the CUDA code paths on a machine without a GPU."""


def items_per_thread(count: int, device) -> int:
    """How many consecutive items (pixels of a row, faces, vertices) one Warp thread handles: all of
    a scene's on the CPU, where Warp runs a launch's threads one after another and fewer, longer
    threads cost less; one on CUDA."""
    return max(count, 1) if device.is_cpu and not ONE_ITEM_PER_THREAD else 1


def vec_view(t: torch.Tensor | None):
    """Warp view of a float ``(..., 3)`` or ``(..., 4)`` tensor as an array of vectors. The last
    dimension is made contiguous if it is not; the others keep their strides (zero strides of
    expanded tensors included)."""
    if t is None:
        return None
    if t.stride(-1) != 1:
        t = t.contiguous()
    scalar = wp.float32 if t.dtype == torch.float32 else wp.float64
    return as_warp(t, wp.types.vector(t.shape[-1], scalar))


_pool: ThreadPoolExecutor | None = None
_loaded: set[tuple[int, str]] = set()
_pool_size = 0

MIN_SCENES_PER_THREAD = 2
"""Below this many scenes per CPU thread a launch is not split (thread hand-off costs more)."""


def _cpu_pool(threads: int) -> ThreadPoolExecutor:
    global _pool, _pool_size
    with _pool_lock:
        if _pool is None or _pool_size != threads:
            if _pool is not None:
                _pool.shutdown(wait=False)
            _pool = ThreadPoolExecutor(threads, thread_name_prefix="cerberus-warp")
            _pool_size = threads
        return _pool


def launch_scenes(kernel, batch: int, threads_per_scene: int, make_inputs: Callable[[int, int], list[Any]],
                  device, stream=None) -> None:
    """Launch ``kernel`` over ``batch`` scenes, ``threads_per_scene`` Warp threads each.

    ``make_inputs(b0, b1)`` returns the kernel arguments for scenes ``b0 .. b1 - 1`` (batch-major
    tensors sliced to those scenes). Warp runs a CPU launch on one core, so on the CPU the scenes are
    split into ``torch.get_num_threads()`` contiguous chunks launched from a thread pool (Warp releases
    the GIL while a kernel runs); every kernel here writes only to its own scenes, so the chunks are
    independent. On CUDA it is one launch on ``stream``.
    """
    if batch == 0 or threads_per_scene == 0:
        return
    threads = min(torch.get_num_threads(), batch // MIN_SCENES_PER_THREAD) if device.is_cpu else 1
    key = (id(kernel), str(device))
    if threads <= 1 or key not in _loaded:
        # The first launch of a kernel on a device loads (maybe compiles) its module: do it once, here.
        wp.launch(kernel, dim=batch * threads_per_scene, inputs=make_inputs(0, batch), device=device, stream=stream)
        _loaded.add(key)
        return
    bounds = [batch * k // threads for k in range(threads + 1)]
    futures = [
        _cpu_pool(threads).submit(wp.launch, kernel, dim=(b1 - b0) * threads_per_scene, inputs=make_inputs(b0, b1),
                                  device=device)
        for b0, b1 in zip(bounds[:-1], bounds[1:], strict=False)
    ]
    for fut in futures:
        fut.result()
