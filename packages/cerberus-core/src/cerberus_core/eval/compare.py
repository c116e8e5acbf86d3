"""Two evaluations compared image by image: is one model better than another on the same test images?

Two ``cerberus eval`` results of the same test set (``results.json``, or
:attr:`~cerberus_core.eval.runner.EvaluationResult.records`) score the same images, so their difference is
best read per image: the images are matched by their record's ``index`` (and must agree on ``subject``, ``pose``
and ``view`` where both records have them: :func:`image_pairs`), the evaluations must have measured alike, the
same data included (the settings of :data:`MEASUREMENT`: :func:`check_comparable`), and :func:`paired_difference`
gives the mean of ``a - b`` over the images both scored, its standard error and how many images favour
``a`` (:class:`PairedDifference`). Pairing removes what the images share (a hard pose is hard for both
models), so its standard error is usually much smaller than either mean's own. Any per-image value of the
records compares: ``iou``, ``hard_iou``, or one value against another of the same evaluation (Human
against Hard Human).

:func:`load_evaluation` reads an evaluation from wherever ``cerberus eval`` left it (the file, its folder, or the
run folder whose ``eval/`` it is); :func:`comparison_rows` puts several side by side, each paired with the first
(``cerberus compare``; :func:`cerberus_core.eval.figures.paired_plot` draws the per-image pairs), and adds the
optional column groups a comparison of runs asks for, by name: :data:`COLUMN_GROUPS`, one :class:`ColumnGroup` of
:class:`Column` s each (a header and a function of the evaluation, and of its run folder, :func:`run_folder`, for
the training log and the evaluation on the run's own training images): ``parts`` (where the parts go and what they
are), ``depth`` (depth across views), ``training`` (steps, minutes, steps/s), ``own-images`` (the IoU on the run's
own training images and the gap) and ``heldout`` (per held-out pose family: :func:`group_means` by
:func:`pose_family`). :func:`cerberus_core.eval.figures.trade_plot` draws each evaluation's voxel IoU against its
Hard Human IoU.

Nothing here needs torch: ``cerberus compare`` and the experiments read ``results.json`` files with it.
"""
from __future__ import annotations

import math
import statistics
from collections.abc import Callable, Hashable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from cerberus_core.bodies.human_heldout import FAMILIES, family_of, is_heldout_id
from cerberus_core.errors import ConfigError, DatasetError, IncomparableEvaluationsError, NoEvaluationError, shown
from cerberus_core.plumbing import jsontext
from cerberus_core.plumbing.metrics_csv import METRICS_CSV, TrainingTime, training_time
from cerberus_core.plumbing.names import did_you_mean, printable

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


@dataclass(frozen=True)
class Setting:
    """One setting of :data:`MEASUREMENT`.

    Attributes:
        key: its key in ``results.json``.
        default: the value an evaluation that does not record it was made under; ``None``: not known, then not
            compared.
        name: how a message says it (``key`` when empty).
        chosen_by: the settings of an evaluation that choose it, which a message asks to make the same
            (:meth:`cerberus_core.run.Run.evaluate`'s ``data``, :class:`~cerberus_core.run.EvalSettings` fields;
            ``(key,)`` when empty).
    """

    key: str
    default: Any = None
    name: str = ""
    chosen_by: tuple[str, ...] = ()

    @property
    def said(self) -> str:
        return self.name or self.key

    @property
    def choices(self) -> tuple[str, ...]:
        return self.chosen_by or (self.key,)


#: What an evaluation measured, under which its per-image values are one measurement, so that two evaluations
#: pair only where they agree on each (:func:`check_comparable`): the voxel-IoU protocol, the grid's resolution
#: (voxels per side), what the metric did with a ground truth that is not watertight (``gt_open_mesh``: refused,
#: closed or scored as it is) and the data scored (``data_id``: the content of the dataset's split,
#: :attr:`cerberus_core.datasets.manifest.SplitRecord.content_id`, chosen by the dataset and the split; two
#: datasets whose images share subject, pose and view names are told apart). Each with the value an evaluation that
#: does not record it was made under: ``"error"`` for ``gt_open_mesh``, the default before ``results.json``
#: recorded it; ``None``: not known, then not compared (``data_id`` of an evaluation from before it was recorded).
#: What the model was shown (``input_look``) and where it ran (``computed_with``) change the model's answer, not the
#: measurement, and the images are matched one by one (:func:`image_pairs`).
MEASUREMENT: tuple[Setting, ...] = (Setting("protocol"), Setting("resolution"), Setting("gt_open_mesh", "error"),
                                    Setting("data_id", name="the data scored (data_id)", chosen_by=("data", "split")))


