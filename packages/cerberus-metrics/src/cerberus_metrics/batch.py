"""Batch evaluation of many (prediction, ground truth) pairs on all cores.

Pairs come from a CSV or JSON file, or from two folders matched by file stem. Each
pair runs in a worker process; a failing pair (unreadable file, empty mesh, ...) is
recorded with its error and counted, never aborts the batch and is never dropped.

Pair file formats (relative paths are resolved against the pair file's folder):

* CSV with a header holding ``pred`` and ``gt`` columns, optional ``id``; a prediction
  made of parts lists its files separated by ``;``.
* JSON: a list (or ``{"pairs": [...]}``) of objects ``{"id"?, "pred": path | [paths], "gt": path}``.

Folders: every mesh file of ``gt_dir`` is a ground truth; its prediction is the file of
``pred_dir`` with the same stem, or a sub-folder of ``pred_dir`` with that name whose mesh
files are the parts. A ground truth without prediction, or a prediction without ground
truth, is a failed pair.

Prediction parts past the ``kato`` grid are clamped to it and counted (``outside="clamp"``), as
``cerberus eval`` scores. The summary gives each metric's mean over all pairs, a failed pair scored 0
as ``cerberus eval`` scores a rejected prediction (``mean_all_pairs``), beside the mean over the pairs
that succeeded (``mean_succeeded``): see :func:`summarize`.
"""

from __future__ import annotations

import csv
import io
import json
import math
import multiprocessing as mp
import os
import signal
import time
import warnings
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ._atomic import write_atomically
from .api import METRICS, evaluate_pair
from .cache import GridCache
from .io import MeshInputError, iter_mesh_files

__all__ = [
    "PairSpec",
    "check_output_path",
    "pairs_from_file",
    "pairs_from_folders",
    "run_batch",
    "summarize",
    "write_results",
]


@dataclass(frozen=True)
class PairSpec:
    """One pair to evaluate. pred: part file paths (one for a single mesh). error: set when the
    pair could not even be formed (e.g. missing prediction); it is then reported as failed."""

    id: str
    pred: tuple[str, ...]
    gt: str
    error: str | None = None


@dataclass
class BatchResult:
    """Per-pair rows (``id``, ``status``, metric values or ``error``, ``warnings``) and the summary."""

    rows: list[dict[str, Any]]
    summary: dict[str, Any] = field(default_factory=dict)


# --------------------------------------------------------------------------- pair sources


def _resolve(base: Path, p: str) -> str:
    """Absolute path of ``p`` (relative ones against ``base``), so no later change of the working
    directory can redirect it."""
    q = Path(p.strip())
    return os.path.abspath(q if q.is_absolute() else base / q)


def _read_text(path: Path, what: str) -> str:
    try:
        return path.read_text(encoding="utf-8-sig")
    except UnicodeDecodeError as exc:
        raise MeshInputError(f"{what} '{path}' is not UTF-8 text ({exc.reason} at byte {exc.start}); "
                             "pass a CSV or JSON text file") from None
    except OSError as exc:
        raise MeshInputError(f"cannot read {what} '{path}' ({exc.strerror}); check its permissions") from None


