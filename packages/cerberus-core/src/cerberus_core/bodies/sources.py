"""Body sources behind the datasets: one small, stateless adapter per geometry provider.

A :class:`~cerberus_core.bodies.body.BodySource` is a set of pure functions of its construction
options (and, for ``folder``, the files it reads):

* :meth:`~BodySource.subjects` ``(split, n, seed) -> [Subject]`` — who is in a split;
* :meth:`~BodySource.pose_pool` ``(subject, split, n) -> [pose id]`` — which poses a split may use;
* :meth:`~BodySource.canonical_pose` ``(subject) -> pose id | None``;
* :meth:`~BodySource.motion_pairs` ``(subject, split, n) -> [(pose id, pose id)]`` — pairs of nearby
  frames of one motion (``human`` only; the others refuse);
* :meth:`~BodySource.heldout_poses` ``(subject, split, n) -> [pose id]`` — poses its training generators
  do not make (``human`` only; the others refuse);
* :meth:`~BodySource.bodies` ``(subject, pose ids) -> [PosedBody]`` — mesh + part labels;
* :meth:`~BodySource.prepare` ``()`` — load a body model now (``human``: anny), before the generator's bar.

A :class:`~cerberus_core.bodies.body.Subject` is a small JSON-ready record (its ``name`` and
``info``: phenotype, species parameters, pose seed, file names ...) that holds everything :meth:`~BodySource.bodies` needs. The
dataset manifest stores these records (:attr:`Manifest.subjects <cerberus_core.datasets.manifest.Manifest.subjects>`), so a reader rebuilds any body from
the manifest alone (:attr:`SubjectRecord.subject <cerberus_core.datasets.manifest.SubjectRecord.subject>`), without replaying the generator's calls; no call
depends on an earlier one. Sources may cache (a loaded model, a subject's scale), never remember.

Sources: ``human`` (anny, :mod:`cerberus_core.bodies.human`), ``animal`` (procedural quadrupeds,
:mod:`cerberus_core.bodies.animal`), ``primitives`` (capsule figures,
:mod:`cerberus_core.bodies.primitives`) and ``folder`` (your own meshes,
:mod:`cerberus_core.bodies.folder`). Each is registered under the ``cerberus.bodies`` entry points in
cerberus-core's ``pyproject.toml``, the way a third party registers its own (docs/bodies.md);
:func:`~cerberus_core.bodies.body.source_class` finds one by name.
"""
from __future__ import annotations

from abc import abstractmethod
from collections.abc import Sequence
from typing import Any

from cerberus_core.bodies import animal, human, primitives
from cerberus_core.bodies.body import BodySource, PosedBody, Subject
from cerberus_core.bodies.human_heldout import heldout_pose_id
from cerberus_core.bodies.human_motion import motion_pose_id
from cerberus_core.errors import ConfigError

__all__ = ["AnimalSource", "HumanSource", "PrimitiveSource"]


class _SeededSubjects(BodySource):
    """Shared logic of sources whose subjects come from a ``sample_subjects(n, seed, split)`` function
    and whose poses are unlimited (id 0 canonical, ids ``1..n`` sampled from the subject's
    ``pose_seed``)."""

    def subjects(self, split: str, n: int | None, seed: int) -> list[Subject]:
        if n is None:
            raise ConfigError.about(f"splits.{split}.subjects", None, f"the {self.name} source needs a subject count",
                                    f"`splits.{split}.subjects=N`")
        return [Subject(s.subject_id, self._info(s)) for s in self._sample(n, seed, split)]

    @abstractmethod
    def _sample(self, n: int, seed: int, split: str) -> list[Any]:
        """``n`` subjects of ``split`` drawn from ``seed``, in the source's own form."""

    @abstractmethod
    def _info(self, subject: Any) -> dict[str, Any]:
        """A subject's JSON-ready record (the manifest's ``subjects[i].info``)."""

    def pose_pool(self, subject: Subject, split: str, n: int | None) -> list[int]:
        if n is None:
            raise ConfigError.about(f"splits.{split}.poses", None, f"the {self.name} source has unlimited poses; give "
                                    "a pose count", f"`splits.{split}.poses=N`")
        return list(range(1, n + 1))

    def canonical_pose(self, subject: Subject) -> int | None:
        return 0


