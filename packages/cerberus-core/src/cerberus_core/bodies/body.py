"""The posed-body record that every body source (human, animal, mesh folder) produces, and the
contract of those sources (:class:`BodySource`, :class:`Subject`; the sources themselves and
:func:`~cerberus_core.bodies.sources.make_source` are in :mod:`cerberus_core.bodies.sources`).

A body source turns (subject, pose) into a :class:`PosedBody`: a watertight-ish triangle mesh in the
dataset's world frame plus per-vertex ground-truth part labels. World frame conventions (shared with
:mod:`cerberus_core.render.camera`): right-handed, +Y up, the body faces +Z at azimuth 0, units are
"normalised units" in which every ground truth lies inside ``[-0.5, 0.5]^3`` (the voxel-IoU
convention of Kato et al.).

Normalisation rule (one rule for all sources, see :func:`normalise_subject`): all poses of one
subject share one scale factor, chosen so that the largest bounding-box extent over the subject's
poses is ``FILL`` (0.9); each pose is then centred on its own bounding-box centre. A shared scale
keeps part shapes identical across poses, which pose consistency relies on.
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from cerberus_core.errors import ConfigError
from cerberus_core.shapes import check_shapes

FILL: float = 0.9
"""Largest bounding-box extent of a subject, in normalised units (inside the unit cube)."""


@dataclass
class PosedBody:
    """One body in one pose.

    Attributes:
        vertices: ``(V, 3)`` float32, world coordinates in normalised units.
        faces: ``(F, 3)`` int64 vertex indices, counter-clockwise seen from outside.
        vertex_parts: ``(V,)`` int16 ground-truth semantic part index per vertex (evaluation only,
            never given to training).
        part_names: names of the semantic parts, ``part_names[vertex_parts[i]]``.
        subject: subject (or species) identifier.
        pose_id: integer pose identifier, unique within the subject.
    """

    vertices: np.ndarray
    faces: np.ndarray
    vertex_parts: np.ndarray
    part_names: list[str]
    subject: str
    pose_id: int
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        v = np.asarray(self.vertices)
        f = np.asarray(self.faces)
        check_shapes("PosedBody", vertices=(v, "V 3"), faces=(f, "F 3"))
        if not np.isfinite(v).all():
            raise ValueError(f"PosedBody {self.subject}/{self.pose_id}: vertices contain NaN or inf")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise ValueError(f"PosedBody {self.subject}/{self.pose_id}: faces index outside 0..{len(v) - 1}")
        if np.asarray(self.vertex_parts).shape != (len(v),):
            raise ValueError("PosedBody.vertex_parts must have one label per vertex")
        self.vertices = v.astype(np.float32, copy=False)
        self.faces = f.astype(np.int64, copy=False)
        self.vertex_parts = np.asarray(self.vertex_parts).astype(np.int16, copy=False)


def normalise_subject(poses: Sequence[np.ndarray], fill: float = FILL) -> tuple[float, list[np.ndarray]]:
    """Scale all poses of one subject by one factor and centre each pose.

    Args:
        poses: vertex arrays ``(V_i, 3)`` of one subject in any consistent unit (e.g. metres).
        fill: the largest bounding-box extent over all poses after scaling.

    Returns:
        ``(scale, normalised)`` where ``normalised[i] = (poses[i] - centre_i) * scale`` and
        ``centre_i`` is the bounding-box centre of pose ``i``. Every output lies in
        ``[-fill/2, fill/2]^3``.
    """
    if len(poses) == 0:
        raise ValueError("normalise_subject needs at least one pose")
    extents = [float((p.max(0) - p.min(0)).max()) for p in poses]
    largest = max(extents)
    if not np.isfinite(largest) or largest <= 0:
        raise ValueError(f"normalise_subject: degenerate subject (largest extent {largest})")
    scale = fill / largest
    out = []
    for p in poses:
        centre = 0.5 * (p.max(0) + p.min(0))
        out.append(((p - centre) * scale).astype(np.float32))
    return scale, out


@dataclass(frozen=True)
class Subject:
    """One subject (person, species, mesh folder) as the manifest stores it.

    Attributes:
        name: unique within the dataset (``PosedBody.subject``).
        info: JSON-ready parameters of the subject: everything its source needs to pose it.
    """

    name: str
    info: dict[str, Any] = field(default_factory=dict, hash=False, compare=False)

    def need(self, source: str, *keys: str) -> list[Any]:
        """``info[key]`` for each key, or a ``KeyError`` naming the missing ones (an older manifest)."""
        missing = [k for k in keys if k not in self.info]
        if missing:
            raise KeyError(f"{source} subject {self.name!r} lacks {missing} in its record; the manifest predates "
                           "self-contained subject records: rerun the same `cerberus data generate` command (it "
                           "resumes and rewrites the manifest)")
        return [self.info[k] for k in keys]


class BodySource(ABC):
    """Geometry provider of a dataset (:mod:`cerberus_core.bodies.sources` describes the calls).

    Attributes:
        name: the source's name as ``cerberus data generate --dataset`` spells it.
        part_names: names of the ground-truth parts indexed by ``PosedBody.vertex_parts``.
        shared_subjects: ``True`` if every split holds the same subjects with disjoint poses (the
            animal protocol); ``False`` if splits hold disjoint subjects (human, folder).
    """

    name: str = "abstract"
    part_names: list[str]
    shared_subjects: bool = False

    @abstractmethod
    def subjects(self, split: str, n: int | None, seed: int) -> list[Subject]:
        """The ``n`` subjects of ``split`` (``None``: all the source has for the split)."""

    @abstractmethod
    def pose_pool(self, subject: Subject, split: str, n: int | None) -> list[int]:
        """Pose ids of ``subject`` available to ``split``, at most ``n`` of them (``None``: all).

        Sources with unlimited poses return exactly ``n`` fresh ids; sources with a fixed set
        return up to ``n`` (the generator reuses them when it needs more).
        """

    def canonical_pose(self, subject: Subject) -> int | None:
        """Pose id of the subject's canonical pose, or ``None`` if the source has none."""
        return None

    def motion_pairs(self, subject: Subject, split: str, n: int | None) -> list[tuple[int, int]]:
        """``n`` pose-id pairs ``(a, b)`` of ``subject``, each two nearby frames of one motion (the
        ``pose_pairs: motion`` mode of a ``pairs`` split); sources without motions refuse.

        Raises:
            ConfigError: the source has no motion pairs (or, for ``n=None``, no fixed number of them).
        """
        raise ConfigError.about(f"splits.{split}.pose_pairs", "motion", f"the {self.name} source has no motion pose "
                                f"pairs; use `splits.{split}.pose_pairs=independent`")

    @abstractmethod
    def bodies(self, subject: Subject, pose_ids: Sequence[int]) -> list[PosedBody]:
        """Normalised posed bodies of one subject, one per pose id, in order; each depends only on
        ``(subject, pose id)``, never on the other ids asked for."""

    def describe(self) -> dict[str, Any]:
        """Options that determine the geometry (stored in the manifest's config; part of its hash)."""
        return {}