def pairs_from_file(path: str | os.PathLike) -> list[PairSpec]:
    """Read pairs from a ``.csv`` or ``.json`` file (see module docstring); all paths come back absolute."""
    path = Path(path)
    if not path.is_file():
        what = "is a directory" if path.is_dir() else "does not exist"
        raise MeshInputError(f"pairs file '{path}' {what}; pass a CSV or JSON file of pairs")
    base = path.parent.absolute()
    suffix = path.suffix.lower()
    if suffix not in (".csv", ".json"):
        raise MeshInputError(f"pairs file '{path}': unknown type '{path.suffix}'; use .csv or .json")
    text = _read_text(path, "pairs file")
    if suffix == ".json":
        try:
            data = json.loads(text)
        except RecursionError:  # json.loads fails three ways: bad syntax, a number too long to read, deep nesting
            raise MeshInputError(f"pairs file '{path}' is not valid JSON (nested too deeply); fix the file") from None
        except ValueError as exc:
            raise MeshInputError(f"pairs file '{path}' is not valid JSON ({exc}); fix the file") from None
        items = data.get("pairs") if isinstance(data, dict) else data
        if not isinstance(items, list):
            raise MeshInputError(f"pairs file '{path}': expected a list of {{'pred', 'gt'}} objects")
        rows = items
    else:
        try:
            reader = csv.DictReader(io.StringIO(text, newline=""))
            fields = [(f or "").strip().lower() for f in (reader.fieldnames or [])]
            missing = {"pred", "gt"} - set(fields)
            if missing:
                raise MeshInputError(
                    f"pairs file '{path}': missing column(s) {sorted(missing)} (found {fields or 'no header'}); "
                    "the first line must be a header naming the columns pred,gt (and optionally id)"
                )
            reader.fieldnames = fields
            rows = [dict(r, pred=(r["pred"] or "").split(";")) for r in reader]
        except csv.Error as exc:
            raise MeshInputError(f"pairs file '{path}' is not a valid CSV file ({exc}); fix the file") from None
    out = []
    for i, r in enumerate(rows):
        if not isinstance(r, dict) or "pred" not in r or "gt" not in r:
            raise MeshInputError(f"pairs file '{path}': entry {i} lacks 'pred' or 'gt': {r!r}")
        preds = r["pred"] if isinstance(r["pred"], list) else [r["pred"]]
        if any("\0" in str(p) for p in (*preds, r["gt"])):  # no file system takes it: os calls raise ValueError
            raise MeshInputError(f"pairs file '{path}': entry {i} names a path holding a NUL byte; fix the file")
        preds = [_resolve(base, str(p)) for p in preds if p is not None and str(p).strip()]
        gt = "" if r["gt"] is None else str(r["gt"]).strip()
        pair_id = str(r.get("id") or Path(gt).stem or i)
        error = None if preds and gt else f"entry {i} of '{path}' has an empty {'pred' if not preds else 'gt'} field"
        out.append(PairSpec(pair_id, tuple(preds), _resolve(base, gt) if gt else "", error))
    return out


def pairs_from_folders(pred_dir: str | os.PathLike, gt_dir: str | os.PathLike) -> list[PairSpec]:
    """Match ground-truth files to predictions by stem (see module docstring)."""
    pred_dir, gt_dir = Path(os.path.abspath(pred_dir)), Path(os.path.abspath(gt_dir))
    for d, what in ((pred_dir, "prediction"), (gt_dir, "ground-truth")):
        if not d.is_dir():
            raise MeshInputError(f"{what} folder '{d}' does not exist or is not a folder")
    gts = {p.stem: p for p in iter_mesh_files(gt_dir)}
    preds: dict[str, tuple[str, ...]] = {p.stem: (str(p),) for p in iter_mesh_files(pred_dir)}
    sources: dict[str, list[str]] = {}  # every file or part folder that claims a stem: more than one is ambiguous
    for p in iter_mesh_files(pred_dir):
        sources.setdefault(p.stem, []).append(f"'{p.name}'")
    for p in iter_mesh_files(gt_dir):
        sources.setdefault(f"gt:{p.stem}", []).append(f"'{p.name}'")
    for sub in sorted(q for q in pred_dir.iterdir() if q.is_dir()):
        preds.setdefault(sub.name, tuple(str(p) for p in iter_mesh_files(sub)))
        sources.setdefault(sub.name, []).append(f"the part folder '{sub.name}/'")
    out = []
    for stem in sorted(set(gts) | set(preds)):
        for key, where in ((stem, pred_dir), (f"gt:{stem}", gt_dir)):
            if len(sources.get(key, [])) > 1:
                out.append(PairSpec(stem, (), str(gts.get(stem, "")), f"both {' and '.join(sources[key])} in '{where}' "
                                    f"are named '{stem}': keep one, so that the score says which was scored"))
                break
        else:
            out.append(_pair(stem, preds, gts, pred_dir, gt_dir))
    return out


def _pair(stem: str, preds: dict[str, tuple[str, ...]], gts: dict[str, Path], pred_dir: Path, gt_dir: Path) -> PairSpec:
    """The pair of one stem, or why it cannot be formed."""
    if stem not in preds or not preds[stem]:
        return PairSpec(stem, (), str(gts[stem]), f"no prediction named '{stem}' in '{pred_dir}'")
    if stem not in gts:
        return PairSpec(stem, preds[stem], "", f"no ground truth named '{stem}' in '{gt_dir}'")
    return PairSpec(stem, preds[stem], str(gts[stem]))


# --------------------------------------------------------------------------- workers

_CACHE: GridCache | None = None
_OPTIONS: dict[str, Any] = {}
_CWD: str = ""


