"""Pretrained models shipped with the toolkit: ``Run.load("human")`` works right after install.

Each model is three files in this folder, all package data:

* ``NAME.safetensors`` — the weights, with the training config and the scene set-up (camera
  elevation, distance, field of view, light, background) in the safetensors metadata, so a model
  is self-contained. Loaded only with safetensors (never pickle).
* ``NAME.json`` — the registry entry: the file's SHA-256 (checked on every load), a one-line
  summary, the figures of its model card (test IoU, part quality, training time) and each learned part's
  label (the ground-truth part it covers most, from the card's part table).
* ``NAME.md`` — the model card: data, preset, exact commands, results, machine, what changed.

``cerberus models`` lists them; :func:`model_path` resolves a name to its verified weights file.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from cerberus_core.datasets.format import sha256_file  # the project's one file checksum
from cerberus_core.errors import ZooError
from cerberus_core.plumbing.names import printable

ZOO_DIR = Path(__file__).resolve().parent
"""Where the shipped models live."""


@dataclass(frozen=True)
class PretrainedModel:
    """One shipped model (the fields of ``NAME.json``).

    Attributes:
        name: what ``Run.load`` and ``cerberus reconstruct --model`` take.
        summary: one line.
        weights: file name of the safetensors weights beside the entry.
        sha256: hex digest of the weights file.
        card: file name of the model card.
        results: headline figures of the card (e.g. ``test_iou``), for ``cerberus models``.
        data: the dataset it was trained and scored on, ``{"dataset": ..., "size": ...}``: regenerate
            its test split with ``cerberus data generate --dataset DATASET --size SIZE``.
        part_labels: per learned part, in order, the ground-truth part it covers most over the test
            images (``cerberus eval``'s part quality; the card's part table), ``None`` for a part that
            covers nothing; empty when unknown. Shown by the 3D viewer beside ``part_00``...
    """

    name: str
    summary: str
    weights: str
    sha256: str
    card: str
    results: dict[str, Any] = field(default_factory=dict)
    data: dict[str, str] = field(default_factory=dict)
    part_labels: list[str | None] = field(default_factory=list)

    @property
    def path(self) -> Path:
        return ZOO_DIR / self.weights

    @property
    def card_path(self) -> Path:
        return ZOO_DIR / self.card


def _entry(path: Path) -> PretrainedModel:
    """One registry entry, checked: JSON of the :class:`PretrainedModel` fields with the right types, its
    ``weights`` and ``card`` plain file names in the zoo folder (never a path elsewhere).

    Raises:
        ZooError: naming the entry, what is wrong and the fix (a damaged install: reinstall cerberus-core).
    """
    from dataclasses import fields

    fix = "the install is damaged or was edited: reinstall cerberus-core"
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError) as exc:
        raise ZooError(f"model registry entry {path}: not readable JSON ({printable(exc)}); {fix}") from None
    if not isinstance(data, dict):
        raise ZooError(f"model registry entry {path}: expected a JSON object, got {type(data).__name__}; {fix}")
    names = {f.name for f in fields(PretrainedModel)}
    missing = sorted(names - set(data) - {"results", "data", "part_labels"})
    unknown = sorted(set(data) - names)
    if missing or unknown:
        raise ZooError(f"model registry entry {path}: " + "; ".join(
            ([f"missing {missing}"] if missing else []) + ([f"unknown {printable(unknown)}"] if unknown else []))
            + f"; {fix}")
    for key in ("name", "summary", "weights", "sha256", "card"):
        if not isinstance(data[key], str):
            raise ZooError(f"model registry entry {path}: {key!r} must be a string; {fix}")
    for key in ("results", "data"):
        if not isinstance(data.get(key, {}), dict):
            raise ZooError(f"model registry entry {path}: {key!r} must be a JSON object; {fix}")
    labels = data.get("part_labels", [])
    if not isinstance(labels, list) or not all(label is None or isinstance(label, str) for label in labels):
        raise ZooError(f"model registry entry {path}: 'part_labels' must be a JSON list of strings (null for a part "
                       f"that covers nothing); {fix}")
    for key, suffix in (("weights", ".safetensors"), ("card", ".md")):
        value = data[key]
        if Path(value).name != value or value in ("", ".", "..") or "\\" in value or not value.endswith(suffix):
            raise ZooError(f"model registry entry {path}: {key!r} is {printable(repr(value))}; it must name a "
                           f"{suffix} file beside the entry (no folders); {fix}")
    return PretrainedModel(**data)


def available() -> dict[str, PretrainedModel]:
    """Every shipped model by name (read from the ``*.json`` entries; cheap, no weights loaded).

    Raises:
        ZooError: an entry is not valid JSON, lacks a field, or names a file outside the zoo folder.
    """
    out: dict[str, PretrainedModel] = {}
    for entry in sorted(ZOO_DIR.glob("*.json")):
        model = _entry(entry)
        out[model.name] = model
    return out


def model_path(name: str) -> Path:
    """The verified weights file of a shipped model.

    Raises:
        ZooError: unknown name (the message lists the shipped ones), a missing file, or a checksum
            mismatch (a damaged install: reinstall cerberus-core).
    """
    models = available()
    if name not in models:
        names = ", ".join(sorted(models)) or "none"
        raise ZooError(f"no pretrained model named {name!r} (shipped: {names}); give a run folder, a "
                       ".safetensors file or one of those names")
    model = models[name]
    if not model.path.is_file():
        raise ZooError(f"pretrained model {name!r}: {model.path} is missing; reinstall cerberus-core")
    actual = sha256_file(model.path)
    if actual != model.sha256:
        raise ZooError(f"pretrained model {name!r}: {model.path} fails its checksum (sha256 {actual[:12]}..., "
                       f"expected {model.sha256[:12]}...); the file is damaged: reinstall cerberus-core")
    return model.path
