"""One shape check for tensors, like kornia's ``KORNIA_CHECK_SHAPE``: the shape written as a pattern.

>>> import torch
>>> check_shapes("pose_parts", local_vertices=(torch.zeros(2, 9, 162, 3), "... P V 3"),
...              rotations=(torch.zeros(2, 9, 3, 3), "... P 3 3"))
{'P': 9, 'V': 162}

A pattern is space-separated dimensions: a number must match exactly, a name binds a size that must
be the same everywhere it appears in one call (across all the tensors checked), ``_`` is any size, and
a leading ``...`` any number of leading dimensions (their sizes must match between tensors that share
them). A mismatch raises ``ValueError`` whose message starts with the checking function's name and
gives every tensor's expected and actual shape, so the fix is visible.
"""
from __future__ import annotations

from typing import Any


def _expected(pattern: str) -> str:
    return "(" + ", ".join(pattern.split()) + ")"


def check_shapes(where: str, **tensors: tuple[Any, str]) -> dict[str, int]:
    """Check tensors against shape patterns and return the sizes the names bound.

    Args:
        where: the function that checks (it starts the message).
        tensors: ``name=(tensor, "pattern")``.
    Returns:
        ``{dimension name: size}``.
    Raises:
        ValueError: ``"<where>: <name> must be (<pattern>), got (<shape>)"`` for the tensors that do
            not fit, with the sizes the other tensors bound.
    """
    sizes: dict[str, int] = {}
    leading: tuple[int, ...] | None = None
    problems: list[str] = []
    for name, (tensor, pattern) in tensors.items():
        dims = pattern.split()
        shape = tuple(tensor.shape)
        ellipsis = bool(dims) and dims[0] == "..."
        fixed = dims[1:] if ellipsis else dims
        ok = len(shape) >= len(fixed) if ellipsis else len(shape) == len(fixed)
        if ok:
            head, tail = shape[:len(shape) - len(fixed)], shape[len(shape) - len(fixed):]
            if ellipsis and leading is not None and head != leading:
                ok = False
            for dim, size in zip(fixed, tail, strict=True):
                if dim == "_":
                    continue
                if dim.isdigit():
                    ok = ok and size == int(dim)
                elif sizes.setdefault(dim, size) != size:
                    ok = False
            if ok and ellipsis:
                leading = head
        if not ok:
            problems.append(f"{name} must be {_expected(pattern)}, got {shape}")
    if problems:
        bound = ", ".join(f"{k}={v}" for k, v in sizes.items())
        raise ValueError(f"{where}: " + "; ".join(problems) + (f" (with {bound})" if bound else ""))
    return sizes


__all__ = ["check_shapes"]
