"""One configuration mechanism for training recipes and dataset presets.

* **Bundled presets** are YAML files inside the package (:class:`Presets`): training recipes in
  ``cerberus_core/configs/<name>.yaml`` (``cerberus train --preset``), dataset presets in
  ``cerberus_core/configs/data/<dataset>_<size>.yaml`` (``cerberus data generate --size``).
* ``extends: NAME`` (a preset of the same folder) or ``extends: path/to/other.yaml`` (relative to
  the file) loads that config first and applies this one on top; ``extends: [a, b]`` merges several,
  left to right, each shared ancestor once (:func:`load_raw`).
* ``--set key.sub=value`` overrides apply last; values are YAML (:func:`parse_overrides`):
  ``--set optim.lr=1e-4``, ``--set losses.pose_consistency=false``, ``--set splits.train.pairs=2000``.
* :func:`build` turns the merged mapping into typed dataclasses and checks every value against its
  type hint. Errors are :class:`~cerberus_core.errors.ConfigError` (a ``ValueError``) naming the
  dotted key, what is allowed (the type, the ``Literal`` choices, the valid keys) and, for a typo,
  the closest valid name ("did you mean").
"""
from __future__ import annotations

import contextlib
import math
import re
import sys
import types
import typing
from collections.abc import Iterable, Mapping
from dataclasses import MISSING, fields, is_dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import yaml

from cerberus_core.errors import ConfigError, shown
from cerberus_core.plumbing.names import did_you_mean

__all__ = ["Presets", "build", "deep_merge", "flatten", "load_raw", "load_yaml", "omit_defaults",
           "parse_overrides", "upgrade"]


# ------------------------------------------------------------------ mappings
def deep_merge(base: Mapping[str, Any], top: Mapping[str, Any]) -> dict[str, Any]:
    """Recursive dict merge: values of ``top`` win; nested mappings merge."""
    out = dict(base)
    for k, v in top.items():
        out[k] = deep_merge(out[k], v) if isinstance(v, dict) and isinstance(out.get(k), dict) else v
    return out


