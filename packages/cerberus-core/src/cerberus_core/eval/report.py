"""Evaluation results as JSON and Markdown.

JSON is strict (NaN and infinity are written as ``null``) and written atomically. Markdown reports
work from the JSON form (:meth:`EvaluationResult.to_dict`), so a report can be remade from a saved
``results.json``; :func:`comparison_table` builds the paper's Table 1 (models x test sets).
"""
from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from cerberus_core.eval.diagnostics import DIAGNOSTICS
from cerberus_core.eval.markdown import markdown_table, md_text
from cerberus_core.eval.runner import EvaluationResult
from cerberus_core.eval.standard import open_ground_truths
from cerberus_core.plumbing.atomic import atomic_write_text


def _finite(obj: Any) -> Any:
    """Replace NaN / inf by ``None`` everywhere (strict JSON)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, Mapping):
        return {str(k): _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if hasattr(obj, "item") and callable(obj.item) and getattr(obj, "ndim", None) == 0:
        return _finite(obj.item())  # numpy / torch scalars
    return obj


def to_jsonable(result: EvaluationResult | Mapping[str, Any]) -> dict[str, Any]:
    """The JSON-ready dict of a result (or of a dict already in that form): NaN and infinity become ``None``.

    Example:
        >>> to_jsonable({"standard": {"mean": float("nan"), "count": 0}, "seconds": float("inf"), "resolution": 32})
        {'standard': {'mean': None, 'count': 0}, 'seconds': None, 'resolution': 32}
    """
    return _finite(result.to_dict() if isinstance(result, EvaluationResult) else dict(result))


def write_json(result: EvaluationResult | Mapping[str, Any], path: str | Path) -> Path:
    """Write ``result`` as indented, strict JSON, atomically (NaN and infinity as ``null``); returns the path.

    Example:
        >>> import tempfile
        >>> folder = Path(tempfile.mkdtemp())
        >>> path = write_json({"standard": {"mean": float("nan"), "count": 0}}, folder / "results.json")
        >>> print(path.read_text(), end="")
        {
          "standard": {
            "mean": null,
            "count": 0
          }
        }
    """
    return write_text(json.dumps(to_jsonable(result), indent=2, allow_nan=False) + "\n", path)


def write_text(text: str, path: str | Path) -> Path:
    """Write a text file (e.g. a Markdown report) atomically."""
    atomic_write_text(path, text)
    return Path(path)


def comparison_table(results: Mapping[str, Mapping[str, float | None]], columns: Sequence[str] | None = None) -> str:
    """Table 1 of the paper: one row per model, one column per test (missing entries show ``-``).

    Args:
        results: ``{model: {column: value}}``, e.g. ``{"Cerberus": {"Human": 0.497, "Hard Human": 0.473}}``.
        columns: column order (default: first-seen order over the models).

    Example:
        >>> print(comparison_table({"Cerberus": {"Human": 0.497, "Hard Human": 0.473}, "NMR": {"Human": 0.41}}))
        | Model | Human | Hard Human |
        |:---|---:|---:|
        | Cerberus | 0.4970 | 0.4730 |
        | NMR | 0.4100 | - |
    """
    if columns is None:
        columns = list(dict.fromkeys(c for row in results.values() for c in row))
    return markdown_table(["Model", *columns], [[m, *(row.get(c) for c in columns)] for m, row in results.items()])


def images_scored(count: int, data: Mapping[str, Any] | None = None) -> str:
    """``"24 of 984 images"`` when ``data`` (``results.json``'s ``data``: the split's ``split_images``) says the
    split holds more than the ``count`` scored, else ``"984 images"``; with why fewer than the limit were scored when
    a limit of whole poses held fewer images (``selection`` ``"whole poses, spread evenly"``: 2 poses of 8 views
    within a limit of 20).

    Example:
        >>> images_scored(24, {"split_images": 984}), images_scored(984, {"split_images": 984}), images_scored(3)
        ('24 of 984 images', '984 images', '3 images')
        >>> images_scored(16, {"split_images": 984, "limit": 20, "selection": "whole poses, spread evenly"})
        '16 of 984 images (whole poses within a limit of 20)'
    """
    data = data or {}
    total, limit = data.get("split_images"), data.get("limit")
    said = f"{count} of {total} images" if total is not None and total > count else f"{count} images"
    if limit is not None and count < limit and data.get("selection") == "whole poses, spread evenly":
        said += f" (whole poses within a limit of {limit})"
    return said


def data_scored(r: Mapping[str, Any]) -> str:
    """Which data a ``results.json`` scored, as ``results.md``'s header says it after the image count: ``" of the
    test split of human/large, data_id 49bc547ce46b9202"`` (what its ``data`` and ``data_id`` record); ``""`` when
    neither is recorded (a bare result, or one from before they were).

    Example:
        >>> data_scored({"data_id": "49bc547ce46b9202", "data": {"dataset": "human", "preset": "large",
        ...                                                       "split": "test"}})
        ' of the test split of human/large, data_id 49bc547ce46b9202'
        >>> data_scored({"data": {"root": "data/animal_paper", "split": "test"}}), data_scored({})
        (' of the test split', '')
    """
    data, data_id = r.get("data") or {}, r.get("data_id")
    source = "/".join(str(data[k]) for k in ("dataset", "preset") if data.get(k) is not None)
    parts = [f" of the {data['split']} split" if data.get("split") is not None else "",
             f" of {source}" if source else "", f", data_id {data_id}" if data_id is not None else ""]
    return md_text("".join(parts))


def _duration(r: Mapping[str, Any]) -> str:
    """``"248 s"`` (the pass: ``seconds``), with the whole command's ``total_seconds`` when recorded."""
    seconds = f"{r.get('seconds') or 0:.0f} s"
    total = r.get("total_seconds")
    return seconds if total is None else f"{seconds} to score, {total:.0f} s with the figures and pictures"