def measurement(evaluation: Evaluation) -> dict[str, Any]:
    """The settings of :data:`MEASUREMENT` an evaluation was made under, ``{setting: value}`` in its order: as its
    ``results.json`` records them, else the value of one made before it was recorded (``None``: not known, as is
    every setting of bare records).

    >>> measurement({"protocol": "kato", "resolution": 32, "records": []})  # before gt_open_mesh was recorded
    {'protocol': 'kato', 'resolution': 32, 'gt_open_mesh': 'error', 'data_id': None}
    >>> measurement([{"index": 0, "iou": 0.5}])
    {'protocol': None, 'resolution': None, 'gt_open_mesh': None, 'data_id': None}
    """
    if not isinstance(evaluation, Mapping):
        return dict.fromkeys(s.key for s in MEASUREMENT)
    return {s.key: s.default if evaluation.get(s.key) is None else evaluation[s.key] for s in MEASUREMENT}


def _by_value(values: Mapping[str, Any]) -> list[tuple[Any, list[str]]]:
    """``{name: value}`` grouped by value, ``[(value, names)]`` in the order each value first appears; a ``None``
    value (not known) left out."""
    groups: list[tuple[Any, list[str]]] = []
    for name, value in values.items():
        if value is None:
            continue
        same = next((names for v, names in groups if v == value), None)
        if same is None:
            groups.append((value, [name]))
        else:
            same.append(name)
    return groups


def check_comparable(evaluations: Mapping[str, Evaluation]) -> None:
    """Refuse to pair evaluations measured differently: each setting of :data:`MEASUREMENT` must be the same in
    every evaluation that knows it (:func:`measurement`).

    Args:
        evaluations: ``{name: results.json dict or its records}``; the names label them in the message.
    Raises:
        IncomparableEvaluationsError: a setting differs; the message names each such setting with each
            evaluation's value, and the fix (``differences``: ``{setting: {name: value}}``).

    Example: a ``results.json`` from before ``gt_open_mesh`` was recorded pairs with one that records ``"error"``:

        >>> old = {"protocol": "kato", "resolution": 32, "records": []}
        >>> check_comparable({"old": old, "new": old | {"gt_open_mesh": "error"}})
        >>> check_comparable({"old": old, "new": old | {"gt_open_mesh": "close", "resolution": 64}})
        Traceback (most recent call last):
        ...
        cerberus_core.errors.IncomparableEvaluationsError: evaluations measured under different settings cannot be
        paired image by image: resolution is 32 in old, 64 in new; gt_open_mesh is 'error' in old, 'close' in new;
        evaluate them again with the same `resolution` and `gt_open_mesh`, or compare only those that agree

    Evaluations of different data (two splits or datasets whose images share subject, pose and view names) are
    refused too, while one from before ``data_id`` was recorded pairs with any:

        >>> check_comparable({"old": old, "large": old | {"data_id": "49bc547ce46b9202"}})
        >>> check_comparable({"large": old | {"data_id": "49bc547ce46b9202"}, "other": old | {"data_id": "0f1e2d3c"}})
        Traceback (most recent call last):
        ...
        cerberus_core.errors.IncomparableEvaluationsError: evaluations measured under different settings cannot be
        paired image by image: the data scored (data_id) is '49bc547ce46b9202' in large, '0f1e2d3c' in other;
        evaluate them again with the same `data` and `split`, or compare only those that agree
    """
    settings = {name: measurement(evaluation) for name, evaluation in evaluations.items()}
    differences = {s: _by_value({name: values[s.key] for name, values in settings.items()}) for s in MEASUREMENT}
    differences = {s: groups for s, groups in differences.items() if len(groups) > 1}
    if not differences:
        return
    said = "; ".join(f"{s.said} is " + ", ".join(f"{shown(value)} in {' and '.join(names)}" for value, names in groups)
                     for s, groups in differences.items())
    chosen = " and ".join(f"`{key}`" for s in differences for key in s.choices)
    raise IncomparableEvaluationsError(
        f"evaluations measured under different settings cannot be paired image by image: {said}; evaluate them "
        f"again with the same {chosen}, or compare only those that agree",
        differences={s.key: {name: value for value, names in groups for name in names}
                     for s, groups in differences.items()})


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
        IncomparableEvaluationsError: ``a`` and ``b`` were measured under different settings
            (:func:`check_comparable`; named ``a`` and ``b`` in the message).

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
    check_comparable({"a": a, "b": b})
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
            :class:`~cerberus_core.errors.DatasetError` (evaluations of different test sets), and both must have
            been measured alike, else an :class:`~cerberus_core.errors.IncomparableEvaluationsError`
            (:func:`check_comparable`).
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