def flatten(d: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """``{"a": {"b": 1}}`` → ``{"a.b": 1}``."""
    out: dict[str, Any] = {}
    for k, v in d.items():
        if isinstance(v, Mapping):
            out.update(flatten(v, f"{prefix}{k}."))
        else:
            out[prefix + str(k)] = v
    return out


def omit_defaults(d: Mapping[str, Any], defaults: Mapping[str, Any]) -> dict[str, Any]:
    """``d`` without the keys whose value equals their entry in ``defaults``.

    The stored form of a config key added after configs were first written: it is written only when
    set, so a config from before the key (the key absent, its behaviour the default) keeps its form
    and its hash (the dataset manifest's ``config_sha256``).
    """
    return {k: v for k, v in d.items() if not (k in defaults and v == defaults[k])}


_INT, _FLOAT = "tag:yaml.org,2002:int", "tag:yaml.org,2002:float"

#: The deepest nesting of mappings and lists a config text may have (the deepest config key has 3 levels).
MAX_DEPTH = 16


class _StrictLoader(yaml.SafeLoader):
    """A safe YAML loader that refuses a mapping with the same key twice (PyYAML keeps the last one
    silently, so a config with ``steps`` written twice would train with whichever came last), a key
    that is not a name (a list or a mapping used as a key), nesting deeper than :data:`MAX_DEPTH`
    (which would end in a ``RecursionError``) and aliases (``*name``: nested ones expand a few hundred
    bytes into gigabytes; settings never need them). Numbers are read as YAML 1.2 reads them (issue 39):
    ``010`` is ten (YAML 1.1 read eight), ``1:30`` is text (1.1 read ninety, so an integer setting refuses
    it), ``0o10`` and ``0x10`` are octal and hexadecimal; booleans stay as PyYAML reads them."""

    yaml_implicit_resolvers = {first: [(tag, rx) for tag, rx in resolvers if tag not in (_INT, _FLOAT)]
                               for first, resolvers in yaml.SafeLoader.yaml_implicit_resolvers.items()}

    def __init__(self, stream) -> None:  # noqa: ANN001 - PyYAML's signature
        super().__init__(stream)
        self._depth = 0

    def compose_node(self, parent, index):  # noqa: ANN001 - PyYAML's signature
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.composer.ComposerError(None, None, f"an alias (*{str(event.anchor)[:40]}) repeats another "
                                              "value; settings take no aliases: write the value out", event.start_mark)
        self._depth += 1
        try:
            if self._depth > MAX_DEPTH:
                raise yaml.composer.ComposerError(None, None, f"nested deeper than {MAX_DEPTH} levels; a config "
                                                  "needs a few", self.peek_event().start_mark)
            return super().compose_node(parent, index)
        finally:
            self._depth -= 1

    def construct_mapping(self, node, deep=False):  # noqa: ANN001 - PyYAML's signature
        seen: dict[object, int] = {}
        for key_node, _ in node.value:
            if not isinstance(key_node, yaml.ScalarNode):
                raise yaml.constructor.ConstructorError(
                    None, None, f"a {'list' if isinstance(key_node, yaml.SequenceNode) else 'mapping'} is used as a "
                    "key; a key is a name", key_node.start_mark)
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                lines = sorted({seen[key] + 1, key_node.start_mark.line + 1})
                raise yaml.constructor.ConstructorError(
                    None, None, f"the key {key!r} is given twice ({'lines' if len(lines) > 1 else 'line'} "
                    f"{' and '.join(map(str, lines))}); keep one", key_node.start_mark)
            seen[key] = key_node.start_mark.line
        return super().construct_mapping(node, deep=deep)


def _construct_int(loader: _StrictLoader, node: yaml.ScalarNode) -> int:
    """A YAML 1.2 integer: decimal (a leading zero changes nothing), ``0o`` octal or ``0x`` hexadecimal."""
    text = loader.construct_scalar(node)
    sign, body = (-1 if text.startswith("-") else 1), text.lstrip("+-")
    base = {"0o": 8, "0x": 16}.get(body[:2], 10)
    return sign * int(body[2:] if base != 10 else body, base)


_StrictLoader.add_implicit_resolver(_INT, re.compile(r"^(?:[-+]?[0-9]+|0o[0-7]+|0x[0-9a-fA-F]+)$"),
                                    list("-+0123456789"))
_StrictLoader.add_implicit_resolver(_FLOAT, re.compile(
    r"^(?:[-+]?(?:\.[0-9]+|[0-9]+(?:\.[0-9]*)?)(?:[eE][-+]?[0-9]+)?|[-+]?\.(?:inf|Inf|INF)|\.(?:nan|NaN|NAN))$"),
    list("-+.0123456789"))
_StrictLoader.add_constructor(_INT, _construct_int)


def load_yaml(text: str, source: object = "config", fix: str = "fix the file") -> Any:
    """The one reader of config text (files, presets, saved configs and ``--set`` values): a safe load that
    refuses a key given twice in one mapping, a list or mapping as a key, nesting deeper than
    :data:`MAX_DEPTH` and aliases, and reads numbers as YAML 1.2 does (:class:`_StrictLoader`), each as one :class:`ConfigError` line ``SOURCE:LINE: not valid YAML (problem); FIX``."""
    try:
        return yaml.load(text, Loader=_StrictLoader)  # noqa: S506 - a SafeLoader subclass
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None) or getattr(exc, "context_mark", None)
        problem = getattr(exc, "problem", None) or getattr(exc, "context", None) or str(exc).splitlines()[0]
        where = f"{source}:{mark.line + 1}" if isinstance(exc, yaml.MarkedYAMLError) and mark is not None else f"{source}"
    except RecursionError:  # a guard of last resort: the composer stops at MAX_DEPTH first
        where, problem = f"{source}", f"nested deeper than {MAX_DEPTH} levels"
    except ValueError:  # PyYAML's int() of a number longer than Python reads (sys.get_int_max_str_digits)
        where, problem = f"{source}", f"a number of more than {sys.get_int_max_str_digits()} digits"
    raise ConfigError(f"{where}: not valid YAML ({problem}); {fix}", problem=problem, key="config")


def parse_overrides(items: Iterable[str], example: str = "optim.lr=0.0001") -> dict[str, Any]:
    """``["optim.lr=1e-4", "train.steps=10"]`` → nested dict (values parsed as YAML)."""
    out: dict[str, Any] = {}
    for item in items:
        key, eq, text = item.partition("=")
        if not eq or not key.strip() or any(not p for p in key.strip().split(".")):
            raise ConfigError.about("overrides", item, f"expected section.key=value, e.g. `{example}`")
        try:
            value = load_yaml(text, "value") if text.strip() else None
        except ConfigError as exc:
            raise ConfigError.about("overrides", item, f"the value is not valid YAML ({exc.problem}); close brackets "
                                    f"and quotes, e.g. `{example}`") from None
        node = out
        parts = key.strip().split(".")
        for p in parts[:-1]:
            child = node.setdefault(p, {})
            if not isinstance(child, dict):
                raise ConfigError.about("overrides", item, f"{p!r} was already given a value, not a section")
            node = child
        node[parts[-1]] = value
    return out


