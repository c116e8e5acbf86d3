"""Two evaluations compared image by image: is one model better than another on the same test images?

Two ``cerberus eval`` results of the same test set (``results.json``, or
:attr:`~cerberus_core.eval.runner.EvaluationResult.records`) score the same images, so their difference is
best read per image: the images are matched by their record's ``index`` (and must agree on ``subject``, ``pose``
and ``view`` where both records have them), and :func:`paired_difference`
gives the mean of ``a - b`` over the images both scored, its standard error and how many images favour
``a`` (:class:`PairedDifference`). Pairing removes what the images share (a hard pose is hard for both
models), so its standard error is usually much smaller than either mean's own. Any per-image value of the
records compares: ``iou``, ``hard_iou``, or one value against another of the same evaluation (Human
against Hard Human).

Nothing here needs torch: the experiments' tables import it to read ``results.json`` files.
"""
from __future__ import annotations

import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from cerberus_core.errors import DatasetError

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


def paired_difference(a: Evaluation | None, b: Evaluation | None, key_a: str = "iou",
                      key_b: str | None = None) -> PairedDifference | None:
    """The paired difference ``a[key_a] - b[key_b]`` per image, over the images both scored.

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
    key_b = key_a if key_b is None else key_b
    rb = {r["index"]: r for r in _records(b)}
    d = []
    for r in _records(a):
        other = rb.get(r["index"], {})
        if r.get(key_a) is None or other.get(key_b) is None:
            continue
        _same_image(r, other)
        d.append(r[key_a] - other[key_b])
    if len(d) < 2:
        return None
    return PairedDifference(statistics.mean(d), statistics.stdev(d) / len(d) ** 0.5, sum(x > 0 for x in d), len(d))
