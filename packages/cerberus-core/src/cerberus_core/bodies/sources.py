"""Body sources behind the datasets: one small adapter per geometry provider.

A :class:`BodySource` answers four questions for the generator (:mod:`cerberus_core.datasets.generate`):
which subjects a split has, which pose ids a subject offers for a split, which pose is canonical,
and the :class:`~cerberus_core.bodies.body.PosedBody` of (subject, pose ids). Every answer is a
deterministic function of the source's options and the seed, so a shard can be regenerated alone.

Sources: ``human`` (anny, :mod:`cerberus_core.bodies.human`), ``animal`` (procedural quadrupeds,
:mod:`cerberus_core.bodies.animal`), ``primitives`` (capsule figures,
:mod:`cerberus_core.bodies.primitives`) and ``folder`` (your own meshes,
:mod:`cerberus_core.bodies.folder`).
"""
from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from cerberus_core.bodies.body import PosedBody


@dataclass(frozen=True)
class SubjectInfo:
    """A subject as the manifest lists it: a unique ``name`` and JSON-ready ``info`` (phenotype,
    species parameters, source file names ...)."""

    name: str
    info: dict[str, Any] = field(default_factory=dict, hash=False, compare=False)


class BodySource(ABC):
    """Geometry provider of a dataset.

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
    def subjects(self, split: str, n: int | None, seed: int) -> list[SubjectInfo]:
        """The ``n`` subjects of ``split`` (``None``: all the source has for the split)."""

    @abstractmethod
    def pose_pool(self, subject: str, split: str, n: int | None, seed: int) -> list[int]:
        """Pose ids of ``subject`` available to ``split``, at most ``n`` of them (``None``: all).

        Sources with unlimited poses return exactly ``n`` fresh ids; sources with a fixed set
        return up to ``n`` (the generator reuses them when it needs more).
        """

    def canonical_pose(self, subject: str) -> int | None:
        """Pose id of the subject's canonical pose, or ``None`` if the source has none."""
        return None

    @abstractmethod
    def bodies(self, subject: str, pose_ids: Sequence[int]) -> list[PosedBody]:
        """Normalised posed bodies of one subject, one per pose id, in order."""

    def describe(self) -> dict[str, Any]:
        """Options that determine the geometry (stored in the manifest's config; part of its hash)."""
        return {}


class _SeededSubjects(BodySource):
    """Shared logic of sources whose subjects come from a ``sample_subjects(n, seed, split)`` function
    and whose poses are unlimited (id 0 canonical, ids ``1..n`` sampled)."""

    def __init__(self) -> None:
        self._subjects: dict[str, Any] = {}

    def _sample(self, n: int, seed: int, split: str) -> list[Any]:
        raise NotImplementedError

    def _info(self, subject: Any) -> dict[str, Any]:
        return {}

    def subjects(self, split: str, n: int | None, seed: int) -> list[SubjectInfo]:
        if n is None:
            raise ValueError(f"the {self.name} source needs a subject count for split {split!r}")
        out = []
        for s in self._sample(n, seed, split):
            self._subjects[s.subject_id] = s
            out.append(SubjectInfo(s.subject_id, self._info(s)))
        return out

    def _subject(self, name: str) -> Any:
        if name not in self._subjects:
            raise KeyError(f"{self.name} subject {name!r} unknown; call subjects() for its split first")
        return self._subjects[name]

    def pose_pool(self, subject: str, split: str, n: int | None, seed: int) -> list[int]:
        if n is None:
            raise ValueError(f"the {self.name} source has unlimited poses; give a pose count")
        return list(range(1, n + 1))

    def canonical_pose(self, subject: str) -> int | None:
        return 0


class HumanSource(_SeededSubjects):
    """anny humans (:mod:`cerberus_core.bodies.human`); loads anny lazily on first posing."""

    name = "human"

    def __init__(self, device: str = "cpu") -> None:
        super().__init__()
        from cerberus_core.bodies import human

        self._human = human
        self.part_names = list(human.PART_NAMES)
        self._device = device
        self._model = None

    def _sample(self, n: int, seed: int, split: str) -> list[Any]:
        return self._human.sample_subjects(n, seed, split)

    def _info(self, subject: Any) -> dict[str, Any]:
        return {"phenotype": dict(subject.phenotype)}

    def bodies(self, subject: str, pose_ids: Sequence[int]) -> list[PosedBody]:
        if self._model is None:
            self._model = self._human.HumanBodySource(device=self._device)
        return self._model.posed_bodies(self._subject(subject), list(pose_ids))

    def describe(self) -> dict[str, Any]:
        import importlib.metadata as md

        try:
            version = md.version("anny")
        except md.PackageNotFoundError:  # pragma: no cover
            version = "?"
        return {"anny": version}