class HumanSource(_SeededSubjects):
    """anny humans (:mod:`cerberus_core.bodies.human`); loads anny in :meth:`prepare` or on first posing.

    Subject record: ``{"phenotype": {...}, "split": ..., "pose_seed": int}``.
    """

    name = "human"
    packages = {"anny": "cerberus-core[human]"}
    photo_subject = "a clothed or coloured person"

    def __init__(self, device: str = "cpu") -> None:
        self._human = human
        self.part_names = list(human.PART_NAMES)
        self._device = device
        self._model: human.HumanBodySource | None = None  # a cache: the loaded anny model

    @classmethod
    def from_options(cls, options: Any, *, device: str = "cpu") -> HumanSource:
        return cls(device=device)  # posing on the generation's device (no effect on the bodies)

    def _sample(self, n: int, seed: int, split: str) -> list[Any]:
        return self._human.sample_subjects(n, seed, split)

    def _info(self, subject: Any) -> dict[str, Any]:
        return {"phenotype": dict(subject.phenotype), "split": subject.split, "pose_seed": int(subject.pose_seed)}

    def motion_pairs(self, subject: Subject, split: str, n: int | None) -> list[tuple[int, int]]:
        """Motion clips ``0..n-1``: pose ids ``(10^9 + 2c, 10^9 + 2c + 1)``
        (:mod:`cerberus_core.bodies.human_motion`)."""
        if n is None:
            raise ConfigError(f"splits.{split}.pairs: the human source has unlimited motion pairs; give a pair count", key=f"splits.{split}.pairs")
        return [(motion_pose_id(c, 0), motion_pose_id(c, 1)) for c in range(n)]

    def heldout_poses(self, subject: Subject, split: str, n: int | None) -> list[int]:
        """Held-out family poses ``0..n-1``: pose ids ``2 * 10^9 + k``, the families in turn
        (:mod:`cerberus_core.bodies.human_heldout`)."""
        if n is None:
            raise ConfigError.about(f"splits.{split}.poses", None, "the human source has unlimited held-out poses; "
                                    "give a pose count", f"`splits.{split}.poses=N`")
        return [heldout_pose_id(k) for k in range(n)]

    def bodies(self, subject: Subject, pose_ids: Sequence[int]) -> list[PosedBody]:
        phenotype, split, pose_seed = subject.need(self.name, "phenotype", "split", "pose_seed")
        person = self._human.HumanSubject(subject.name, dict(phenotype), str(split), int(pose_seed))
        return self._loaded().posed_bodies(person, list(pose_ids))

    def prepare(self) -> None:
        """Load anny (building its model cache on a machine's first use: announced, with its progress)."""
        self._loaded()

    def _loaded(self) -> human.HumanBodySource:
        if self._model is None:
            self._model = self._human.HumanBodySource(device=self._device)
        return self._model

    def describe(self) -> dict[str, Any]:
        import importlib.metadata as md

        try:
            version = md.version("anny")
        except md.PackageNotFoundError:  # pragma: no cover
            version = "?"
        return {"anny": version}


class PrimitiveSource(_SeededSubjects):
    """Capsule figures (:mod:`cerberus_core.bodies.primitives`).

    Subject record: ``{"proportions": {...}, "pose_seed": int}``.
    """

    name = "primitives"
    photo_subject = "a painted or textured figure"

    def __init__(self) -> None:
        self._prim = primitives
        self._model = primitives.PrimitiveBodySource()
        self.part_names = list(primitives.PART_NAMES)

    def _sample(self, n: int, seed: int, split: str) -> list[Any]:
        return self._prim.sample_subjects(n, seed, split)

    def _info(self, subject: Any) -> dict[str, Any]:
        return {"proportions": dict(subject.proportions), "pose_seed": int(subject.pose_seed)}

    def bodies(self, subject: Subject, pose_ids: Sequence[int]) -> list[PosedBody]:
        proportions, pose_seed = subject.need(self.name, "proportions", "pose_seed")
        figure = self._prim.PrimitiveSubject(subject.name, dict(proportions), int(pose_seed))
        return self._model.posed_bodies(figure, list(pose_ids))


class AnimalSource(BodySource):
    """Procedural quadrupeds (:mod:`cerberus_core.bodies.animal`): the same species in every split,
    with disjoint poses (the paper's protocol: 47 training and 3 test poses per species).

    Subject record: ``{"archetype": ..., "params": {...}, "pose_seed": int}``. Pose ids: training
    pose ``k`` has id ``k``; test pose ``k`` has id :attr:`TEST_POSE_BASE` ``+ k``. Poses come from
    :func:`~cerberus_core.bodies.animal.animal_pose_splits` with the subject's ``pose_seed`` (the
    dataset's seed); their lists are prefix-stable, so pose ``k`` never depends on how many are asked.
    """

    name = "animal"
    photo_subject = "a furred, patterned or coloured animal"
    shared_subjects = True
    packages = {"scipy": "cerberus-core[animal]", "pymeshlab": "cerberus-core[animal]"}
    TEST_POSE_BASE = 1000

    def __init__(self) -> None:
        self._animal = animal
        self.part_names = list(animal.ANIMAL_PART_NAMES)

    def subjects(self, split: str, n: int | None, seed: int) -> list[Subject]:
        n = self._animal.N_SPECIES if n is None else n
        return [Subject(sp.name, {"archetype": sp.archetype, "params": dict(sp.params), "pose_seed": int(seed)})
                for sp in self._animal.sample_species(n, seed)]

    def pose_pool(self, subject: Subject, split: str, n: int | None) -> list[int]:
        if n is None:
            n = self._animal.N_TRAIN_POSES if split == "train" else self._animal.N_TEST_POSES
        base = 0 if split == "train" else self.TEST_POSE_BASE
        if split == "train" and n > self.TEST_POSE_BASE:
            raise ConfigError.about(f"splits.{split}.poses", n, f"at most {self.TEST_POSE_BASE} training poses per "
                                    "species")
        return [base + k for k in range(n)]

    def bodies(self, subject: Subject, pose_ids: Sequence[int]) -> list[PosedBody]:
        archetype, params, seed = subject.need(self.name, "archetype", "params", "pose_seed")
        species = self._animal.AnimalSpecies(subject.name, dict(params), str(archetype))
        ids = [int(p) for p in pose_ids]
        test = [p - self.TEST_POSE_BASE for p in ids if p >= self.TEST_POSE_BASE]
        train = [p for p in ids if p < self.TEST_POSE_BASE]
        train_poses, test_poses = self._animal.animal_pose_splits(
            species, max(train, default=-1) + 1, max(test, default=-1) + 1, seed=int(seed))
        return [self._animal.build_animal(
            species, test_poses[p - self.TEST_POSE_BASE] if p >= self.TEST_POSE_BASE else train_poses[p], p)
            for p in ids]

    def describe(self) -> dict[str, Any]:
        return {"target_faces": self._animal.DEFAULT_TARGET_FACES}
