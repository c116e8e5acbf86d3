"""What every kernel module of this package shares: the module options its kernels compile with, the
split of threads over scenes and items, and the float32/float64 overloads of a generic kernel.

Each kernel module starts with::

    from cerberus_render_warp._common import KERNEL_OPTIONS, Tensor, span, wp

    wp.set_module_options(KERNEL_OPTIONS)

(Warp keeps options per Python module, so each module sets them itself.) The ``@wp.func`` helpers
here are defined at module level, where Warp finds them, and are compiled into every module whose
kernels call them, with that module's options.
"""
from __future__ import annotations

from typing import Any

import torch

from cerberus_render_warp._runtime import wp

Tensor = torch.Tensor

KERNEL_OPTIONS: dict[str, Any] = {"fuse_fp": False, "enable_backward": False}
"""No FMA contraction, so that every ``a * b + c`` rounds twice as the separate torch ops do
(:mod:`.arith`); no generated adjoints (the backward kernels are written by hand)."""

wp.set_module_options(KERNEL_OPTIONS)


@wp.func
def span(tid: int, count: int, per_thread: int):
    """Thread ``tid`` -> scene ``b`` and its item range ``[first, last)`` of the scene's ``count``
    items, ``per_thread`` items a thread (thread ``t = b * chunks + k`` takes chunk ``k``)."""
    chunks = (count + per_thread - 1) / per_thread
    b = tid / chunks
    first = (tid - b * chunks) * per_thread
    return b, first, wp.min(first + per_thread, count)


@wp.func
def row_span(tid: int, height: int, width: int, cols_per_thread: int):
    """Thread ``tid`` -> scene ``b``, image row ``r`` and its column range ``[c_first, c_last)``: the
    :func:`span` of the ``height`` rows of every scene, each row ``width`` columns."""
    row_id, c_first, c_last = span(tid, width, cols_per_thread)
    b = row_id / height
    return b, row_id - b * height, c_first, c_last


def overloads(kernel, vec3: dict[str, Any], vec4: dict[str, Any], scalar: dict[str, Any]) -> dict[torch.dtype, Any]:
    """Concrete float32 and float64 overloads of a generic kernel, keyed by torch dtype. The dicts map
    argument names to array constructors whose dtype is a 3-vector, a 4-vector or a scalar."""
    out = {}
    for dtype, t in ((torch.float32, wp.float32), (torch.float64, wp.float64)):
        v3, v4 = wp.types.vector(3, t), wp.types.vector(4, t)
        args = {**{k: ctor(dtype=v3) for k, ctor in vec3.items()}, **{k: ctor(dtype=v4) for k, ctor in vec4.items()},
                **{k: ctor(dtype=t) for k, ctor in scalar.items()}}
        out[dtype] = wp.overload(kernel, args)
    return out
