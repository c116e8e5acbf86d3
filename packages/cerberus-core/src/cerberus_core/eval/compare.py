"""Two evaluations compared image by image: is one model better than another on the same test images?

Two ``cerberus eval`` results of the same test set (``results.json``, or
:attr:`~cerberus_core.eval.runner.EvaluationResult.records`) score the same images, so their difference is
best read per image: the images are matched by their record's ``index`` (and must agree on ``subject``, ``pose``
and ``view`` where both records have them: :func:`image_pairs`), and :func:`paired_difference`
gives the mean of ``a - b`` over the images both scored, its standard error and how many images favour
``a`` (:class:`PairedDifference`). Pairing removes what the images share (a hard pose is hard for both
models), so its standard error is usually much smaller than either mean's own. Any per-image value of the
records compares: ``iou``, ``hard_iou``, or one value against another of the same evaluation (Human
against Hard Human).

:func:`load_evaluation` reads an evaluation from wherever ``cerberus eval`` left it (the file, its folder, or the
run folder whose ``eval/`` it is); :func:`comparison_rows` puts several side by side, each paired with the first
(``cerberus compare``; :func:`cerberus_core.eval.figures.paired_plot` draws the per-image pairs).

Nothing here needs torch: the experiments' tables import it to read ``results.json`` files.
"""
from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cerberus_core.errors import DatasetError, NoEvaluationError
from cerberus_core.plumbing import jsontext
from cerberus_core.plumbing.names import printable

#: The file ``cerberus eval`` writes its scores and per-image records to.
RESULTS = "results.json"

#: A ``results.json`` dict (its ``records``) or the records themselves: one dict per image, with its ``index``.
Evaluation = Mapping[str, Any] | Sequence[Mapping[str, Any]]


@dataclass(frozen=True)
class PairedDifference:
    """The per-image difference ``a - b`` of two evaluations, over the ``n`` images both scored.

    ``str()`` gives the form the tables print, ``mean ± sem (better / n)``, three decimals.

    Attributes:
        mean: the mean over the images of ``a - b``, in the value's units (voxel IoU, 0 to 1).
        sem: its standard error: the sample standard deviation of the differences over ``sqrt(n)``.
        better: how many images have ``a - b > 0``.
        n: how many images both scored (``>= 2``).
    """

    mean: float
    sem: float
    better: int
    n: int

    def __str__(self) -> str:
        return f"{self.mean:+.3f} ± {self.sem:.3f} ({self.better} / {self.n})"


IDENTITY = ("subject", "pose", "view")
"""The fields of a record that name its image besides ``index``: two records paired by ``index`` must agree on
those both have."""


def _same_image(ra: Mapping[str, Any], rb: Mapping[str, Any]) -> None:
    """Two records paired by ``index`` are of one image: a :class:`DatasetError` where they differ in a field of
    :data:`IDENTITY` both have (two evaluations of different test sets or splits)."""
    for name in IDENTITY:
        if name in ra and name in rb and ra[name] != rb[name]:
            raise DatasetError(f"image {ra['index']} is {name} {ra[name]!r} in one evaluation and {rb[name]!r} in the "
                               "other: they scored different test sets; compare two evaluations of the same dataset "
                               "and split")


def _records(evaluation: Evaluation) -> Sequence[Mapping[str, Any]]:
    return evaluation.get("records", []) if isinstance(evaluation, Mapping) else evaluation


def image_pairs(a: Evaluation, b: Evaluation, key_a: str = "iou",
                key_b: str | None = None) -> list[tuple[float, float]]:
    """The images two evaluations both scored, as ``(a[key_a], b[key_b])`` per image: the one pairing of this
    module (:func:`paired_difference`, :func:`comparison_rows`,
    :func:`cerberus_core.eval.figures.paired_plot`).

    Args:
        a, b: two evaluations of the same test set: a ``results.json`` dict (its ``records``) or the records,
            one dict per image with its ``index``; in any order, and either may lack images.
        key_a: the per-image value of ``a`` (``"iou"``, ``"hard_iou"``...).
        key_b: that of ``b``; ``key_a`` if None.
    Returns:
        One ``(value in a, value in b)`` per image of ``a`` whose ``key_a`` is set and whose ``index`` has a
        record in ``b`` with ``key_b`` set, in ``a``'s order (empty where none is shared).

    Raises:
        DatasetError: two records paired by ``index`` name different images (they differ in a field of
            :data:`IDENTITY` both have): the evaluations scored different test sets.

    Example:
        >>> a = [{"index": 0, "iou": 0.5, "subject": "s1"}, {"index": 1, "iou": 0.6}, {"index": 2, "iou": None}]
        >>> image_pairs(a, [{"index": 2, "iou": 0.4}, {"index": 0, "iou": 0.45, "subject": "s1"}])
        [(0.5, 0.45)]
        >>> image_pairs(a, [{"index": 0, "iou": 0.45, "subject": "s2"}])
        Traceback (most recent call last):
        ...
        cerberus_core.errors.DatasetError: image 0 is subject 's1' in one evaluation and 's2' in the other: ...
    """
    key_b = key_a if key_b is None else key_b
    rb = {r["index"]: r for r in _records(b)}
    pairs = []
    for r in _records(a):
        other = rb.get(r["index"], {})
        if r.get(key_a) is None or other.get(key_b) is None:
            continue
        _same_image(r, other)
        pairs.append((r[key_a], other[key_b]))
    return pairs