def group_means(evaluation: Evaluation, by: str | Callable[[Mapping[str, Any]], Hashable | None],
                key: str = "iou") -> dict[Any, float]:
    """The mean of the per-image value ``key`` (voxel IoU, 0 to 1, for ``"iou"``) over the images of each group.

    Args:
        evaluation: a ``results.json`` dict (its ``records``) or the records, one dict per image.
        by: a record's group: the record's field of that name (``"subject"``), or a function of the record.
        key: the per-image value to average.
    Returns:
        ``{group: mean}`` in the order the groups first appear, over the records whose group is not ``None`` and
        whose ``key`` is set (a group with no such record is absent).

    Example:
        >>> records = [{"index": 0, "subject": "s1", "iou": 0.25}, {"index": 1, "subject": "s1", "iou": 0.75},
        ...            {"index": 2, "subject": "s2", "iou": 0.5}, {"index": 3, "subject": "s2", "iou": None}]
        >>> group_means(records, "subject")
        {'s1': 0.5, 's2': 0.5}
        >>> group_means(records, lambda r: "high" if r["iou"] and r["iou"] > 0.4 else None)
        {'high': 0.625}
    """
    values: dict[Any, list[float]] = {}
    for record in _records(evaluation):
        group = record.get(by) if isinstance(by, str) else by(record)
        if group is not None and record.get(key) is not None:
            values.setdefault(group, []).append(record[key])
    return {group: statistics.fmean(v) for group, v in values.items()}


def run_folder(path: str | Path) -> Path | None:
    """The run folder of the evaluation at ``path`` (:func:`evaluation_file`): ``RUN`` where the evaluation is
    ``RUN/eval/results.json`` (``path`` is ``RUN``, ``RUN/eval`` or that file), else ``None`` (an evaluation
    written to a folder of its own). The ``training`` and ``own-images`` columns read its ``metrics.csv`` and
    ``eval_train/``.

    Raises:
        NoEvaluationError: no evaluation at ``path``.

    Example:
        >>> import json, tempfile
        >>> run = Path(tempfile.mkdtemp())
        >>> (run / "eval").mkdir()
        >>> _ = (run / "eval" / RESULTS).write_text(json.dumps({"records": []}))
        >>> run_folder(run / "eval") == run, run_folder(run / "eval" / RESULTS) == run
        (True, True)
        >>> (run / "heldout").mkdir()
        >>> _ = (run / "heldout" / RESULTS).write_text(json.dumps({"records": []}))
        >>> print(run_folder(run / "heldout"))
        None
    """
    file = evaluation_file(path)
    return file.parent.parent if file.parent.name == "eval" else None


# ----------------------------------------------------------------------------- the optional columns
#: A cell of an optional column: the text the table prints (its figures rounded as the column says), a count, or
#: ``None`` where the evaluation or its run lacks the figure (printed ``-``).
Cell = str | int | None

