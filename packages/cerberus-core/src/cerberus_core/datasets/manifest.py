"""A dataset's ``manifest.json``, typed both ways (see docs/data_format.md).

The manifest is a tree of frozen records, each with ``from_json`` (the JSON object as stored) and
``to_json`` (the object to store):

* :class:`Manifest`: format and version, the dataset's name and size preset, the generation config
  (as stored, compared whole on resume), the scene (:class:`~cerberus_core.datasets.scene.SceneSetup`),
  image size, part names, subjects, body source, splits, whether generation finished;
* :class:`SubjectRecord`: one subject (``name``, the source's ``info``, its splits, canonical pose);
* :class:`SourceRecord`: the body source a reader rebuilds bodies with (name and options);
* :class:`SplitRecord`: a split's layout, planned counts and the shards written so far;
* :class:`ShardRecord`: one written shard (counts, the subjects it holds, its files);
* :class:`FileRecord`: one shard file (relative path, bytes, sha256, array shape and dtype).

The generator builds these records and writes them with :meth:`Manifest.write` (atomically, after
each shard); every reader opens a dataset with :meth:`Manifest.read`. This module is the only place
that reads or writes the manifest's JSON keys. Manifests written by earlier versions of format 1
still read: keys they lack take the defaults below (``tests/core/datasets/old_manifest.json``).
"""
from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from cerberus_core.bodies.body import BodySource, Subject, no_subjects_hint, source_class
from cerberus_core.datasets.scene import SceneSetup, read_scene
from cerberus_core.datasets.settings import GenerationConfig
from cerberus_core.errors import CerberusError, ConfigError, DatasetError, IncompleteDatasetError, ManifestFormatError
from cerberus_core.plumbing import jsontext
from cerberus_core.plumbing.atomic import atomic_write

FORMAT_NAME = "cerberus-dataset"
FORMAT_VERSION = 1
MANIFEST = "manifest.json"


def canonical_json(obj: Any) -> str:
    """Deterministic JSON (sorted keys, 1-space indent) used for the manifest and config hashes."""
    return json.dumps(obj, sort_keys=True, indent=1, ensure_ascii=True)


