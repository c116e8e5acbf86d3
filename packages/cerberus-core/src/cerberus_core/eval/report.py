"""Evaluation results as JSON and Markdown.

JSON is strict (NaN and infinity are written as ``null``) and written atomically. Markdown reports
work from the JSON form (:meth:`EvaluationResult.to_dict`), so a report can be remade from a saved
``results.json``; :func:`comparison_table` builds the paper's Table 1 (models x test sets).
"""
from __future__ import annotations

import html
import json
import math
import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from cerberus_core.eval.allocation import allocation_line
from cerberus_core.eval.depth import depth_line
from cerberus_core.eval.runner import EvaluationResult
from cerberus_core.eval.segments import segments_line
from cerberus_core.eval.visibility import visibility_line
from cerberus_core.plumbing.atomic import atomic_write_text
from cerberus_core.plumbing.names import printable

_MD_SPECIAL = re.compile(r"([\\`|\[\]*])")


def md_text(text: object) -> str:
    """A name (subject, part, path) as Markdown text that shows it literally: control characters and
    undecodable bytes escaped (:func:`cerberus_core.plumbing.names.printable`), ``& < >`` as HTML character
    references (no raw HTML reaches a renderer), and ``\\ ` | [ ] *`` backslash-escaped (no code span,
    link, emphasis or broken table cell)."""
    return _MD_SPECIAL.sub(r"\\\1", html.escape(printable(text), quote=False))


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
    """The JSON-ready dict of a result (or of a dict already in that form)."""
    return _finite(result.to_dict() if isinstance(result, EvaluationResult) else dict(result))


def write_json(result: EvaluationResult | Mapping[str, Any], path: str | Path) -> Path:
    """Write ``result`` as indented, strict JSON, atomically."""
    return write_text(json.dumps(to_jsonable(result), indent=2, allow_nan=False) + "\n", path)


def write_text(text: str, path: str | Path) -> Path:
    """Write a text file (e.g. a Markdown report) atomically."""
    atomic_write_text(path, text)
    return Path(path)


def _fmt(v: Any, digits: int = 4) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return md_text(v)


def markdown_table(header: Sequence[str], rows: Sequence[Sequence[Any]], digits: int = 4) -> str:
    """A GitHub-flavoured Markdown table; floats get ``digits`` decimals, ``None``/NaN show as ``-``."""
    lines = ["| " + " | ".join(md_text(h) for h in header) + " |",
             "|" + "|".join(":---" if i == 0 else "---:" for i in range(len(header))) + "|"]
    lines += ["| " + " | ".join(_fmt(v, digits) for v in row) + " |" for row in rows]
    return "\n".join(lines)


def comparison_table(results: Mapping[str, Mapping[str, float | None]], columns: Sequence[str] | None = None) -> str:
    """Table 1 of the paper: one row per model, one column per test (missing entries show ``-``).

    Args:
        results: ``{model: {column: value}}``, e.g. ``{"Cerberus": {"Human": 0.497, "Hard Human": 0.473}}``.
        columns: column order (default: first-seen order over the models).
    """
    if columns is None:
        columns = list(dict.fromkeys(c for row in results.values() for c in row))
    return markdown_table(["Model", *columns], [[m, *(row.get(c) for c in columns)] for m, row in results.items()])


def markdown_report(result: EvaluationResult | Mapping[str, Any], title: str = "Evaluation") -> str:
    """A readable summary: voxel IoU overall and per subject (standard and Hard Human), then part
    quality (consistency per learned part, with its visibility in the input view, and segmentation
    IoU per ground-truth part, per side and with left and right merged); part visibility gets a table
    of its own when part quality was not run; then depth across views and body segments (recall,
    off-body voxels and input-view coverage per segment, the IoU lost when each learned part is deleted)."""
    r = to_jsonable(result)
    std, hard = r["standard"], r.get("hard")
    out = [f"# {md_text(title)}", "",
           f"Voxel IoU, protocol `{r['protocol']}` at {r['resolution']}^3, union of parts; "
           f"{std['count']} images ({r.get('seconds', 0):.0f} s).", ""]
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
    pq, vis = r.get("part_quality"), r.get("part_visibility")
    vis_header = ["Hidden in input view", "Silhouette share"] if vis else []

    def vis_cells(p: int) -> list[Any]:
        return [vis["hidden_fraction"][p], vis["mean_silhouette_share"][p]] if vis else []

    if pq and pq.get("part_labels") is False:  # data without part labels: say so, score nothing
        out += ["## Part quality", "", f"Not scored: {pq['note']}.", ""]
        pq = None
    if pq:
        out += ["## Part quality (ground-truth semantic parts, never seen in training)", "",
                f"Consistency (mean agreement) {_fmt(pq['consistency'])}, mean entropy "
                f"{_fmt(pq['mean_entropy_bits'], 3)} bits, mean segmentation IoU {_fmt(pq['mean_segmentation_iou'])} "
                f"over {pq['images']} images.", ""]
        out += [_visibility_sentence(vis), ""] if vis else []
        prow = [[p["part"], p["label"] or "(unused)", p.get("agreement"), p.get("entropy_bits"), p.get("purity"),
                 p["images"], *vis_cells(p["part"])] for p in pq["parts"]]
        out += [markdown_table(["Learned part", "Majority GT part", "Agreement", "Entropy (bits)", "Purity", "Images",
                                *vis_header], prow, 3), ""]
        out += [markdown_table(["GT part", "Segmentation IoU"], list(pq["segmentation_iou"].items()), 3), ""]
        merged = pq.get("sides_merged")
        if merged:
            out += _merged_sides(merged)
    elif vis:
        vrow = [[p, *vis_cells(p), px] for p, px in enumerate(vis["mean_visible_pixels"])]
        out += ["## Part visibility", "", _visibility_sentence(vis), "",
                markdown_table(["Learned part", *vis_header, "Visible pixels"], vrow, 3), ""]
    depth = r.get("depth")
    if depth:
        labels = {p["part"]: p["label"] for p in pq["parts"]} if pq else {}
        drow = [[p, labels.get(p) or "-", d] for p, d in enumerate(depth["translation_disagreement"])]
        out += ["## Depth across views", "", depth_line(depth)[0].upper() + depth_line(depth)[1:] + ".", "",
                markdown_table(["Learned part", "Majority GT part", "Translation disagreement"], drow, 3), ""]
    if r.get("segments"):
        out += _segments(r["segments"], pq)
    if r.get("allocation"):
        out += _allocation(r["allocation"], pq)
    return "\n".join(out)