def paired_difference(a: Evaluation | None, b: Evaluation | None, key_a: str = "iou",
                      key_b: str | None = None) -> PairedDifference | None:
    """The paired difference ``a[key_a] - b[key_b]`` per image, over the images both scored (:func:`image_pairs`).

    Args:
        a, b: two evaluations of the same test set: a ``results.json`` dict (its ``records``) or the records,
            one dict per image with its ``index``; in any order, and either may lack images. Records paired by
            ``index`` that both name their image (``subject``, ``pose``, ``view``) must name the same one, else a
            :class:`~cerberus_core.errors.DatasetError` (evaluations of different test sets).
        key_a: the per-image value of ``a`` (``"iou"``, ``"hard_iou"``...).
        key_b: that of ``b``; ``key_a`` if None.
    Returns:
        The :class:`PairedDifference` over the images of ``a`` whose ``key_a`` is set and whose ``index`` has a
        record in ``b`` with ``key_b`` set (in ``a``'s order), or None if either evaluation is None or fewer
        than 2 images are shared.

    Example:
        >>> a = {"records": [{"index": 0, "iou": 0.50}, {"index": 1, "iou": 0.60}, {"index": 2, "iou": 0.70}]}
        >>> b = [{"index": 2, "iou": 0.60}, {"index": 0, "iou": 0.45}, {"index": 1, "iou": 0.62}]
        >>> d = paired_difference(a, b)
        >>> round(d.mean, 4), round(d.sem, 4), d.better, d.n
        (0.0433, 0.0348, 2, 3)
        >>> print(d)
        +0.043 ± 0.035 (2 / 3)
        >>> print(paired_difference(a, b[:1]))
        None
    """
    if a is None or b is None:
        return None
    d = [x - y for x, y in image_pairs(a, b, key_a, key_b)]
    if len(d) < 2:
        return None
    return PairedDifference(statistics.mean(d), statistics.stdev(d) / len(d) ** 0.5, sum(x > 0 for x in d), len(d))


def evaluation_file(path: str | Path) -> Path:
    """The ``results.json`` an evaluation path means: the file itself, ``PATH/results.json`` (a ``cerberus eval``
    output folder) or ``PATH/eval/results.json`` (a run folder evaluated into its default place).

    Raises:
        NoEvaluationError: none of the three is a file; the message names the places looked at.
    """
    p = Path(path)
    for candidate in (p, p / RESULTS, p / "eval" / RESULTS):
        if candidate.is_file():
            return candidate
    where = f"{printable(p)} does not exist" if not p.exists() else (
        f"neither {printable(p / RESULTS)} nor {printable(p / 'eval' / RESULTS)} is a file")
    raise NoEvaluationError(f"no evaluation at {printable(p)}: {where}; pass a results.json, the folder an evaluation "
                            "was written to, or a run folder evaluated into its eval/ (`cerberus eval RUN`, or "
                            "`Run.evaluate` in Python)")


def load_evaluation(path: str | Path, *, missing_ok: bool = False) -> dict[str, Any] | None:
    """An evaluation's ``results.json`` as a dict (``standard``, the diagnostics, ``records``...), found by
    :func:`evaluation_file`; ``None`` where there is none and ``missing_ok`` (a run not evaluated yet).

    Raises:
        NoEvaluationError: no ``results.json`` there (without ``missing_ok``).
        DatasetError: the file cannot be read, is not JSON (malformed, not UTF-8, a number too long or nesting too
            deep to read: :func:`cerberus_core.plumbing.jsontext.loads`), or is not an evaluation (no ``records``
            list).

    Example:
        >>> import json, tempfile
        >>> run = Path(tempfile.mkdtemp())
        >>> (run / "eval").mkdir()
        >>> _ = (run / "eval" / RESULTS).write_text(json.dumps({"standard": {"mean": 0.5}, "records": []}))
        >>> load_evaluation(run)["standard"], load_evaluation(run / "other", missing_ok=True)
        ({'mean': 0.5}, None)
    """
    try:
        file = evaluation_file(path)
    except NoEvaluationError:
        if missing_ok:
            return None
        raise
    try:
        data = jsontext.loads(file.read_text(encoding="utf-8"))
    except OSError as exc:
        raise DatasetError(f"{printable(file)} cannot be read ({exc}); make it readable, or pass another "
                           "evaluation's results.json") from exc
    except ValueError as exc:  # malformed or not UTF-8 (its decode error), too long a number or too deep a nesting
        raise DatasetError(f"{printable(file)} cannot be read as JSON ({exc}); pass the results.json an evaluation "
                           "wrote, or evaluate again to rewrite it") from exc
    if not isinstance(data, dict) or not isinstance(data.get("records"), list):
        raise DatasetError(f"{printable(file)} is not an evaluation's results.json (it has no list of per-image "
                           "'records'); pass the results.json an evaluation wrote")
    return data