class PrimitiveSource(_SeededSubjects):
    """Capsule figures (:mod:`cerberus_core.bodies.primitives`)."""

    name = "primitives"

    def __init__(self) -> None:
        super().__init__()
        from cerberus_core.bodies import primitives

        self._prim = primitives
        self._model = primitives.PrimitiveBodySource()
        self.part_names = list(primitives.PART_NAMES)

    def _sample(self, n: int, seed: int, split: str) -> list[Any]:
        return self._prim.sample_subjects(n, seed, split)

    def _info(self, subject: Any) -> dict[str, Any]:
        return {"proportions": dict(subject.proportions)}

    def bodies(self, subject: str, pose_ids: Sequence[int]) -> list[PosedBody]:
        return self._model.posed_bodies(self._subject(subject), list(pose_ids))


class AnimalSource(BodySource):
    """Procedural quadrupeds (:mod:`cerberus_core.bodies.animal`): the same species in every split,
    with disjoint poses (the paper's protocol: 47 training and 3 test poses per species).

    Pose ids: training pose ``k`` has id ``k``; test pose ``k`` has id :attr:`TEST_POSE_BASE` ``+ k``.
    Poses come from :func:`~cerberus_core.bodies.animal.animal_pose_splits` with the dataset's seed.
    """

    name = "animal"
    shared_subjects = True
    TEST_POSE_BASE = 1000

    def __init__(self) -> None:
        from cerberus_core.bodies import animal

        self._animal = animal
        self.part_names = list(animal.ANIMAL_PART_NAMES)
        self._species: dict[str, Any] = {}
        self._seed = 0
        self._poses: dict[str, tuple[list, list]] = {}

    def subjects(self, split: str, n: int | None, seed: int) -> list[SubjectInfo]:
        n = self._animal.N_SPECIES if n is None else n
        self._seed = seed
        out = []
        for sp in self._animal.sample_species(n, seed):
            self._species[sp.name] = sp
            out.append(SubjectInfo(sp.name, {"archetype": sp.archetype, "params": dict(sp.params)}))
        return out

    def pose_pool(self, subject: str, split: str, n: int | None, seed: int) -> list[int]:
        if n is None:
            n = self._animal.N_TRAIN_POSES if split == "train" else self._animal.N_TEST_POSES
        base = 0 if split == "train" else self.TEST_POSE_BASE
        if split == "train" and n > self.TEST_POSE_BASE:
            raise ValueError(f"at most {self.TEST_POSE_BASE} training poses per species")
        return [base + k for k in range(n)]

    def _pose(self, subject: str, pose_id: int) -> Any:
        train, test = self._poses.get(subject, ([], []))
        is_test = pose_id >= self.TEST_POSE_BASE
        k = pose_id - self.TEST_POSE_BASE if is_test else pose_id
        if k >= len(test if is_test else train):  # the splits are prefix-stable: ask for enough of both
            n_train = max(len(train), 0 if is_test else k + 1)
            n_test = max(len(test), k + 1 if is_test else 0)
            train, test = self._animal.animal_pose_splits(self._species[subject], n_train, n_test, seed=self._seed)
            self._poses[subject] = (train, test)
        return (test if is_test else train)[k]

    def bodies(self, subject: str, pose_ids: Sequence[int]) -> list[PosedBody]:
        if subject not in self._species:
            raise KeyError(f"animal species {subject!r} unknown; call subjects() first")
        sp = self._species[subject]
        return [self._animal.build_animal(sp, self._pose(subject, p), int(p)) for p in pose_ids]

    def describe(self) -> dict[str, Any]:
        return {"target_faces": self._animal.DEFAULT_TARGET_FACES}


def make_source(name: str, **options: Any) -> BodySource:
    """Build a body source by name: ``human``, ``animal``, ``primitives`` or ``folder`` (which needs
    ``root=``; see :class:`cerberus_core.bodies.folder.FolderSource`)."""
    if name == "human":
        return HumanSource(**options)
    if name == "primitives":
        return PrimitiveSource(**options)
    if name == "animal":
        return AnimalSource(**options)
    if name == "folder":
        from cerberus_core.bodies.folder import FolderSource

        return FolderSource(**options)
    raise ValueError(f"unknown dataset source {name!r}; choose human, animal, primitives or folder")