def _init_worker(options: dict[str, Any], cache_dir: str | None, use_cache: bool = True) -> None:
    global _CACHE, _OPTIONS, _CWD
    _CACHE = GridCache(cache_dir) if use_cache else None
    _OPTIONS = options
    _CWD = os.getcwd()


def _init_pool_worker(options: dict[str, Any], cache_dir: str | None, use_cache: bool = True) -> None:
    """:func:`_init_worker` in a pool's process, which leaves Ctrl-C to the parent: it stops the pool and says so
    in one line (each worker would print a KeyboardInterrupt traceback)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _init_worker(options, cache_dir, use_cache)


def _evaluate(spec: PairSpec) -> dict[str, Any]:
    row: dict[str, Any] = {"id": spec.id, "pred": ";".join(spec.pred), "gt": spec.gt}
    if spec.error or not spec.pred or not spec.gt:
        error = spec.error or f"pair '{spec.id}' lists no {'prediction' if not spec.pred else 'ground truth'} file"
        return dict(row, status="error", error=error, warnings=[])
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            pred = list(spec.pred) if len(spec.pred) > 1 else spec.pred[0]
            row.update(evaluate_pair(pred, spec.gt, cache=_CACHE, **_OPTIONS))
            row["status"] = "ok"
        except Exception as exc:  # noqa: BLE001 - a failing pair is recorded, never fatal
            row.update(status="error", error=f"{type(exc).__name__}: {exc}")
        finally:
            if _CWD and os.getcwd() != _CWD:  # no pair may change where the next one looks for files
                os.chdir(_CWD)
    row["warnings"] = sorted({str(w.message) for w in caught})
    row["seconds"] = round(time.perf_counter() - t0, 4)
    return row


def run_batch(
    pairs: Sequence[PairSpec],
    metrics: Iterable[str] = ("voxel_iou",),
    *,
    jobs: int | None = None,
    cache_dir: str | os.PathLike | None = None,
    use_cache: bool = True,
    progress: bool = True,
    **options: Any,
) -> BatchResult:
    """Evaluate all pairs with ``jobs`` worker processes (default: all cores).

    metrics: names from :data:`cerberus_metrics.api.METRICS`. options: keyword options of
    :func:`cerberus_metrics.api.evaluate_pair` (protocol, resolution, outside, n_samples, seed,
    threshold, normalize, open_mesh, check_self_intersections); ``outside`` defaults to ``"clamp"``
    here, as ``cerberus eval`` scores: a prediction part past the ``kato`` grid is clamped to it and
    counted, not a failed pair. Ground-truth grids are cached
    per worker in memory (``use_cache``) and, with ``cache_dir``, in a folder shared by the
    workers and by later runs. Returns rows in input order and the summary (:func:`summarize`).
    """
    metrics = list(metrics)
    unknown = sorted(set(metrics) - set(METRICS))
    if unknown:
        raise MeshInputError(f"unknown metric(s) {unknown}; choose from {list(METRICS)}")
    if jobs is not None and (isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1):
        raise MeshInputError(f"jobs must be a positive number of processes, got {jobs!r}; omit it for all cores")
    options = {"outside": "clamp", **options, "metrics": metrics}
    jobs = max(1, min(int(jobs or os.cpu_count() or 1), max(1, len(pairs))))
    cache = None if cache_dir is None else os.path.abspath(cache_dir)
    # Same-GT pairs next to each other so a worker's in-memory cache serves them.
    order = sorted(range(len(pairs)), key=lambda i: pairs[i].gt)
    ordered = [pairs[i] for i in order]
    bar = _progress(len(pairs), progress)
    rows: list[dict[str, Any]] = []
    if jobs == 1:
        _init_worker(options, cache, use_cache)
        for r in map(_evaluate, ordered):
            rows.append(r)
            bar.update(1)
    else:
        chunk = max(1, min(16, len(pairs) // (jobs * 4)))
        with mp.get_context().Pool(jobs, initializer=_init_pool_worker, initargs=(options, cache, use_cache)) as pool:
            for r in pool.imap(_evaluate, ordered, chunksize=chunk):
                rows.append(r)
                bar.update(1)
            pool.close()
            pool.join()
    bar.close()
    by_id = dict(zip(order, rows, strict=True))
    rows = [by_id[i] for i in range(len(pairs))]
    return BatchResult(rows, summarize(rows, metrics))


def _progress(total: int, enabled: bool):
    try:
        from tqdm import tqdm
    except ImportError:  # tqdm is a declared dependency, but keep the batch usable without it
        enabled = False
    if not enabled:

        class _Null:
            def update(self, n: int) -> None: ...

            def close(self) -> None: ...

        return _Null()
    return tqdm(total=total, unit="pair", desc="cerberus-metrics", dynamic_ncols=True)


#: The metrics whose worst value a failed pair can stand for: 0 (an IoU, an F-score and its precision and
#: recall are in [0, 1], higher is better). Chamfer-L2 has no worst value, so a failed pair gets none.
FAILED_SCORES = {"voxel_iou": 0.0, "fscore": 0.0, "precision": 0.0, "recall": 0.0}


def summarize(rows: Sequence[dict[str, Any]], metrics: Iterable[str]) -> dict[str, Any]:
    """Summary: pair counts, failures (id and error), clamped predictions (``pairs_clamped``: pairs
    with a prediction part clamped into the ``kato`` grid, ``parts_clamped``: such parts in all)
    and per metric two means, named apart:

    * ``mean_all_pairs``: over all pairs, a failed pair (or one without a finite value) scored as
      :data:`FAILED_SCORES` says (0), as ``cerberus eval`` scores a rejected prediction; ``None`` for a
      metric with no such score (``chamfer_l2``) when a pair failed;
    * ``mean_succeeded``: over the pairs that succeeded only, with their ``median``, ``min``, ``max`` and
      ``count``.

    Example: a pair scored 1.0 and a pair that failed:

    >>> s = summarize([{"id": "a", "status": "ok", "voxel_iou": 1.0},
    ...                {"id": "b", "status": "error", "error": "MeshInputError: ..."}], ["voxel_iou"])
    >>> s["succeeded"], s["failed"], s["metrics"]["voxel_iou"]
    (1, 1, {'mean_all_pairs': 0.5, 'mean_succeeded': 1.0, 'median': 1.0, 'min': 1.0, 'max': 1.0, 'count': 1})
    """
    ok = [r for r in rows if r.get("status") == "ok"]
    failed = [r for r in rows if r.get("status") != "ok"]
    out: dict[str, Any] = {
        "pairs": len(rows),
        "succeeded": len(ok),
        "failed": len(failed),
        "failures": [{"id": r["id"], "error": r.get("error", "")} for r in failed],
        "pairs_with_warnings": sum(1 for r in rows if r.get("warnings")),
        "pairs_clamped": sum(1 for r in ok if r.get("clamped_parts")),
        "parts_clamped": int(sum(r.get("clamped_parts") or 0 for r in ok)),
        "metrics": {},
    }
    names = list(metrics)
    if "fscore" in names:
        names += ["precision", "recall"]
    for m in names:
        vals = np.array([r[m] for r in ok if m in r and r[m] is not None and math.isfinite(r[m])], float)
        missing = len(rows) - vals.size
        if not rows or (missing and m not in FAILED_SCORES):
            mean_all = None
        else:
            mean_all = float((vals.sum() + missing * FAILED_SCORES.get(m, 0.0)) / len(rows))
        out["metrics"][m] = {
            "mean_all_pairs": mean_all,
            "mean_succeeded": float(vals.mean()) if vals.size else None,
            "median": float(np.median(vals)) if vals.size else None,
            "min": float(vals.min()) if vals.size else None,
            "max": float(vals.max()) if vals.size else None,
            "count": int(vals.size),
        }
    return out


#: The first key of every JSON results file ``batch`` writes: what marks a file it may replace.
WRITTEN_BY = "cerberus-metrics batch"
#: How a results file of this package begins: the marked form, and the form before the marker (issue 39).
_JSON_STARTS = ('{\n  "written_by": "' + WRITTEN_BY + '"', '{\n  "summary": {\n    "pairs": ')
#: Columns only a results CSV of ``batch`` has together (a pairs file has ``id``, ``pred``, ``gt`` alone).
_CSV_COLUMNS = {"id", "pred", "gt", "status", "warnings"}


def written_here(path: Path) -> bool:
    """Whether the existing file ``path`` is empty or results that ``batch`` wrote (a JSON file beginning with
    its marker, or a CSV whose header has its columns): the only files an output may replace. This package's
    copy of the toolkit's one output rule (docs/outputs.md): it stands alone, and writes files, never folders."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(4096)
    except OSError:
        return False
    if not head:
        return True
    text = head.decode("utf-8", "replace")
    if text.startswith(_JSON_STARTS):
        return True
    header = next(csv.reader([text.splitlines()[0]]), []) if text.splitlines() else []
    return _CSV_COLUMNS <= set(header)