# ------------------------------------------------------------------ preset folders and files
class Presets:
    """A folder of bundled YAML presets inside a package (``cerberus_core``, or a plugin's own).

    Args:
        folder: path inside the package, ``/``-separated (``"configs"``, ``"configs/data"``).
        kind: what a preset is called in messages (``"preset"``).
        package: the importable package that holds the folder.
    """

    def __init__(self, folder: str, kind: str = "preset", package: str = "cerberus_core") -> None:
        self.folder, self.kind, self.package = folder, kind, package

    def _dir(self):
        return resources.files(self.package).joinpath(*self.folder.split("/"))

    def names(self) -> list[str]:
        """Names of the bundled presets (file stems)."""
        return sorted(p.name[:-5] for p in self._dir().iterdir() if p.name.endswith(".yaml") and p.is_file())

    def text(self, name: str) -> str:
        """The YAML text of preset ``name``; a :class:`ConfigError` naming the bundled ones otherwise."""
        res = self._dir().joinpath(f"{name}.yaml")
        if not res.is_file():
            raise ConfigError(f"unknown {self.kind} {name!r}{did_you_mean(name, self.names())}; bundled "
                              f"{self.kind}s: {', '.join(self.names())}", key=self.kind, value=name)
        return res.read_text()


def read_file(path: str | Path) -> str:
    """A config file's text; :class:`ConfigError` names the file when it is missing, not a regular file
    (a folder, a FIFO: checked before it is opened, so nothing blocks), unreadable or not UTF-8."""
    path = Path(path)
    try:
        if path.exists() and not path.is_file():
            raise ConfigError(f"config file {path} is not a regular file (a folder, FIFO or device); pass a YAML file", key="config", value=path)
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise ConfigError(f"config file {path} does not exist", key="config", value=path) from None
    except UnicodeDecodeError as exc:
        raise ConfigError(f"config file {path} is not UTF-8 text ({exc.reason} at byte {exc.start}); save it as "
                          "UTF-8", key="config", value=path) from None
    except OSError as exc:
        raise ConfigError(f"config file {path} cannot be read ({exc.strerror or exc}); check its permissions", key="config", value=path) from None


def load_raw(presets: Presets, path: str | Path | None = None, *, preset: str | list[str] | None = None,
             overrides: Iterable[str] = (), example: str = "optim.lr=0.0001") -> dict[str, Any]:
    """The merged mapping of a config file or bundled preset(s) (``extends`` resolved), plus ``--set``.

    ``preset`` may be a list, merged left to right like ``extends: [a, b]``. With neither ``path``
    nor ``preset`` only the overrides are returned.
    """
    if path is not None and preset is not None:
        raise ConfigError("give either a config file or a preset, not both (a file can say 'extends: PRESET')", key="preset", value=preset)
    layers: list[tuple[str, dict[str, Any]]] = []
    if path is not None:
        layers = _layers(read_file(path), str(path), Path(path).parent, presets)
    elif preset is not None:
        names = [preset] if isinstance(preset, str) else list(preset)
        layers = _layers(yaml.safe_dump({"extends": names}), f"{presets.kind}s {' + '.join(names)}", None, presets)
    raw: dict[str, Any] = {}
    for _, layer in layers:
        raw = deep_merge(raw, layer)
    return deep_merge(raw, parse_overrides(overrides, example))


def _layers(text: str, source: str, base_dir: Path | None, presets: Presets,
            depth: int = 0) -> list[tuple[str, dict[str, Any]]]:
    """The config and its ancestors as ``(source, mapping)`` layers, most basic first.

    ``extends: [a, b]`` lists a's layers, then b's layers not already listed, then this file's own:
    ``[cpu, nmrr]`` (both extending ``paper``) gives paper, cpu, nmrr, so the variant lands on the CPU
    schedule instead of bringing the paper's settings back.
    """
    if depth > 8:
        raise ConfigError(f"{source}: 'extends' chain deeper than 8 (a cycle?)", key="extends")
    raw = load_yaml(text, source) or {}
    if not isinstance(raw, dict):
        raise ConfigError(f"{source} must hold a YAML mapping of config sections", key="config")
    parents = raw.pop("extends", None)
    parents = [] if parents is None else parents if isinstance(parents, list) else [parents]
    layers: list[tuple[str, dict[str, Any]]] = []
    for parent in parents:
        parent = str(parent)
        if parent.endswith((".yaml", ".yml")):
            path = Path(parent) if base_dir is None or Path(parent).is_absolute() else base_dir / parent
            parent_layers = _layers(read_file(path), str(path.resolve()), path.parent, presets, depth + 1)
        else:
            parent_layers = _layers(presets.text(parent), f"{presets.kind} {parent}", None, presets, depth + 1)
        for layer in parent_layers:
            if layer[0] not in {name for name, _ in layers}:
                layers.append(layer)
    return [*layers, (source, raw)]