def evaluation_name(path: str | Path) -> str:
    """A short name for the evaluation at ``path``: the run's folder for ``RUN``, ``RUN/eval`` and
    ``RUN/eval/results.json``, else the folder the results are in.

    >>> evaluation_name("runs/cpu"), evaluation_name("runs/cpu/eval/results.json"), evaluation_name("out/heldout")
    ('cpu', 'cpu', 'heldout')
    """
    p = Path(path)
    if p.name == RESULTS:
        p = p.parent
    return p.parent.name if p.name == "eval" and p.parent.name else p.name


#: The per-image values :func:`comparison_rows` shows: ``(column, record key)``. Each column is the mean over the
#: evaluation's images of the record's value, the statistic its ``Δ`` column pairs: voxel IoU and Hard Human are
#: then the ``standard`` and ``hard`` means of ``results.json``, but precision and recall are not its
#: ``segments`` figures, which pool the voxels of every image before dividing.
PAIRED_VALUES = (("voxel IoU", "iou"), ("Hard Human", "hard_iou"), ("precision", "voxel_precision"),
                 ("recall", "voxel_recall"))


def image_mean(evaluation: Evaluation, key: str) -> float | None:
    """The mean over an evaluation's images of the per-image value ``key`` (voxel IoU, 0 to 1, for ``"iou"``), over
    the records where it is set; ``None`` where none is. Where two evaluations scored the same images, their
    :func:`paired_difference` has this mean's difference as its mean.

    >>> image_mean([{"index": 0, "iou": 0.5}, {"index": 1, "iou": 0.7}, {"index": 2, "iou": None}], "iou")
    0.6
    >>> print(image_mean({"records": [{"index": 0, "iou": 0.5}]}, "hard_iou"))
    None
    """
    values = [r[key] for r in _records(evaluation) if r.get(key) is not None]
    return statistics.fmean(values) if values else None


def comparison_rows(evaluations: Mapping[str, Mapping[str, Any]]) -> tuple[list[str], list[list[Any]]]:
    """Several evaluations of one test set side by side, each paired image by image with the first.

    Args:
        evaluations: ``{name: results.json dict}`` (:func:`load_evaluation`), the baseline first.
    Returns:
        ``(header, rows)`` for :func:`~cerberus_core.eval.markdown.markdown_table`: per evaluation its name, the
        images it scored and, for each of :data:`PAIRED_VALUES` that some evaluation's records have, the mean over
        its images of the per-image value (:func:`image_mean`; precision and recall too, not the pooled figures of
        its ``segments`` summary) and (column ``Δ ...``) its :func:`paired_difference` to the first (``None`` for
        the first itself, or where either lacks it): of two evaluations of the same images, the difference of
        their means.

    Raises:
        DatasetError: two evaluations scored different images under one index (different test sets).

    Example:
        >>> a = {"records": [{"index": i, "iou": 0.5 + 0.05 * i} for i in range(3)]}
        >>> b = {"records": [{"index": i, "iou": 0.52 + 0.06 * i} for i in range(3)]}
        >>> header, rows = comparison_rows({"base": a, "new": b})
        >>> header
        ['model', 'images', 'voxel IoU', 'Δ voxel IoU']
        >>> rows[1][:2], round(rows[1][2], 4), str(rows[1][3])
        (['new', 3], 0.58, '+0.030 ± 0.006 (3 / 3)')
    """
    names = list(evaluations)
    first = evaluations[names[0]] if names else None
    means = {name: {key: image_mean(e, key) for _, key in PAIRED_VALUES} for name, e in evaluations.items()}
    shown = [(column, key) for column, key in PAIRED_VALUES if any(m[key] is not None for m in means.values())]
    header = ["model", "images"]
    for column, _ in shown:
        header += [column, f"Δ {column}"]
    rows = []
    for name, evaluation in evaluations.items():
        row: list[Any] = [name, len(evaluation.get("records", []))]
        for _, key in shown:
            row += [means[name][key], None if evaluation is first else paired_difference(evaluation, first, key)]
        rows.append(row)
    return header, rows