def check_output_path(path: str | os.PathLike, flag: str) -> str:
    """Absolute form of an output path, after checking it can be written (before any work is done).

    Raises :class:`MeshInputError` naming ``flag`` when the path is a folder, its folder does not exist or
    is not writable (what it may replace: :func:`check_replaceable`, after :func:`check_not_input`).
    """
    p = Path(os.path.abspath(path))
    if p.is_dir():
        raise MeshInputError(f"{flag} '{path}' is a folder; pass a file name, e.g. {flag} {Path(path) / 'results'}")
    if not p.parent.is_dir():
        raise MeshInputError(f"{flag} '{path}': folder '{p.parent}' does not exist; create it first")
    if not os.access(p.parent, os.W_OK):
        raise MeshInputError(f"{flag} '{path}': folder '{p.parent}' is not writable; choose another place")
    return str(p)


def check_replaceable(outputs: dict[str, str | None]) -> None:
    """Refuse (:class:`MeshInputError` naming the flag) an output file (``{flag: path or None}``) that exists and
    is not one ``batch`` wrote (:func:`written_here`): such a file is never replaced."""
    for flag, out in outputs.items():
        if out and os.path.lexists(out) and (not os.path.isfile(out) or not written_here(Path(out))):
            raise MeshInputError(f"{flag} '{out}' exists and is not results that cerberus-metrics batch wrote; it "
                                 "is never replaced: move it away or choose another name (docs/outputs.md)")


