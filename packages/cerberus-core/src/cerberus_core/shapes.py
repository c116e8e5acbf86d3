"""One shape check for tensors, like kornia's ``KORNIA_CHECK_SHAPE``: the shape written as a pattern.

>>> import torch
>>> check_shapes("pose_parts", local_vertices=(torch.zeros(2, 9, 162, 3), "... P V 3"),
...              rotations=(torch.zeros(2, 9, 3, 3), "... P 3 3"))
{'P': 9, 'V': 162}

A pattern is space-separated dimensions: a number must match exactly, a name binds a size that must
be the same everywhere it appears in one call (across all the tensors checked), ``_`` is any size, and
a leading ``...`` any number of leading dimensions (their sizes must match between tensors that share
them). A third element names the dtypes allowed (``(clip, "B V 4", FLOATS)``), and ``same_device=True``
asks every tensor of the call to be on one device. A mismatch raises
:class:`~cerberus_core.errors.ShapeError` (a ``ValueError``) whose message starts with the checking
function's name and gives every tensor's expected and actual shape or dtype, so the fix is visible;
tensors on different devices raise :class:`~cerberus_core.errors.DeviceError`.
"""
from __future__ import annotations

from cerberus_core.errors import DeviceError, InputTypeError, ShapeError


def _expected(pattern: str) -> str:
    return "(" + ", ".join(pattern.split()) + ")"


def _check_tensor(where: str, name: str, tensor: object, pattern: str) -> None:
    """:class:`InputTypeError` for an argument that is not an array (a torch tensor, or a numpy array where the
    function takes one)."""
    if not (hasattr(tensor, "shape") and hasattr(tensor, "dtype")):
        raise InputTypeError(f"{where}: {name} is a {type(tensor).__name__}, not a tensor of shape "
                             f"{_expected(pattern)}; pass torch.as_tensor(...)")


def check_shapes(where: str, *, same_device: bool = False, **tensors: tuple) -> dict[str, int]:
    """Check tensors against shape patterns (and dtypes, and one device) and return the sizes the names bound.

    Args:
        where: the function that checks (it starts the message).
        same_device: every tensor must be on one device.
        tensors: ``name=(tensor, "pattern")`` or ``name=(tensor, "pattern", allowed dtypes)``.
    Returns:
        ``{dimension name: size}``.
    Raises:
        InputTypeError: an argument that is not a tensor.
        ShapeError: ``"<where>: <name> must be (<pattern>), got (<shape>)"`` for the tensors that do
            not fit (or ``<name> must be float32 or float64, got int64``), with the sizes the other
            tensors bound.
        DeviceError: with ``same_device``, ``"<where>: a, b must be on one device, got cpu, cuda:0"``.
    """
    sizes: dict[str, int] = {}
    leading: tuple[int, ...] | None = None
    problems: list[str] = []
    for name, spec in tensors.items():
        tensor, pattern = spec[0], spec[1]
        _check_tensor(where, name, tensor, pattern)
        if len(spec) > 2 and tensor.dtype not in spec[2]:
            allowed = " or ".join(str(d).removeprefix("torch.") for d in spec[2])
            problems.append(f"{name} must be {allowed}, got {str(tensor.dtype).removeprefix('torch.')}")
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
        raise ShapeError(f"{where}: " + "; ".join(problems) + (f" (with {bound})" if bound else ""))
    if same_device and len({str(spec[0].device) for spec in tensors.values()}) > 1:
        raise DeviceError(f"{where}: {', '.join(tensors)} must be on one device, got "
                          f"{', '.join(str(spec[0].device) for spec in tensors.values())}; move them with .to(device)")
    if meta := [name for name, spec in tensors.items() if getattr(spec[0], "is_meta", False)]:
        raise DeviceError(f"{where}: {', '.join(meta)} on the meta device, which holds no values; pass tensors on the "
                          "cpu or a cuda device")
    return sizes


__all__ = ["check_shapes"]