def markdown_report(result: EvaluationResult | Mapping[str, Any], title: str = "Evaluation") -> str:
    """A readable summary: voxel IoU overall and per subject (standard and Hard Human), then each
    diagnostic's section in :data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS` order (those that ran
    and have one: part quality with each part's visibility, or part visibility alone; depth across
    views; body segments; allocation).

    Example: from a results.json dict with no diagnostic (each one skipped: ``null``):

        >>> std = {"mean": 0.5, "count": 2, "per_group": {"s1": 0.4, "s2": 0.6}, "clipped": 1, "failed": 0}
        >>> print(markdown_report({"protocol": "kato", "resolution": 32, "standard": std, "hard": None,
        ...                        "seconds": 12.3, "records": []}, title="Demo"))
        # Demo
        <BLANKLINE>
        Voxel IoU, protocol `kato` at 32^3, union of parts; 2 images (12 s).
        <BLANKLINE>
        ## Voxel IoU
        <BLANKLINE>
        | Subject | Standard | Hard Human |
        |:---|---:|---:|
        | all | 0.5000 | - |
        | s1 | 0.4000 | - |
        | s2 | 0.6000 | - |
        <BLANKLINE>
        - standard: 1 predictions clamped into the grid, 0 rejected by the metric (scored 0).
        <BLANKLINE>
    """
    r = to_jsonable(result)
    std, hard = r["standard"], r.get("hard")
    policy = open_ground_truths(r.get("gt_open_mesh"))
    out = [f"# {md_text(title)}", "",
           f"Voxel IoU, protocol `{r['protocol']}` at {r['resolution']}^3, union of parts{', ' if policy else ''}"
           f"{policy}; {images_scored(std['count'], r.get('data'))}{data_scored(r)} ({_duration(r)}).", ""]
    groups = sorted(set(std["per_group"]) | set((hard or {}).get("per_group", {})))
    rows = [["all", std["mean"], hard["mean"] if hard else None]]
    rows += [[g, std["per_group"].get(g), (hard or {}).get("per_group", {}).get(g)] for g in groups]
    out += ["## Voxel IoU", "", markdown_table(["Subject", "Standard", "Hard Human"], rows), ""]
    notes = []
    for name, s in (("standard", std), ("Hard Human", hard)):
        if s and (s.get("clipped") or s.get("failed")):
            notes.append(f"{name}: {s['clipped']} predictions clamped into the grid, {s['failed']} rejected "
                         "by the metric (scored 0).")
    if hard:
        notes.append("Hard Human shapes from images " + ", ".join(f"{md_text(s)}: #{i}" for s, i in r["canonical"].items())
                     + f"; {hard['count']} images scored.")
    out += [*(f"- {n}" for n in notes), ""] if notes else []
    for row in DIAGNOSTICS:
        if row.section is not None and r.get(row.key):
            out += row.section(r)
    return "\n".join(out)