#: The folder beside a run's ``eval/`` that holds its evaluation on its own training images (``cerberus eval RUN
#: --data TRAIN --split train --out RUN/eval_train``), read by the ``own-images`` columns.
OWN_IMAGES = "eval_train"

#: The column of :data:`COLUMN_GROUPS` ``heldout`` for the images that are not of a held-out pose family.
CANONICAL = "canonical"


@dataclass(frozen=True)
class Column:
    """One optional column of :func:`comparison_rows`.

    Attributes:
        header: the column's header.
        cell: ``(results.json dict, run folder or None) -> Cell``: the row's cell, read from the evaluation's
            summaries and, for a few columns, the run's folder (:func:`run_folder`; ``None`` when there is none).
    """

    header: str
    cell: Callable[[Mapping[str, Any], Path | None], Cell]


@dataclass(frozen=True)
class ColumnGroup:
    """Optional columns added together by name (:func:`comparison_rows`'s ``columns``).

    Attributes:
        name: the group's name.
        summary: what the group answers, in one line (the command's help lists it).
        columns: its columns, in the table's order.
    """

    name: str
    summary: str
    columns: tuple[Column, ...]


def _section(evaluation: Mapping[str, Any], key: str) -> Mapping[str, Any]:
    """A summary of ``results.json`` (``segments``, ``allocation``...); empty where it was not measured."""
    return evaluation.get(key) or {}


def _number(value: float | None, digits: int) -> str | None:
    """``value`` with ``digits`` decimals; ``None`` for ``None``, NaN or infinity."""
    return None if value is None or not math.isfinite(value) else f"{value:.{digits}f}"


def _per_name(values: Mapping[str, float | None], digits: int) -> str | None:
    """``{name: value}`` as ``name value, name value`` in its order (values of ``digits`` decimals, unset ones
    left out); ``None`` when none is set."""
    shown = [f"{name} {text}" for name, v in values.items() if (text := _number(v, digits)) is not None]
    return ", ".join(shown) or None


def _of_results(header: str, read: Callable[[Mapping[str, Any]], Cell]) -> Column:
    """A column read from the evaluation alone."""
    return Column(header, lambda evaluation, run: read(evaluation))


def _spare_parts(evaluation: Mapping[str, Any]) -> Cell:
    """``k of N``: the parts whose deletion costs at most ``segments.spare_threshold`` of IoU, of all parts."""
    segments = _section(evaluation, "segments")
    spare = segments.get("spare_count")
    return None if spare is None else f"{spare} of {len(segments.get('deletion_loss') or []) or '?'}"


def _top_spreads(evaluation: Mapping[str, Any]) -> Cell:
    """The four largest keypoint spreads (px, one decimal), largest first."""
    spreads = [s for s in _section(evaluation, "allocation").get("keypoint_spread") or [] if s is not None]
    return " ".join(f"{s:.1f}" for s in sorted(spreads, reverse=True)[:4]) or None


def _merged_labels(evaluation: Mapping[str, Any]) -> Cell:
    """The labels (left and right merged) of the parts whose agreement is at least 0.5, sorted."""
    quality = _section(evaluation, "part_quality")
    parts = (quality.get("sides_merged") or quality).get("parts") or []
    return ", ".join(sorted({p["label"] for p in parts if p.get("label") and (p.get("agreement") or 0) >= 0.5})) or None


def _labels_with_agreement(evaluation: Mapping[str, Any]) -> Cell:
    """Each labelled part's label (per side) and agreement, most consistent first."""
    parts = [p for p in _section(evaluation, "part_quality").get("parts") or []
             if p.get("label") and p.get("agreement") is not None]
    return ", ".join(f"{p['label']} ({p['agreement']:.2f})" for p in sorted(parts, key=lambda p: -p["agreement"])) or None


def _of_training(header: str, read: Callable[[TrainingTime], Cell]) -> Column:
    """A column read from the run's ``metrics.csv`` (:func:`~cerberus_core.plumbing.metrics_csv.training_time`)."""
    def cell(evaluation: Mapping[str, Any], run: Path | None) -> Cell:
        trained = None if run is None else training_time(run / METRICS_CSV)
        return None if trained is None else read(trained)

    return Column(header, cell)