def check_not_input(outputs: dict[str, str | None], pairs: Sequence[PairSpec], extra: Sequence[str] = (),
                    folders: dict[str, str | None] | None = None) -> None:
    """Refuse (:class:`MeshInputError` naming the flag) an output file (``{flag: path or None}``) that is one
    of the inputs (a mesh of ``pairs`` or a file of ``extra``, e.g. the pairs file), or an output folder
    (``folders``, e.g. the cache's) that holds one, compared by real path: writing would replace or mix with
    the inputs."""
    inputs = {os.path.realpath(m): m for m in [*extra, *(m for pair in pairs for m in (*pair.pred, pair.gt) if m)]}
    for flag, out in outputs.items():
        if out and os.path.realpath(out) in inputs:
            raise MeshInputError(f"{flag} '{out}' is one of the inputs ({inputs[os.path.realpath(out)]}); writing it "
                                 "would replace that file: choose another name")
    for flag, folder in (folders or {}).items():
        real = os.path.realpath(folder) if folder else None
        held = next((m for r, m in inputs.items() if real and r.startswith(real.rstrip(os.sep) + os.sep)), None)
        if held:
            raise MeshInputError(f"{flag} '{folder}' holds the input {held}; files written there would mix with "
                                 "the inputs: choose a folder of its own")


def _csv_text(rows: Sequence[dict[str, Any]]) -> str:
    keys: list[str] = []
    for r in rows:
        keys += [k for k in r if k not in keys]
    buf = io.StringIO(newline="")
    w = csv.DictWriter(buf, fieldnames=keys)
    w.writeheader()
    for r in rows:
        w.writerow({k: " | ".join(v) if isinstance(v, list) else v for k, v in r.items()})
    return buf.getvalue()


def write_results(result: BatchResult, json_path: str | os.PathLike | None, csv_path: str | os.PathLike | None) -> None:
    """Write ``{"written_by", "summary", "pairs"}`` as JSON and/or the per-pair rows as CSV (warnings joined by ' | ').

    UTF-8, and atomic (:func:`~cerberus_metrics._atomic.write_atomically`): each file is written to a temporary
    file in its folder, synced, and moved into place only when all requested files are complete, so a failure
    leaves no partial output. Permissions are those of a plain ``open(path, "w")``: a new file gets ``0o666``
    less the umask, a replaced file keeps its mode.
    """
    todo: list[tuple[Path, bytes]] = []
    if json_path:
        record = {"written_by": WRITTEN_BY, "summary": result.summary, "pairs": result.rows}
        todo.append((Path(json_path), json.dumps(record, indent=2).encode("utf-8")))
    if csv_path:
        todo.append((Path(csv_path), _csv_text(result.rows).encode("utf-8")))
    write_atomically([(target, lambda fh, data=data: fh.write(data)) for target, data in todo])