# ------------------------------------------------------------------ typed building
_EXACT = {bool: "true/false", str: "a string", type(None): "null"}
"""Types taken as they are (no conversion), with how an error message names them."""


def _hint_name(hint: Any) -> str:
    if hint in _EXACT:
        return _EXACT[hint]
    if typing.get_origin(hint) is typing.Literal:
        return "one of " + ", ".join(repr(o) for o in typing.get_args(hint))
    return {int: "an integer", float: "a number"}.get(hint, getattr(hint, "__name__", str(hint)))


def _coerce_union(value: Any, options: tuple, key: str) -> Any:
    for option in options:
        try:
            return coerce(value, option, key)
        except ConfigError:
            pass
    raise ConfigError(f"{key}: expected {' or '.join(_hint_name(o) for o in options)}, got {shown(value)}", key=key, value=value)


def _coerce_literal(value: Any, allowed: tuple, key: str) -> Any:
    if any(value == a and type(value) is type(a) for a in allowed):
        return value
    raise ConfigError(f"{key}: must be one of {', '.join(repr(a) for a in allowed)}, got {shown(value)}"
                      f"{did_you_mean(value, allowed)}", key=key, value=value)


def _coerce_int(value: Any, key: str) -> int:
    if isinstance(value, int) and not isinstance(value, bool):
        return value
    if isinstance(value, float) and value.is_integer():
        return int(value)
    raise ConfigError(f"{key}: expected an integer, got {shown(value)}", key=key, value=value)


def _coerce_float(value: Any, key: str) -> float:
    number = None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        number = float(value)
    elif isinstance(value, str):
        with contextlib.suppress(ValueError):
            number = float(value)  # YAML reads "5e-4" as a string
    if number is None:
        raise ConfigError(f"{key}: expected a number, got {shown(value)}", key=key, value=value)
    if not math.isfinite(number):  # .nan / .inf are YAML numbers, never sensible settings
        raise ConfigError.about(key, number, "must be a finite number")
    return number


def _coerce_sequence(value: Any, origin: type, args: tuple, key: str) -> list | tuple:
    if not isinstance(value, (list, tuple)):
        raise ConfigError(f"{key}: expected a list, got {shown(value)}", key=key, value=value)
    if origin is tuple and args and args[-1] is not Ellipsis:
        if len(value) != len(args):
            raise ConfigError(f"{key}: expected a list of {len(args)} values, got {shown(value)}", key=key, value=value)
        return tuple(coerce(v, a, f"{key}[{i}]") for i, (v, a) in enumerate(zip(value, args, strict=True)))
    item = args[0] if args else Any
    out = [coerce(v, item, f"{key}[{i}]") for i, v in enumerate(value)]
    return tuple(out) if origin is tuple else out


def _coerce_mapping(value: Any, args: tuple, key: str) -> dict:
    if not isinstance(value, Mapping):
        raise ConfigError(f"{key}: expected a mapping, got {shown(value)}", key=key, value=value)
    _, item = args or (str, Any)
    return {str(k): coerce(v, item, f"{key}.{k}") for k, v in value.items()}


def coerce(value: Any, hint: Any, key: str) -> Any:
    """Check/convert one value against a type hint; :class:`ConfigError` names the key on mismatch."""
    origin = typing.get_origin(hint)
    if origin in (typing.Union, types.UnionType):
        return _coerce_union(value, typing.get_args(hint), key)
    if origin is typing.Literal:
        return _coerce_literal(value, typing.get_args(hint), key)
    if hint is Any:
        return value
    if hint in _EXACT:
        if isinstance(value, hint):
            return value
        raise ConfigError(f"{key}: expected {_EXACT[hint]}, got {shown(value)}", key=key, value=value)
    if hint is int:
        return _coerce_int(value, key)
    if hint is float:
        return _coerce_float(value, key)
    if origin in (list, tuple):
        return _coerce_sequence(value, origin, typing.get_args(hint), key)
    if origin is dict:
        return _coerce_mapping(value, typing.get_args(hint), key)
    if is_dataclass(hint):
        return build(hint, value, key + ".")
    return value