def _own_images(run: Path | None) -> tuple[float | None, int]:
    """The mean voxel IoU on the run's own training images (``RUN/eval_train``) and how many were scored;
    ``(None, 0)`` without that evaluation."""
    own = None if run is None else load_evaluation(run / OWN_IMAGES, missing_ok=True)
    if own is None:
        return None, 0
    return image_mean(own, "iou"), sum(r.get("iou") is not None for r in _records(own))


def _own_cell(evaluation: Mapping[str, Any], run: Path | None) -> Cell:
    mean, n = _own_images(run)
    return None if mean is None else f"{mean:.4f} ({n})"


def _gap_cell(evaluation: Mapping[str, Any], run: Path | None) -> Cell:
    own, test = _own_images(run)[0], image_mean(evaluation, "iou")
    return None if own is None or test is None else f"{own - test:.3f}"


def pose_family(record: Mapping[str, Any]) -> str | None:
    """A record's held-out pose family (:func:`cerberus_core.bodies.human_heldout.family_of`), :data:`CANONICAL`
    for another pose, ``None`` for a record without one: the groups of the ``heldout`` columns.

    >>> from cerberus_core.bodies.human_heldout import heldout_pose_id
    >>> pose_family({"pose": heldout_pose_id(1)}), pose_family({"pose": 3}), pose_family({"index": 0})
    ('jumping_jack', 'canonical', None)
    """
    pose = record.get("pose")
    if pose is None:
        return None
    return family_of(pose) if is_heldout_id(pose) else CANONICAL


def _family_column(family: str) -> Column:
    """The mean voxel IoU (three decimals) of one family's images; ``None`` for an evaluation without held-out
    poses, whose images are all of other poses."""
    def read(evaluation: Mapping[str, Any]) -> Cell:
        means = group_means(evaluation, pose_family)
        return _number(means.get(family), 3) if set(means) - {CANONICAL} else None

    return _of_results(family, read)


#: The optional column groups of :func:`comparison_rows` (``cerberus compare``), in the order they are listed.
COLUMN_GROUPS: tuple[ColumnGroup, ...] = (
    ColumnGroup("parts", "the parts: spares, keypoint spreads, segment → keypoint and recall, labels, consistency, "
                "hidden", (
        _of_results("spare parts", _spare_parts),
        _of_results("keypoint spread, top 4 (px)", _top_spreads),
        _of_results("segment → keypoint (px)",
                    lambda e: _per_name(_section(e, "allocation").get("segment_to_keypoint") or {}, 1)),
        _of_results("segment recall", lambda e: _per_name(_section(e, "segments").get("recall") or {}, 2)),
        _of_results("part consistency", lambda e: _number(_section(e, "part_quality").get("consistency"), 3)),
        _of_results("merged labels ≥ 0.5", _merged_labels),
        _of_results("part labels (agreement)", _labels_with_agreement),
        _of_results("parts hidden in most images",
                    lambda e: _section(e, "part_visibility").get("parts_hidden_in_most_images")),
    )),
    ColumnGroup("depth", "depth across views: input- and turned-view silhouette IoU, mean translation disagreement "
                "(world units)", (
        _of_results("input-view silhouette IoU",
                    lambda e: _number(_section(e, "depth").get("input_view_silhouette_iou"), 3)),
        _of_results("turned-view silhouette IoU",
                    lambda e: _number(_section(e, "depth").get("turned_view_silhouette_iou"), 3)),
        _of_results("translation disagreement",
                    lambda e: _number(_section(e, "depth").get("mean_translation_disagreement"), 3)),
    )),
    ColumnGroup("training", "from RUN/metrics.csv: steps, minutes (summed over a resumed run's sittings), "
                "steps/s", (
        _of_training("steps", lambda t: t.steps),
        _of_training("minutes", lambda t: f"{t.seconds / 60:.0f}"),
        _of_training("steps/s", lambda t: _number(t.steps / t.seconds if t.seconds > 0 else None, 2)),
    )),
    ColumnGroup("own-images", f"IoU on the run's own training images (RUN/{OWN_IMAGES}/results.json), its gap to "
                "the test IoU", (
        Column("own training images (n)", _own_cell),
        Column("gap", _gap_cell),
    )),
    ColumnGroup("heldout", "mean IoU of each held-out pose family (human heldout_poses data) and of the canonical "
                "views", tuple(_family_column(f) for f in (*FAMILIES, CANONICAL))),
)


