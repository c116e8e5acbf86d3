"""Floating-point helpers that reproduce torch's arithmetic bit for bit.

Face ids must agree with the torch backend, so the edge functions are computed with the same
roundings as torch. Kernels in this package are compiled with FMA contraction off (module option
``fuse_fp=False``), so every ``a * b + c`` rounds twice as separate torch ops do. The one place where
torch itself fuses is :func:`torch.linalg.cross`: its vectorised CPU kernel (AVX2 builds) computes
``a_i b_j - a_j b_i`` as ``fma(a_i, b_j, -(a_j b_i))``, while other builds round both products.
:func:`torch_cross_is_fused` probes which one the running torch uses on a device, and the kernels
take the answer as a flag.
"""
from __future__ import annotations

from typing import Any

import torch

from cerberus_render_warp._runtime import wp


@wp.func_native("return fmaf(a, b, c);")
def fma(a: wp.float32, b: wp.float32, c: wp.float32) -> wp.float32:  # pragma: no cover - native stub
    """``a * b + c`` with one rounding (float32)."""
    ...


@wp.func_native("return fma(a, b, c);")
def fma(a: wp.float64, b: wp.float64, c: wp.float64) -> wp.float64:  # noqa: F811  # pragma: no cover
    """``a * b + c`` with one rounding (float64)."""
    ...


@wp.func
def cross_term(ai: Any, bj: Any, aj: Any, bi: Any, fused: int):
    """One component ``ai * bj - aj * bi`` of a cross product, rounded as torch rounds it."""
    if fused != 0:
        return fma(ai, bj, -(aj * bi))
    return ai * bj - aj * bi


@wp.func
def cross(a: Any, b: Any, fused: int):
    """``a x b`` of 3-vectors, each component rounded as :func:`torch.linalg.cross` rounds it."""
    return wp.vector(cross_term(a[1], b[2], a[2], b[1], fused),
                     cross_term(a[2], b[0], a[0], b[2], fused),
                     cross_term(a[0], b[1], a[1], b[0], fused))


_FUSED_CACHE: dict[tuple[str, torch.dtype], int] = {}


def torch_cross_is_fused(device: torch.device, dtype: torch.dtype) -> int:
    """1 if ``torch.linalg.cross`` on ``device``/``dtype`` differs from the twice-rounded formula
    (i.e. torch fuses it into an FMA), else 0. Probed once per (device type, dtype)."""
    key = (str(device), dtype)
    if key not in _FUSED_CACHE:
        gen = torch.Generator().manual_seed(1234)
        a = torch.randn(256, 3, generator=gen, dtype=torch.float64).to(device=device, dtype=dtype)
        b = torch.randn(256, 3, generator=gen, dtype=torch.float64).to(device=device, dtype=dtype)
        crossed = torch.linalg.cross(a, b, dim=-1)
        plain = torch.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                             a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                             a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], dim=-1)
        _FUSED_CACHE[key] = 0 if bool(torch.equal(crossed, plain)) else 1
    return _FUSED_CACHE[key]
