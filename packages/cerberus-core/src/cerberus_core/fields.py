"""Config fields whose allowed values are declared as data, checked where the object is made.

A settings dataclass declares each field's type with its hint (``Literal`` for a choice, which
:func:`cerberus_core.config.build` enforces when a YAML file or ``--set`` is read) and each number's
range with :func:`ranged` in the field's metadata. Deriving from :class:`Checked` checks every
range and every ``Literal`` when the object is constructed, from a file or from Python, and raises
:class:`~cerberus_core.errors.ConfigError` there, at the source, naming the dotted key, the value,
the range and the fix in Python terms (the ``cerberus`` command says it as ``--set`` or its flag)::

    @dataclass
    class OptimConfig(Checked):
        SECTION = "optim"
        lr: float = ranged(0.0005, gt=0)

    OptimConfig(lr=0)
    # ConfigError: optim.lr = 0: must be a number > 0 (`optim.lr=VALUE`)

Checks that relate two fields stay in the class's ``validate()``, which :meth:`Checked.check` calls
after the ranges; they raise :class:`ConfigError` too. Call ``check()`` again after changing a field
in place. Nothing here imports torch.
"""
from __future__ import annotations

import functools
import math
import numbers
import os
import types
import typing
from collections.abc import Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

from cerberus_core.errors import ConfigError, InputTypeError

__all__ = ["Checked", "Range", "check_fields", "check_kind", "check_path", "check_paths", "check_value", "ranged"]

RANGE = "cerberus.range"
"""The ``dataclasses.field`` metadata key that holds a field's :class:`Range`."""


@dataclass(frozen=True)
class Range:
    """An interval of allowed numbers; ``integer`` also demands a whole number (not a bool).

    ``None`` bounds are open; a value of ``None`` always passes (whether ``null`` is allowed is the
    type hint's business).
    """

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    integer: bool = False

    def admits(self, value: Any) -> bool:
        if value is None:
            return True
        if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(value):
            return False
        if self.integer and not isinstance(value, numbers.Integral):
            return False
        return not ((self.ge is not None and value < self.ge) or (self.gt is not None and value <= self.gt)
                    or (self.le is not None and value > self.le) or (self.lt is not None and value >= self.lt))

    def describe(self) -> str:
        """``"an integer >= 1"``, ``"a number in [0, 1)"``, ``"a number > 0"``..."""
        kind = "an integer" if self.integer else "a number"
        low = (f"[{self.ge:g}" if self.ge is not None else f"({self.gt:g}" if self.gt is not None else None)
        high = (f"{self.le:g}]" if self.le is not None else f"{self.lt:g})" if self.lt is not None else None)
        if low and high:
            return f"{kind} in {low}, {high}"
        if low:
            return f"{kind} {'>=' if self.ge is not None else '>'} {low[1:]}"
        if high:
            return f"{kind} {'<=' if self.le is not None else '<'} {high[:-1]}"
        return f"a finite {kind.split()[-1]}"


def check_value(key: str, value: Any, allowed: Range, fix: str = "") -> Any:
    """``value`` of the parameter ``key``, or :class:`ConfigError` naming it when it is outside ``allowed``
    (a function's parameter checked like a settings field: the API and the command check with this one)."""
    if not allowed.admits(value) or value is None:
        raise ConfigError.about(key, value, f"must be {allowed.describe()}", fix)
    return value


def _shown(value: Any) -> str:
    text = repr(value)
    return f"{type(value).__name__} {text if len(text) <= 40 else text[:37] + '...'}"


def check_kind(key: str, value: Any, kind: type | tuple[type, ...], what: str) -> Any:
    """``value`` of the parameter ``key`` when it is a ``kind``, else :class:`InputTypeError` naming the parameter,
    what came and ``what`` is taken (``"an EvalSettings"``): a public function's object parameter checked before
    it is used, not an ``AttributeError`` midway."""
    if not isinstance(value, kind):
        raise InputTypeError(f"{key}: got {_shown(value)}; pass {what}")
    return value