def column_groups(names: str | Sequence[str]) -> tuple[ColumnGroup, ...]:
    """The groups of :data:`COLUMN_GROUPS` that ``names`` asks for, in its order, each once.

    Args:
        names: group names, comma-separated (``"parts,depth"``) or as a sequence; empty for none.
    Raises:
        ConfigError: a name that is no group (key ``columns``); the message lists the groups.

    Example:
        >>> [g.name for g in column_groups("parts, depth,parts")], column_groups(())
        (['parts', 'depth'], ())
        >>> column_groups("bogus")
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ConfigError: columns = 'bogus': no column group 'bogus'; the groups are parts, ...
    """
    wanted = [n.strip() for n in (names.split(",") if isinstance(names, str) else names) if n.strip()]
    known = {group.name: group for group in COLUMN_GROUPS}
    for name in wanted:
        if name not in known:
            raise ConfigError.about("columns", names if isinstance(names, str) else ",".join(names),
                                    f"no column group {name!r}{did_you_mean(name, known)}; the groups are "
                                    f"{', '.join(known)}")
    return tuple(known[name] for name in dict.fromkeys(wanted))


def comparison_rows(evaluations: Mapping[str, Mapping[str, Any]], columns: str | Sequence[str] = (),
                    runs: Mapping[str, Path | None] | None = None) -> tuple[list[str], list[list[Any]]]:
    """Several evaluations of one test set side by side, each paired image by image with the first.

    Args:
        evaluations: ``{name: results.json dict}`` (:func:`load_evaluation`), the baseline first.
        columns: the optional column groups to add after the paired values, by name (:data:`COLUMN_GROUPS`;
            ``"parts,depth"`` or ``["parts", "depth"]``); none by default.
        runs: ``{name: run folder or None}`` (:func:`run_folder`) for the columns that read the run's folder
            (``training``, ``own-images``); a name missing here has none, and those cells are ``None``.
    Returns:
        ``(header, rows)`` for :func:`~cerberus_core.eval.markdown.markdown_table`: per evaluation its name, the
        images it scored and, for each of :data:`PAIRED_VALUES` that some evaluation's records have, the mean over
        its images of the per-image value (:func:`image_mean`; precision and recall too, not the pooled figures of
        its ``segments`` summary) and (column ``Δ ...``) its :func:`paired_difference` to the first (``None`` for
        the first itself, or where either lacks it): of two evaluations of the same images, the difference of
        their means; then the cell of each :class:`Column` of the ``columns`` groups (text, a count, or ``None``
        where the evaluation lacks it).

    Raises:
        IncomparableEvaluationsError: the evaluations were measured under different settings (:data:`MEASUREMENT`;
            :func:`check_comparable`, the message names each by its name here).
        DatasetError: two evaluations scored different images under one index (different test sets).
        ConfigError: a name of ``columns`` that is no group of :data:`COLUMN_GROUPS` (the message lists them).

    Example:
        >>> a = {"records": [{"index": i, "iou": 0.5 + 0.05 * i} for i in range(3)]}
        >>> b = {"records": [{"index": i, "iou": 0.52 + 0.06 * i} for i in range(3)]}
        >>> header, rows = comparison_rows({"base": a, "new": b})
        >>> header
        ['model', 'images', 'voxel IoU', 'Δ voxel IoU']
        >>> rows[1][:2], round(rows[1][2], 4), str(rows[1][3])
        (['new', 3], 0.58, '+0.030 ± 0.006 (3 / 3)')
    """
    extra = [column for group in column_groups(columns) for column in group.columns]
    check_comparable(evaluations)
    runs = runs or {}
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
        rows.append(row + [column.cell(evaluation, runs.get(name)) for column in extra])
    return header + [column.header for column in extra], rows