def _merged_sides(merged: Mapping[str, Any]) -> list[str]:
    """The part-quality tables again, with left and right merged."""
    rows = [[p["part"], p["label"] or "(unused)", p.get("agreement"), p.get("entropy_bits"), p.get("purity")]
            for p in merged["parts"]]
    return ["### With left and right merged", "",
            "A grey, untextured body seen from the front or the back looks the same, so no image says which "
            "limb is the body's left: per-side agreement is capped near 0.5 by the data, not the model. "
            f"Merged: consistency {_fmt(merged['consistency'])}, mean entropy {_fmt(merged['mean_entropy_bits'], 3)} "
            f"bits, mean segmentation IoU {_fmt(merged['mean_segmentation_iou'])}.", "",
            markdown_table(["Learned part", "Majority GT part", "Agreement", "Entropy (bits)", "Purity"], rows, 3), "",
            markdown_table(["GT part", "Segmentation IoU"], list(merged["segmentation_iou"].items()), 3), ""]


def _segments(seg: Mapping[str, Any], pq: Mapping[str, Any] | None) -> list[str]:
    """The body-segment section: per segment, then per learned part."""
    out = ["## Body segments", "",
           f"Voxels as the standard IoU scores them, {seg['images']} images: precision {_fmt(seg['voxel_precision'])}, "
           f"recall {_fmt(seg['voxel_recall'])}. {segments_line(seg)[0].upper() + segments_line(seg)[1:]}.", ""]
    if seg["segment_labels"]:
        out += ["Each voxel belongs to the segment of the nearest ground-truth vertex. *Recall*: the share of the "
                "segment's voxels the prediction covers; *missed* and *off-body*: its share of the voxels only "
                "the ground truth has, and of those only the prediction has; *input view*: the share of its "
                "ground-truth vertices that project onto a pixel the predicted parts cover, beside the same for "
                "the ground truth's own render.", ""]
        cov = seg["input_view_coverage"]
        rows = [[k, seg["body_share"][k], seg["recall"][k], seg["missed_share"][k], seg["off_body_share"][k],
                 *([cov[k], seg["gt_render_coverage"][k]] if cov else [])] for k in seg["segments"]]
        out += [markdown_table(["GT segment", "Share of body", "Recall", "Share of missed", "Share of off-body",
                                *(["Input view: predicted", "Input view: ground truth"] if cov else [])], rows, 3), ""]
    labels = {p["part"]: p["label"] for p in pq["parts"]} if pq else {}
    rows = [[p, labels.get(p) or "-", loss, "spare" if p in seg["spare_parts"] else ""]
            for p, loss in enumerate(seg["deletion_loss"])]
    out += [f"IoU lost when a learned part is deleted (mean over images; spare: at most {seg['spare_threshold']:g}):",
            "", markdown_table(["Learned part", "Majority GT part", "IoU lost when deleted", "Spare"], rows, 4), ""]
    return out


def _allocation(alloc: Mapping[str, Any], pq: Mapping[str, Any] | None) -> list[str]:
    """The allocation section: per learned part, then per ground-truth segment."""
    line = allocation_line(alloc)
    labels = {p["part"]: p["label"] for p in pq["parts"]} if pq else {}
    prow = [[p, labels.get(p) or "-", spread, alloc["unique_coverage"][p]]
            for p, spread in enumerate(alloc["keypoint_spread"])]
    srow = [[k, alloc["segment_to_keypoint"][k], alloc["segment_spread"][k]] for k in alloc["segment_to_keypoint"]]
    return ["## Allocation", "",
            f"Where the parts go, in pixels of the input image, {alloc['images']} images. {line[0].upper() + line[1:]}. "
            "*Keypoint spread*: the standard deviation over images of (keypoint − the ground-truth silhouette's "
            "centroid), RMS of the two axes; *alone covers*: the mean share of the ground-truth foreground that "
            "only this part covers (each part rendered on its own); *to nearest keypoint*: the median distance "
            "from the segment's projected vertex centroid to the nearest keypoint; *segment spread*: the same "
            "spread as the keypoints' for the segment's centroid, for scale.", "",
            markdown_table(["Learned part", "Majority GT part", "Keypoint spread (px)", "Alone covers"], prow, 3), "",
            markdown_table(["GT segment", "To nearest keypoint (px)", "Segment spread (px)"], srow, 2), ""]


def _visibility_sentence(vis: Mapping[str, Any]) -> str:
    h, w = vis["image_size"]
    return (f"Part visibility in the input view ({h}x{w} renders of the reconstruction, {vis['images']} images): "
            f"{visibility_line(vis)}. *Hidden*: the fraction of images where no pixel shows the part (it gets no "
            "gradient from the paper's renderer there); *silhouette share*: its mean share of the rendered "
            "silhouette.")