def jsonable(obj: Any) -> Any:
    """``obj`` with NumPy scalars and arrays as Python numbers and lists, tuples as lists and keys as
    strings: what :func:`json.dumps` takes, and what reading the JSON back gives."""
    if isinstance(obj, Mapping):
        return {str(k): jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [jsonable(v) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    if isinstance(obj, np.ndarray):
        return obj.tolist()
    return obj


def _need(record: Any, key: str, kind: type | tuple[type, ...], where: str) -> Any:
    if not isinstance(record, Mapping) or key not in record:
        raise ManifestFormatError(f"{where} lacks {key!r}")
    value = record[key]
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise ManifestFormatError(f"{where}.{key} is {value!r}, not {getattr(kind, '__name__', kind)}")
    return value


MAX_COUNT = 1 << 40
"""The largest count a manifest may state (images, bytes, array sizes): more than any disk holds."""


def _count(record: Mapping[str, Any], key: str, where: str, default: int | None = None) -> int:
    """``record[key]`` as a count: an integer in [0, :data:`MAX_COUNT`] (``default`` when absent, if given)."""
    if default is not None and key not in record:
        return default
    value = _need(record, key, int, where)
    if not 0 <= value <= MAX_COUNT:
        raise ManifestFormatError(f"{where}.{key} is {value!r}, not a count in [0, {MAX_COUNT}]")
    return value


def _counts(values: Any, where: str) -> tuple[int, ...]:
    """A list of counts (an array shape, subject indices) as a tuple."""
    if not isinstance(values, list):
        raise ManifestFormatError(f"{where} is {values!r}, not a list of counts")
    for i, v in enumerate(values):
        if isinstance(v, bool) or not isinstance(v, int) or not 0 <= v <= MAX_COUNT:
            raise ManifestFormatError(f"{where}[{i}] is {v!r}, not a count in [0, {MAX_COUNT}]")
    return tuple(values)


def _strings(values: Any, where: str) -> tuple[str, ...]:
    """A list of strings (part names, split names) as a tuple."""
    if not isinstance(values, list) or not all(isinstance(v, str) for v in values):
        raise ManifestFormatError(f"{where} is {values!r}, not a list of strings")
    return tuple(values)


def _optional(record: Mapping[str, Any], key: str, kind: type, where: str) -> Any:
    """``record[key]``, which may be absent or null."""
    return None if record.get(key) is None else _need(record, key, kind, where)


def _mapping(record: Any, where: str) -> Mapping[str, Any]:
    if not isinstance(record, Mapping):
        raise ManifestFormatError(f"{where} is {type(record).__name__}, not an object")
    return record


@dataclass(frozen=True)
class FileRecord:
    """One file of a shard.

    Attributes:
        path: relative to the dataset folder, POSIX form.
        bytes: its size.
        sha256: hex digest of its content.
        shape: the array's shape (``.npy`` files), else ``None``.
        dtype: the array's ``dtype.str`` (``.npy`` files), else ``None``.
    """

    path: str
    bytes: int
    sha256: str
    shape: tuple[int, ...] | None = None
    dtype: str | None = None

    @classmethod
    def from_json(cls, record: Any, where: str = "file") -> FileRecord:
        shape = _mapping(record, where).get("shape")
        return cls(_need(record, "path", str, where), _count(record, "bytes", where),
                   _need(record, "sha256", str, where), None if shape is None else _counts(shape, f"{where}.shape"),
                   _optional(record, "dtype", str, where))

    def to_json(self) -> dict[str, Any]:
        out: dict[str, Any] = {"path": self.path, "bytes": self.bytes, "sha256": self.sha256}
        if self.shape is not None:
            out["shape"], out["dtype"] = list(self.shape), self.dtype
        return out


@dataclass(frozen=True)
class ShardRecord:
    """One written shard of a split.

    Attributes:
        index: its position in the split (``shard-NNNNN``).
        name: ``shard-NNNNN``.
        images, quadruplets, meshes: what it holds.
        files: ``{role: FileRecord}`` (roles ``images``, ``views``, ``quads``, and ``vertices``, ``meshes`` when meshes are stored).
        subjects: indices (into :attr:`Manifest.subjects`) of the subjects whose bodies it holds.
    """

    index: int
    name: str
    images: int
    quadruplets: int
    meshes: int
    files: Mapping[str, FileRecord] = field(default_factory=dict)
    subjects: tuple[int, ...] = ()

    @classmethod
    def from_json(cls, record: Any, where: str = "shard") -> ShardRecord:
        index = _count(_mapping(record, where), "index", where)
        where = f"{where} {index}"
        files = _mapping(record.get("files", {}), f"{where}.files")
        return cls(index, _need(record, "name", str, where), _count(record, "images", where),
                   _count(record, "quadruplets", where, 0), _count(record, "meshes", where, 0),
                   {role: FileRecord.from_json(rec, f"{where}.files.{role}") for role, rec in files.items()},
                   _counts(record.get("subjects", []), f"{where}.subjects"))

    def to_json(self) -> dict[str, Any]:
        return {"index": self.index, "name": self.name, "images": self.images, "quadruplets": self.quadruplets,
                "meshes": self.meshes, "files": {role: rec.to_json() for role, rec in self.files.items()},
                "subjects": list(self.subjects)}


@dataclass(frozen=True)
class SplitRecord:
    """One split: its layout, what the plan promised and the shards written so far.

    Attributes:
        layout: ``pairs`` (training quadruplets) or ``grid`` (views of each pose).
        meshes: whether its shards store the ground-truth meshes.
        planned_shards, planned_images, planned_quadruplets, planned_meshes: the plan's totals.
        shards: the shards written, by index.
    """

    layout: str
    meshes: bool
    planned_shards: int
    planned_images: int = 0
    planned_quadruplets: int = 0
    planned_meshes: int = 0
    shards: tuple[ShardRecord, ...] = ()

    @property
    def complete(self) -> bool:
        """Every planned shard is written."""
        return len(self.shards) == self.planned_shards

    @property
    def content_id(self) -> str:
        """The identity of what the split holds, read from the manifest alone (no file is hashed): the first 16
        hex digits of the sha256 of its shards' files' sha256s (by shard index and role). The same images, views
        and meshes give the same id whatever the dataset's folder, name or preset (the ``small`` and ``large``
        human sets share their test split); another generation of them, another. An evaluation records it
        (``results.json``'s ``data_id``) and ``cerberus compare`` pairs only evaluations of the same one."""
        files = [[shard.index, role, rec.sha256] for shard in self.shards for role, rec in sorted(shard.files.items())]
        return hashlib.sha256(canonical_json(files).encode()).hexdigest()[:16]

    def totals(self) -> dict[str, int]:
        """Images, quadruplets and meshes in the shards written so far."""
        return {"images": sum(s.images for s in self.shards), "quadruplets": sum(s.quadruplets for s in self.shards),
                "meshes": sum(s.meshes for s in self.shards)}

    def with_shard(self, shard: ShardRecord) -> SplitRecord:
        """This split with ``shard`` written (replacing a shard of the same index)."""
        kept = [s for s in self.shards if s.index != shard.index]
        return replace(self, shards=tuple(sorted([*kept, shard], key=lambda s: s.index)))

    @classmethod
    def from_json(cls, record: Any, where: str = "split") -> SplitRecord:
        shards = record.get("shards", []) if isinstance(record, Mapping) else None
        if not isinstance(shards, list):
            raise ManifestFormatError(f"{where}.shards is not a list")
        if _need(record, "layout", str, where) not in ("pairs", "grid"):
            raise ManifestFormatError(f"{where}.layout is {record['layout']!r}, not 'pairs' or 'grid'")
        return cls(_need(record, "layout", str, where), bool(_need(record, "meshes", bool, where) if "meshes" in record
                                                            else False),
                   _count(record, "planned_shards", where), _count(record, "planned_images", where, 0),
                   _count(record, "planned_quadruplets", where, 0), _count(record, "planned_meshes", where, 0),
                   tuple(ShardRecord.from_json(s, f"{where}.shards") for s in shards))

    def to_json(self) -> dict[str, Any]:
        return {"layout": self.layout, "meshes": self.meshes, "planned_shards": self.planned_shards,
                "planned_images": self.planned_images, "planned_quadruplets": self.planned_quadruplets,
                "planned_meshes": self.planned_meshes, "shards": [s.to_json() for s in self.shards]}


@dataclass(frozen=True)
class SubjectRecord:
    """One subject of the dataset.

    Attributes:
        name: unique within the dataset.
        info: JSON-ready parameters its body source poses it with.
        splits: the splits it appears in.
        canonical_pose: the pose id of its canonical pose (Hard Human), or ``None``.
    """

    name: str
    info: Mapping[str, Any] = field(default_factory=dict)
    splits: tuple[str, ...] = ()
    canonical_pose: int | None = None

    @property
    def subject(self) -> Subject:
        """The subject as its body source takes it."""
        return Subject(self.name, dict(self.info))

    @property
    def pose_names(self) -> list[str] | None:
        """Names of its poses by pose id, where its source records them (a folder's frame names)."""
        poses = self.info.get("poses")
        return [str(p) for p in poses] if isinstance(poses, list) else None

    def in_split(self, split: str) -> SubjectRecord:
        """This subject, also in ``split``."""
        return self if split in self.splits else replace(self, splits=(*self.splits, split))

    @classmethod
    def from_json(cls, record: Any, where: str = "subject") -> SubjectRecord:
        info = _mapping(record, where).get("info", {})
        canonical = None if record.get("canonical_pose") is None else _count(record, "canonical_pose", where)
        return cls(_need(record, "name", str, where), dict(_mapping(info, f"{where}.info")),
                   _strings(record.get("splits", []), f"{where}.splits"), canonical)

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "info": dict(self.info), "splits": list(self.splits),
                "canonical_pose": self.canonical_pose}


@dataclass(frozen=True)
class SourceRecord:
    """The body source of a dataset: its registered name and the JSON-ready options it was built with
    (a folder's ``root``, ``test_fraction`` or ``test_subjects``, ...)."""

    name: str
    options: Mapping[str, Any] = field(default_factory=dict)

    @classmethod
    def from_json(cls, record: Any, dataset: str) -> SourceRecord:
        if not record:  # manifests before the source record: the dataset's own source, default options
            return cls(dataset)
        options = _mapping(record, "source").get("options") or {}
        return cls(_need(record, "name", str, "source"), dict(_mapping(options, "source.options")))

    def to_json(self) -> dict[str, Any]:
        return {"name": self.name, "options": dict(self.options)}

    def build(self, device: str = "cpu") -> BodySource:
        """The body source again, from its registered name and these options (its ``Options`` check them).

        Raises:
            DatasetError: the source is not installed here or refuses the options (its reason kept).
        """
        try:
            cls = source_class(self.name)
            return cls.from_options(cls.options(self.options), device=device)
        except CerberusError as exc:
            raise DatasetError(f"the dataset's body source {self.name!r} cannot be rebuilt here ({exc})") from exc

    def empty_split_hint(self, subjects: int, split: str, root: Path) -> str:
        """Why ``split`` has no subject, in the source's own terms (:meth:`BodySource.empty_split_hint`; a
        generic hint when the source is not installed here)."""
        try:
            cls = source_class(self.name)
        except CerberusError:
            return no_subjects_hint(split, subjects, root)
        return cls.empty_split_hint(self.options, subjects, split, root)


@dataclass(frozen=True)
class Manifest:
    """A dataset's ``manifest.json``: read one with :meth:`read`, store one with :meth:`write`.

    Attributes:
        dataset: the body source's name: ``human``, ``animal``, ``primitives``, ``folder``.
        preset: the size preset it was generated with.
        config: the resolved generation config, typed (stored in its :meth:`GenerationConfig.to_dict`
            form): a resume compares it whole.
        config_sha256: its hash (:func:`cerberus_core.datasets.format.config_hash`).
        scene: the scene set-up the images were rendered with (checked).
        image_size: images are ``image_size`` pixels square.
        part_names: the ground-truth semantic part names.
        subjects: one record per subject; view records index it.
        source: the body source a reader rebuilds bodies with.
        splits: ``{split: its record}``.
        complete: whether the generation finished.
        generator: the versions that wrote it (``{"cerberus_core": "0.2.0+toolkit"}``).
        root: the dataset folder it was read from or is written to (not stored).
    """

    dataset: str
    preset: str | None
    config: GenerationConfig
    config_sha256: str
    scene: SceneSetup
    image_size: int
    part_names: tuple[str, ...]
    subjects: tuple[SubjectRecord, ...]
    source: SourceRecord
    splits: Mapping[str, SplitRecord]
    complete: bool = False
    generator: Mapping[str, str] = field(default_factory=dict)
    root: Path = field(default=Path("."), compare=False)

    # ---------------------------------------------------------------------------- reading, writing
    @classmethod
    def read(cls, root: str | Path) -> Manifest:
        """Load and check ``root/manifest.json``.

        Raises:
            DatasetError: a missing or unreadable manifest, another format or format version, or a
                manifest without the form of one (naming the first problem).
        """
        root = Path(root)
        path = root / MANIFEST
        if root.exists() and not root.is_dir():
            raise DatasetError(f"{root} is a file, not a dataset folder; pass the folder that holds {MANIFEST}")
        if not root.is_dir():
            raise DatasetError(f"dataset folder {root} does not exist; generate one there first "
                               "(`Dataset.generate`, or `cerberus data generate`)")
        if not path.is_file():
            raise DatasetError(f"{path} not found: {root} is not a Cerberus dataset (generate one there first: "
                               "`Dataset.generate`, or `cerberus data generate`)")
        try:
            record = jsontext.loads(path.read_text())
        except (OSError, UnicodeDecodeError) as exc:
            raise DatasetError(f"{path} cannot be read ({exc}); the dataset is corrupt — regenerate it") from None
        except ValueError as exc:
            raise DatasetError(f"{path} is not valid JSON ({exc}); the dataset is corrupt — regenerate it") from None
        return cls.from_json(record, root)

    @classmethod
    def from_json(cls, record: Any, root: str | Path = ".") -> Manifest:
        """The manifest stored as ``record`` (the parsed JSON) in the folder ``root``.

        Raises:
            DatasetError: another format or format version, or a record without the form of a
                manifest (a required key missing, a value of another type, an invalid scene).
        """
        path = Path(root) / MANIFEST
        if not isinstance(record, Mapping) or record.get("format") != FORMAT_NAME:
            found = record.get("format") if isinstance(record, Mapping) else None
            raise DatasetError(f"{path} is not a {FORMAT_NAME} manifest (format={found!r})")
        version = record.get("format_version")
        if version != FORMAT_VERSION:
            raise DatasetError(f"{path} has format version {version!r}, this cerberus-core reads version "
                               f"{FORMAT_VERSION}; regenerate the dataset with this version (overwriting it) or "
                               "install the cerberus-core release that wrote it")
        try:
            dataset = _need(record, "dataset", str, "manifest")
            config = _config(_mapping(_need(record, "config", Mapping, "manifest"), "config"), path)
            splits = _mapping(_need(record, "splits", Mapping, "manifest"), "splits")
            return cls(
                dataset=dataset, preset=_optional(record, "preset", str, "manifest"), config=config,
                config_sha256=str(record.get("config_sha256", "")), scene=_scene(record.get("scene"), path),
                image_size=_image_size(record),
                part_names=_strings(_need(record, "part_names", list, "manifest"), "manifest.part_names"),
                subjects=tuple(SubjectRecord.from_json(s, f"subjects[{i}]")
                               for i, s in enumerate(_need(record, "subjects", list, "manifest"))),
                source=SourceRecord.from_json(record.get("source"), dataset),
                splits={name: SplitRecord.from_json(rec, f"splits.{name}") for name, rec in splits.items()},
                complete=bool(record.get("complete", False)),
                generator=dict(_mapping(record.get("generator") or {}, "manifest.generator")), root=Path(root))._checked()
        except ManifestFormatError as exc:
            raise DatasetError(f"{path}: {exc}; the dataset is corrupt — regenerate it") from None
        except DatasetError:
            raise
        except (TypeError, ValueError, AttributeError, RecursionError) as exc:  # a field of a form not checked above
            raise DatasetError(f"{path}: a field has the wrong form ({type(exc).__name__}: {exc}); the dataset is "
                               "corrupt — regenerate it") from None

    def _checked(self) -> Manifest:
        """This manifest, after the checks between its records: the splits recorded are the splits its config
        plans, and a shard's subject index is within the subjects."""
        if set(self.splits) != set(self.config.splits):
            raise ManifestFormatError(f"splits records {sorted(self.splits)}, but its config plans {sorted(self.config.splits)}")
        for name, split in self.splits.items():
            indices = [shard.index for shard in split.shards]
            if len(set(indices)) < len(indices) or any(not 0 <= i < split.planned_shards for i in indices):
                raise ManifestFormatError(f"splits.{name}.shards records shards {sorted(indices)}, not distinct shards of the "
                               f"{split.planned_shards} planned")
            for shard in split.shards:
                bad = [i for i in shard.subjects if i >= len(self.subjects)]
                if bad:
                    raise ManifestFormatError(f"splits.{name}.shards {shard.index}.subjects names subject {bad[0]}, but the "
                                   f"manifest has {len(self.subjects)} subjects")
        return self

    def to_json(self) -> dict[str, Any]:
        """The JSON object :meth:`write` stores (:meth:`from_json` reads it back equal)."""
        return {"format": FORMAT_NAME, "format_version": FORMAT_VERSION, "dataset": self.dataset,
                "preset": self.preset, "config": jsonable(self.config.to_dict()), "config_sha256": self.config_sha256,
                "scene": self.scene.to_dict(), "image_size": self.image_size, "part_names": list(self.part_names),
                "subjects": [s.to_json() for s in self.subjects], "source": self.source.to_json(),
                "splits": {name: rec.to_json() for name, rec in self.splits.items()}, "complete": self.complete,
                "generator": dict(self.generator)}

    def write(self) -> None:
        """Store it as :attr:`path`, atomically (a reader sees the old manifest or this one)."""
        text = canonical_json(self.to_json()) + "\n"
        atomic_write(self.path, lambda fh: fh.write(text.encode()))

    # ---------------------------------------------------------------------------- changes
    def with_shard(self, split: str, shard: ShardRecord) -> Manifest:
        """This manifest with ``shard`` written into ``split``."""
        return replace(self, splits={**self.splits, split: self.split(split).with_shard(shard)})

    def with_shards(self, shards: Mapping[str, Iterable[ShardRecord]]) -> Manifest:
        """This manifest with each split's shards replaced by ``shards[split]`` (splits not named: none)."""
        return replace(self, splits={name: replace(rec, shards=tuple(sorted(shards.get(name, ()),
                                                                           key=lambda s: s.index)))
                                     for name, rec in self.splits.items()})

    def finished(self) -> Manifest:
        """This manifest, marked complete."""
        return replace(self, complete=True)

    # ---------------------------------------------------------------------------- reading parts
    def __repr__(self) -> str:
        return f"Manifest({str(self.root)!r}: {self.dataset}/{self.preset}, splits {sorted(self.splits)})"

    @property
    def path(self) -> Path:
        """The ``manifest.json`` file."""
        return self.root / MANIFEST

    @property
    def subject_names(self) -> list[str]:
        return [s.name for s in self.subjects]

    def split(self, name: str) -> SplitRecord:
        """The record of split ``name``.

        Raises:
            DatasetError: no such split, naming the dataset's splits.
        """
        if name not in self.splits:
            raise DatasetError(f"{self.path}: no split {name!r}; this dataset has {sorted(self.splits)}")
        return self.splits[name]

    def incomplete(self, name: str) -> str | None:
        """What is missing from split ``name`` (``"split 'train' is incomplete (1 of 3 shards)"``), ``None``
        when every planned shard is written."""
        info = self.split(name)
        if info.complete:
            return None
        return f"split {name!r} is incomplete ({len(info.shards)} of {info.planned_shards} shards)"

    def readable_split(self, name: str, *, allow_partial: bool = False) -> SplitRecord:
        """The record of split ``name``, which a reader may open: it has subjects and (unless
        ``allow_partial``) every shard.

        Raises:
            DatasetError: no such split, or an empty one (why, in its source's terms).
            IncompleteDatasetError: a split whose generation has not finished.
        """
        info = self.split(name)
        if info.planned_shards == 0:
            raise DatasetError(f"{self.root}: split {name!r} is empty: "
                               f"{self.source.empty_split_hint(len(self.subjects), name, self.root)}")
        if not allow_partial and (problem := self.incomplete(name)):
            raise IncompleteDatasetError(self.root, f"{self.root}: {problem}")
        return info


def _config(record: Mapping[str, Any], path: Path) -> GenerationConfig:
    try:
        return GenerationConfig.from_dict(dict(record))
    except ConfigError as exc:
        raise DatasetError(f"{path}: invalid generation config ({exc}); the manifest is damaged or of a newer "
                           "version: regenerate the dataset with this version") from None


MAX_IMAGE_SIZE = 4096
"""The largest image size a manifest may state (pixels per side)."""


def _image_size(record: Mapping[str, Any]) -> int:
    size = _need(record, "image_size", int, "manifest")
    if not 1 <= size <= MAX_IMAGE_SIZE:
        raise ManifestFormatError(f"manifest.image_size is {size!r}, not a size in [1, {MAX_IMAGE_SIZE}] pixels")
    return size


def _scene(record: Any, path: Path) -> SceneSetup:
    try:
        return read_scene(record)
    except ConfigError as exc:
        raise DatasetError(f"{path}: invalid scene set-up ({exc}); the manifest is damaged: regenerate the "
                           "dataset") from None


__all__ = ["FORMAT_NAME", "FORMAT_VERSION", "MANIFEST", "FileRecord", "IncompleteDatasetError", "Manifest", "ShardRecord", "SourceRecord",
           "SplitRecord", "SubjectRecord", "canonical_json", "jsonable"]