def upgrade(cls: type, d: Any) -> Any:
    """A saved mapping of ``cls`` with the keys an earlier version wrote under other names converted (each
    section's ``RENAMED`` table, :class:`~cerberus_core.fields.Checked`, in every section that is a dataclass);
    anything else is left for :func:`build` to judge (an old key beside its new one, or with a value the table does
    not list, stays, and :func:`build` names it).

    Example:
        >>> from cerberus_core.train.settings import TrainConfig
        >>> upgrade(TrainConfig, {"model": {"predict_rotation": False, "num_parts": 4}})
        {'model': {'rotation': 'none', 'num_parts': 4}}
    """
    if not isinstance(d, Mapping):
        return d
    hints = typing.get_type_hints(cls)
    renamed = getattr(cls, "RENAMED", {})
    out: dict[Any, Any] = {}
    for key, value in d.items():
        new, values = renamed.get(key, (None, {}))
        match = [b for a, b in values.items() if type(value) is type(a) and value == a]  # 1 is not True
        if new is not None and new not in d and match:
            out[new] = match[0]
        else:  # an old key beside its new one, or with a value the table does not know: build names it
            out[key] = upgrade(hints[key], value) if key in hints and is_dataclass(hints[key]) else value
    return out


def check_known(keys: Iterable[Any], known: Iterable[str], prefix: str = "") -> None:
    """Every one of ``keys`` is one of ``known`` (the settings of one section, said under ``prefix``), else a
    :class:`ConfigError` naming the unknown ones, the closest valid key and the valid keys.

    >>> check_known(["skipp"], ["skip", "limit"])
    Traceback (most recent call last):
    ...
    cerberus_core.errors.ConfigError: unknown config key(s) ['skipp'] (did you mean 'skip'?); valid keys here: ['limit', 'skip']
    """
    known = list(known)
    unknown = sorted(set(keys) - set(known), key=str)  # a YAML key may be a number
    if unknown:
        raise ConfigError(f"unknown config key(s) {[prefix + str(k) for k in unknown]}"
                          f"{did_you_mean(prefix + str(unknown[0]), [prefix + k for k in known])}; "
                          f"valid keys here: {sorted(prefix + k for k in known)}", key=prefix + str(unknown[0]))


def build(cls: type, d: Any, prefix: str = "") -> Any:
    """The dataclass ``cls`` from a plain mapping, every value checked against its type hint.

    Raises:
        ConfigError: an unknown key (with the closest valid one and the list of valid keys), a
            missing required key, a value of the wrong type or outside a ``Literal``, or the
            dataclass's own checks (:class:`~cerberus_core.fields.Checked`: its key under this section).
    """
    section = prefix[:-1] if prefix else "config"
    if not isinstance(d, Mapping):
        raise ConfigError(f"{section}: expected a mapping of {sorted(f.name for f in fields(cls))}, got {shown(d)}", key=section, value=d)
    hints = typing.get_type_hints(cls)
    known = [f.name for f in fields(cls) if f.init]
    unknown = sorted(set(d) - set(known), key=str)  # a YAML key may be a number
    renamed = getattr(cls, "RENAMED", {})
    if retired := [k for k in unknown if k in renamed]:
        new, values = renamed[retired[0]]
        conversions = ", ".join(f"{str(a).lower() if isinstance(a, bool) else a} → {b}" for a, b in values.items())
        raise ConfigError(f"{prefix}{retired[0]} became {prefix}{new} ({conversions}); remove {prefix}{retired[0]} "
                          f"and write `{prefix}{new}=VALUE` in its place", key=prefix + str(retired[0]))
    check_known(d, known, prefix)
    missing = [f.name for f in fields(cls)
               if f.init and f.name not in d and f.default is MISSING and f.default_factory is MISSING]
    if missing:
        raise ConfigError(f"{prefix}{missing[0]}: required, no default", key=prefix + missing[0])
    kwargs = {k: coerce(v, hints[k], prefix + k) for k, v in d.items()}
    try:
        return cls(**kwargs)
    except ConfigError as exc:  # a settings class's own check (fields.Checked): its key said under this section
        raise exc.within(prefix) from None
