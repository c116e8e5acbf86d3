"""The identity-conditional ("Hard Human") evaluation of §5.3.

For each test subject, the part shapes (``local_vertices``) are extracted once, from one image of
the subject's canonical pose. Every other test image of that subject is then reconstructed by
posing those shapes with the rotations and translations predicted from that image, and scored by
voxel IoU against its own ground truth. Good scores mean the parts transfer between poses.

Choice of the canonical image: the canonical-pose image of the subject with the lowest view index
(or the view asked for). "Every other image" excludes only that one image; the other views of the
canonical pose are scored like any pose.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from cerberus_core.errors import ConfigError, ShapeError, UnknownSubjectError
from cerberus_core.eval.standard import IoUSummary, Score, VoxelScorer, summarize
from cerberus_core.parts import PartSet, transfer_pose


@dataclass(frozen=True)
class ItemMeta:
    """What the evaluation needs to know about a test image besides its pixels."""

    index: int
    subject: str
    pose: int
    view: int
    is_canonical: bool


def select_canonical(items: Sequence[ItemMeta], view: int | None = None) -> dict[str, int]:
    """Dataset index of the canonical image of each subject that has one.

    Args:
        items: metadata of the test images.
        view: use this view of the canonical pose (default: the lowest view present).
    Returns:
        ``{subject: index}``; subjects without a canonical image (or without that view) are absent.

    Example:
        >>> items = [ItemMeta(index=0, subject="s1", pose=0, view=2, is_canonical=True),
        ...          ItemMeta(index=1, subject="s1", pose=0, view=1, is_canonical=True),
        ...          ItemMeta(index=2, subject="s1", pose=1, view=0, is_canonical=False),
        ...          ItemMeta(index=3, subject="s2", pose=1, view=0, is_canonical=False)]
        >>> select_canonical(items), select_canonical(items, view=2)  # s2 has no canonical image
        ({'s1': 1}, {'s1': 0})
    """
    best: dict[str, ItemMeta] = {}
    for it in items:
        if not it.is_canonical or (view is not None and it.view != view):
            continue
        cur = best.get(it.subject)
        if cur is None or (it.view, it.index) < (cur.view, cur.index):
            best[it.subject] = it
    return {s: it.index for s, it in sorted(best.items())}


class CanonicalParts:
    """The part shapes extracted from each subject's canonical image.

    Args:
        shapes: ``{subject: reconstruction of batch 1}`` of the canonical images.
        indices: ``{subject: dataset index}`` of those images.
    Raises:
        ConfigError: a subject of ``indices`` has no shapes.
        ShapeError: a reconstruction of ``shapes`` is not of batch 1.

    Example: subject ``s1``'s one part (a tetrahedron with unit edges along the axes, normalised units), posed by
    two images whose predicted translations are 0 and 0.5 along x:

        >>> import torch
        >>> from cerberus_core.parts import PartSet
        >>> tet = torch.tensor([[0.0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]])
        >>> faces = torch.tensor([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
        >>> canonical = CanonicalParts({"s1": PartSet.from_posed(tet[None, None], faces)}, {"s1": 0})
        >>> poses = PartSet(torch.zeros(2, 1, 4, 3), faces, torch.eye(3).expand(2, 1, 3, 3),
        ...                 torch.tensor([[[0.0, 0, 0]], [[0.5, 0, 0]]]))
        >>> posed = canonical.pose("s1", poses).posed()
        >>> tuple(posed.shape), posed[1, 0, 1].tolist()  # (B, P, V, 3); vertex 1 moved by 0.5
        ((2, 1, 4, 3), [1.5, 0.0, 0.0])
        >>> canonical.applies_to(ItemMeta(0, "s1", 0, 0, True)), canonical.applies_to(ItemMeta(3, "s1", 0, 1, True))
        (False, True)
        >>> CanonicalParts({}, {"s1": 0})
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ConfigError: CanonicalParts: no shapes for subjects ['s1']; ...
    """

    def __init__(self, shapes: dict[str, PartSet], indices: dict[str, int]) -> None:
        missing = set(indices) - set(shapes)
        if missing:
            raise ConfigError(f"CanonicalParts: no shapes for subjects {sorted(missing)}; pass a canonical "
                              "reconstruction in `shapes` for every subject in `indices`", key="shapes")
        for s, r in shapes.items():
            if r.batch_size != 1:
                raise ShapeError(f"CanonicalParts: subject {s!r} needs a batch-1 reconstruction, got {r.batch_size}; "
                                 "pass one reconstruction per subject")
        self.shapes = shapes
        self.indices = indices

    def applies_to(self, item: ItemMeta) -> bool:
        """Whether ``item`` is scored in the hard test (its subject has a canonical image, and it is
        not that image)."""
        return item.subject in self.shapes and self.indices.get(item.subject) != item.index

    def pose(self, subject: str, poses: PartSet) -> PartSet:
        """The canonical parts of ``subject`` with the transforms of ``poses`` (any batch size).

        Raises:
            UnknownSubjectError: ``subject`` has no canonical image here (a ``KeyError`` too).
        """
        if subject not in self.shapes:
            raise UnknownSubjectError(f"CanonicalParts.pose: no canonical image of subject {subject!r} (those with one: "
                                      f"{', '.join(map(repr, sorted(self.shapes))) or 'none'}); pose a subject "
                                      "`applies_to(item)` accepts, or give its canonical reconstruction in `shapes` "
                                      "and its image in `indices`")
        return transfer_pose(self.shapes[subject], poses)


class HardHumanIoU:
    """The Hard Human test: each subject's canonical part shapes, posed by every other image of it, scored like
    :class:`~cerberus_core.eval.accumulators.StandardIoU` (the accumulator of the ``hard`` row of
    :data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS`, fed
    :class:`~cerberus_core.eval.accumulators.BatchResult` s); adds ``hard_iou``, ``hard_clipped``, ``hard_error`` to the
    records it applies to. :meth:`summary` is ``None`` when it applied to none."""

    def __init__(self, scorer: VoxelScorer, canonical: CanonicalParts) -> None:
        self.scorer = scorer
        self.canonical = canonical
        self.scores: list[Score] = []
        self.groups: list[str] = []

    @classmethod
    def for_evaluation(cls, context: Any) -> HardHumanIoU:
        """From an :class:`~cerberus_core.eval.accumulators.EvalContext`: its scorer and the canonical part
        shapes (reconstructed now)."""
        return cls(context.scorer, context.canonical())

    def update(self, batch: Any) -> None:
        for _, item, one, gt, rec in batch.scored():
            if self.canonical.applies_to(item):
                score = self.scorer(self.canonical.pose(item.subject, one).part_meshes(0), gt)
                self.scores.append(score)
                self.groups.append(item.subject)
                rec.update(hard_iou=score.iou, hard_clipped=score.clipped, hard_error=score.error)

    def summary(self) -> IoUSummary | None:
        return summarize(self.scores, self.groups) if self.scores else None

    @staticmethod
    def outputs(hard: HardHumanIoU | None) -> dict[str, Any]:
        """Its entries of a result: ``hard`` (the summary, ``None``: not run or nothing scored) and
        ``canonical`` (``{subject: dataset index}`` of the images the shapes came from)."""
        return {"hard": None if hard is None else hard.summary(),
                "canonical": {} if hard is None else dict(hard.canonical.indices)}