def check_path(key: str, value: Any) -> Path:
    """The parameter ``key`` as a :class:`~pathlib.Path` (it takes a ``str`` or path-like object), else
    :class:`InputTypeError` naming it (not ``TypeError: expected str, bytes or os.PathLike object``)."""
    if isinstance(value, bytes) or not isinstance(value, (str, os.PathLike)) or not os.fspath(value):
        raise InputTypeError(f"{key}: got {_shown(value)}; pass a path (a str or pathlib.Path, not empty)")
    return Path(value)


def check_paths(key: str, value: Any) -> list[Path]:
    """The parameter ``key``, a sequence of paths, as a list of :class:`~pathlib.Path`; :class:`InputTypeError` for
    one path alone (a ``str`` would otherwise be read one character at a time) or an item that is not a path."""
    if isinstance(value, (str, bytes, os.PathLike)) or not isinstance(value, Sequence):
        raise InputTypeError(f"{key}: got {_shown(value)}; pass a list of paths (e.g. [{key[:-1] or 'path'}])")
    return [check_path(f"{key}[{i}]", item) for i, item in enumerate(value)]


def ranged(default: Any, *, ge: float | None = None, gt: float | None = None, le: float | None = None,
           lt: float | None = None, integer: bool | None = None) -> Any:
    """A dataclass field with a default and a declared range (``integer`` defaults to whether the
    default is an ``int``)."""
    whole = isinstance(default, int) and not isinstance(default, bool) if integer is None else integer
    return field(default=default, metadata={RANGE: Range(ge, gt, le, lt, whole)})


@functools.cache
def _choices(cls: type) -> dict[str, tuple]:
    """``{field: allowed values}`` of the fields whose hint is a ``Literal`` (or ``Literal | None``)."""
    out = {}
    for name, hint in typing.get_type_hints(cls).items():
        options = typing.get_args(hint) if typing.get_origin(hint) in (typing.Union, types.UnionType) else (hint,)
        literals = [o for o in options if typing.get_origin(o) is typing.Literal]
        if literals and all(o is type(None) or typing.get_origin(o) is typing.Literal for o in options):
            out[name] = tuple(v for o in literals for v in typing.get_args(o)) + \
                ((None,) if type(None) in options else ())
    return out


def check_fields(obj: Any, section: str = "") -> None:
    """Raise :class:`ConfigError` for the first field of the dataclass ``obj`` outside its range or
    its ``Literal`` choices.

    Args:
        section: the dotted prefix of the keys in messages (``"model"`` → ``model.width``).
    """
    prefix = f"{section}." if section else ""
    choices = _choices(type(obj))
    fix = getattr(type(obj), "FIX", Checked.FIX)
    for f in fields(obj):
        value, key = getattr(obj, f.name), f"{prefix}{f.name}"
        problem = None
        if f.name in choices and value not in choices[f.name]:
            problem = "must be one of " + ", ".join("null" if c is None else repr(c) for c in choices[f.name])
        rng = f.metadata.get(RANGE)
        if problem is None and rng is not None and not rng.admits(value):
            problem = f"must be {rng.describe()}"
        if problem is not None:
            raise ConfigError.about(key, value, problem, fix.format(key=key, cls=type(obj).__name__))


class Checked:
    """Mixin of a settings dataclass: ranges (:func:`ranged`) and then ``validate()`` (the checks
    between fields) run on construction. ``SECTION`` is the config section the keys live under;
    ``FIX`` how a message says to fix a field in Python terms (a config section: its key,
    `` `optim.lr=VALUE` ``; a settings object made in Python: ``EvalSettings(resolution=...)``)."""

    SECTION: ClassVar[str] = ""
    FIX: ClassVar[str] = "`{key}=VALUE`"
    """How a message says to fix a field (``{key}``: the dotted key, ``{cls}``: the class name)."""
    RENAMED: ClassVar[dict[str, tuple[str, dict[Any, Any]]]] = {}
    """Keys an earlier version wrote: ``old → (new, {old value: new value})``. A saved config (a run's
    ``config.yaml``, a checkpoint, a model file) is read with them converted
    (:func:`cerberus_core.config.upgrade`); a config someone writes now is told the new key."""

    def __post_init__(self) -> None:
        self.check()

    def check(self) -> None:
        """Check the ranges, then :meth:`validate` (again after changing a field in place)."""
        check_fields(self, self.SECTION)
        self.validate()

    def validate(self) -> None:
        """Checks between fields (override); raise :class:`ConfigError` naming the keys and the fix."""
