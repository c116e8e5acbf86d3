"""What a dataset contains: generation configs, presets, and the deterministic shard plan.

Two layouts, following the paper's two protocols (section 5):

* ``pairs`` (Human): each training example is a *pair of poses* of one subject, both seen from the
  same two viewpoints whose azimuths are drawn uniformly in [0, 360) for that pair. A pair is stored
  as 4 images in the order ``(a0, a1, b0, b1)`` and one quadruplet. Its two poses are independent
  draws or two nearby frames of one motion (:attr:`SplitConfig.pose_pairs`).
* ``grid`` (Animal, and every test split): each pose of a subject is seen from ``views`` azimuths
  ``offset + k * 360 / views``. With ``azimuths="shared"`` one random offset per subject serves all
  its poses (so two poses share their viewpoints, as quadruplets need); with ``"per_pose"`` each pose
  draws its own offset. Training grids form quadruplets ``(a,i), (a,j), (b,i), (b,j)`` from pose
  pairs ``a < b`` and view pairs ``i < j``, ``quadruplets_per_pose * poses`` of them per subject
  (sampled without replacement; the paper's 38,540 animal quadruplets are 20 per pose).

With ``canonical=True`` a grid also renders each subject's canonical pose from azimuths
``0, 360/views, ...`` (flagged ``canonical``; the Hard Human test takes its parts from these). A grid
with ``pose_set="heldout"`` shows the source's held-out poses (:attr:`SplitConfig.pose_set`) instead of
its pose pool.

The plan is a pure function of the config and the body source, so any shard can be (re)built alone:
that is what makes generation resumable and deterministic.
"""
from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from cerberus_core.bodies.body import BodySource, Subject, source_class, source_contract
from cerberus_core.config import build, flatten, load_raw
from cerberus_core.datasets.format import VIEW_DTYPE
from cerberus_core.datasets.manifest import Manifest, SubjectRecord, jsonable
from cerberus_core.datasets.scene import SceneSetup, evenly_spaced
from cerberus_core.datasets.settings import GenerationConfig, SplitConfig
from cerberus_core.errors import BodyError, CerberusError, ConfigError
from cerberus_core.fields import check_kind
from cerberus_core.plumbing.names import did_you_mean

# ------------------------------------------------------------------------------------ presets
SET_EXAMPLE = "splits.train.pairs=2000"
"""The override example that error messages show."""


def load_generation_config(dataset: str, size: str | None = None, overrides: Iterable[str] = ()) -> GenerationConfig:
    """The :class:`GenerationConfig` of a size preset of a body source, plus ``overrides`` (YAML values).

    Args:
        dataset: the body source's registered name (``cerberus.bodies`` entry points).
        size: its size preset (:meth:`BodySource.sizes`; default its :attr:`BodySource.default_size`).
        overrides: ``KEY=VALUE`` strings over the config's keys: ``seed``, ``image_size``,
            ``renderer``, ``shard_images``, ``scene.<field>`` and ``splits.<split>.<field>``.

    Raises:
        ConfigError: an unknown size, or a bad key or value (named, with what is allowed).
        UnknownPluginError: no body source of that name is installed (with the closest name).
    """
    cls = source_class(dataset)
    size = cls.default_size if size is None else size
    known = cls.sizes()
    if size not in known:
        raise ConfigError.about("size", size, f"unknown size preset for dataset {dataset!r}"
                                f"{did_you_mean(size, known)}; choose one of {', '.join(known)}")
    raw = load_raw(cls.presets, preset=f"{dataset}_{size}", overrides=overrides, example=SET_EXAMPLE)
    for key, why in (("dataset", "`dataset`"), ("preset", "`size`"), ("source", "the body source")):
        if key in raw:
            raise ConfigError(f"{key}: set by {why}, not by a preset file or `overrides`", key=key)
    return build(GenerationConfig, {**raw, "dataset": dataset, "preset": size})


def preset_config(dataset: str, size: str, **overrides: Any) -> GenerationConfig:
    """The :class:`GenerationConfig` of a bundled preset, with ``overrides`` (Python values for
    ``seed``, ``image_size``, ``renderer``, ``scene``, ``shard_images``, ``splits``) applied."""
    return replace(load_generation_config(dataset, size), **overrides)


#: A config key as :class:`GenerationRequest` takes it: names of letters, digits and ``_`` joined by dots.
_CONFIG_KEY = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(?:\.[A-Za-z_][A-Za-z0-9_]*)*")


@dataclass(frozen=True)
class GenerationRequest:
    """A dataset as it is asked for: a body source, a size preset, the config keys set over the preset and
    the source's options. :meth:`Dataset.generate <cerberus_core.datasets.dataset.Dataset.generate>` takes one
    (``cerberus data generate`` makes one from its flags); :meth:`Dataset.request
    <cerberus_core.datasets.dataset.Dataset.request>` gives the one that resumes a dataset, which ``cerberus data``
    says as a command.

    Attributes:
        dataset: the body source's name.
        size: the size preset (``None``: the source's :attr:`~BodySource.default_size`).
        overrides: flat config key (``seed``, ``splits.train.pairs``) → value, set over the preset.
        source_options: the source's options (checked by its ``Options``).
    """

    dataset: str
    size: str | None = None
    overrides: Mapping[str, Any] = field(default_factory=dict)
    source_options: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        """Each field checked when the request is made (issue 39: ``overrides`` as a list was an AttributeError,
        a key ``"splits.train.pairs=2 #"`` was accepted): :class:`InputTypeError` or :class:`ConfigError`
        naming the field."""
        check_kind("dataset", self.dataset, str, "a body source's name (a str)")
        if not self.dataset.strip():
            raise ConfigError.about("dataset", self.dataset, "is empty; name a body source, e.g. 'human'")
        if self.size is not None:
            check_kind("size", self.size, str, "a size preset's name (a str) or None")
        check_kind("overrides", self.overrides, Mapping, "a mapping of config keys to values, e.g. {'seed': 3}")
        check_kind("source_options", self.source_options, Mapping, "a mapping of the source's options")
        for where, mapping in (("overrides", self.overrides), ("source_options", self.source_options)):
            for key in mapping:
                if not isinstance(key, str) or not _CONFIG_KEY.fullmatch(key):
                    raise ConfigError.about(where, key, "is not a config key (names of letters, digits "
                                            "and _ joined by dots); give the value as the key's value, e.g. "
                                            "{'splits.train.pairs': 2}")

    def config(self) -> GenerationConfig:
        """The config asked for (:func:`load_generation_config`)."""
        return load_generation_config(self.dataset, self.size,
                                      [f"{k}={json.dumps(v, default=str)}" for k, v in self.overrides.items()])

    @classmethod
    def of(cls, manifest: Manifest) -> GenerationRequest:
        """The request that rebuilds exactly the config ``manifest`` stores (so a generation resumes it): every
        stored key whose value differs from the size preset's (every key, if this version lacks the preset)."""
        dataset, size = manifest.dataset, str(manifest.preset)
        try:
            preset = flatten(json.loads(json.dumps(load_generation_config(dataset, size).to_dict())))
        except CerberusError:  # a preset (or a source) this version no longer has: every stored key is given
            preset = {}
        stored = flatten({k: v for k, v in jsonable(manifest.config.to_dict()).items()
                          if k not in ("dataset", "preset", "source")})
        overrides = {k: v for k, v in stored.items() if not (k in preset and preset[k] == v)}
        return cls(dataset, size, overrides, dict(manifest.source.options))


# ------------------------------------------------------------------------------------ plan
@dataclass
class ShardPlan:
    """One shard to build.

    Attributes:
        split, index: where it goes.
        meshes: ``M`` (subject index, pose id) bodies to build, in order.
        views: ``(N,)`` :data:`VIEW_DTYPE` records; ``views["mesh"]`` indexes :attr:`meshes`.
        quads: ``(Q, 4)`` int32 image indices ``(a0, a1, b0, b1)``.
    """

    split: str
    index: int
    meshes: list[tuple[int, int]]
    views: np.ndarray
    quads: np.ndarray

    @property
    def subjects(self) -> list[int]:
        return sorted({s for s, _ in self.meshes})


@dataclass
class _Unit:
    """A piece of work that is never split across shards (its quadruplets stay inside it)."""

    meshes: list[tuple[int, int]]
    images: list[tuple[int, float, int, bool]]  # (mesh index in unit, azimuth, view, canonical)
    quads: list[tuple[int, int, int, int]]


@dataclass
class DatasetPlan:
    """The whole dataset: the subject table, and the shards of every split."""

    subjects: list[SubjectRecord]
    shards: dict[str, list[ShardPlan]]

    def totals(self, split: str) -> dict[str, int]:
        sh = self.shards[split]
        return {"shards": len(sh), "images": sum(len(s.views) for s in sh),
                "quadruplets": sum(len(s.quads) for s in sh), "meshes": sum(len(s.meshes) for s in sh)}


def _code(text: str) -> int:
    return int.from_bytes(hashlib.sha256(text.encode()).digest()[:4], "little")


def _spread(total: int, n: int) -> list[int]:
    """``total`` split into ``n`` near-equal integers (the first ones get the remainder)."""
    return [total // n + (1 if i < total % n else 0) for i in range(n)]


def _independent_pairs(who: Subject, n_pairs: int | None, source: BodySource, split: str,
                       rng: np.random.Generator) -> list[tuple[int, int]]:
    """``pose_pairs: independent``: consecutive ids of the source's pose pool, ``(pool[2k], pool[2k+1])``;
    a fixed pose set smaller than needed gives distinct pairs drawn at random (``n_pairs=None``: one
    pair per pose)."""
    if n_pairs is None:
        pool = source.pose_pool(who, split, None)
        n_pairs = len(pool)
    else:
        pool = source.pose_pool(who, split, 2 * n_pairs)
    if n_pairs == 0:
        return []
    if len(pool) < 2:
        raise BodyError(f"subject {who.name!r} has {len(pool)} pose(s) for split {split!r}; a pose pair needs 2: give "
                        "it a second pose, or move it to a grid split")
    if len(pool) >= 2 * n_pairs:
        return [(pool[2 * k], pool[2 * k + 1]) for k in range(n_pairs)]
    a = rng.integers(0, len(pool), n_pairs)
    b = (a + rng.integers(1, len(pool), n_pairs)) % len(pool)
    return [(pool[i], pool[j]) for i, j in zip(a, b, strict=True)]


def _pairs_units(subject: int, who: Subject, cfg: SplitConfig, n_pairs: int | None, source: BodySource,
                 split: str, rng: np.random.Generator, chunk: int) -> list[_Unit]:
    if cfg.pose_pairs == "motion":
        pairs = source.motion_pairs(who, split, n_pairs)
    else:
        pairs = _independent_pairs(who, n_pairs, source, split, rng)
    n_pairs = len(pairs)
    if n_pairs == 0:
        return []
    azimuths = rng.uniform(0.0, 360.0, (n_pairs, 2))
    units = []
    for start in range(0, n_pairs, chunk):
        meshes: list[tuple[int, int]] = []
        index: dict[int, int] = {}
        images, quads = [], []
        for (pa, pb), (az0, az1) in zip(pairs[start:start + chunk], azimuths[start:start + chunk], strict=True):
            for p in (pa, pb):
                if p not in index:
                    index[p] = len(meshes)
                    meshes.append((subject, p))
            base = len(images)
            images += [(index[pa], az0, 0, False), (index[pa], az1, 1, False),
                       (index[pb], az0, 0, False), (index[pb], az1, 1, False)]
            quads.append((base, base + 1, base + 2, base + 3))
        units.append(_Unit(meshes, images, quads))
    return units


def _grid_units(subject: int, who: Subject, cfg: SplitConfig, source: BodySource, split: str,
                rng: np.random.Generator, shard_images: int) -> list[_Unit]:
    if cfg.pose_set == "heldout":
        pool = list(source.heldout_poses(who, split, cfg.poses))
    else:
        pool = list(source.pose_pool(who, split, cfg.poses))
    canonical = source.canonical_pose(who) if cfg.canonical else None
    if canonical is not None and canonical in pool:
        pool.remove(canonical)
    v = cfg.views
    shared = evenly_spaced(rng.uniform(0.0, 360.0), v)
    offsets = rng.uniform(0.0, 360.0, len(pool))
    poses = [(p, shared if cfg.azimuths == "shared" else evenly_spaced(o, v), False)
             for p, o in zip(pool, offsets, strict=True)]
    quads: list[tuple[int, int, int, int]] = []
    if cfg.quadruplets_per_pose and len(pool) >= 2:
        pose_pairs = [(a, b) for a in range(len(pool)) for b in range(a + 1, len(pool))]
        view_pairs = [(i, j) for i in range(v) for j in range(i + 1, v)]
        total = len(pose_pairs) * len(view_pairs)
        want = min(total, cfg.quadruplets_per_pose * len(pool))
        for c in np.sort(rng.choice(total, want, replace=False)):
            (a, b), (i, j) = pose_pairs[c // len(view_pairs)], view_pairs[c % len(view_pairs)]
            quads.append((a * v + i, a * v + j, b * v + i, b * v + j))
    if canonical is not None:
        poses.append((canonical, evenly_spaced(0.0, v), True))

    def unit(chunk: list) -> _Unit:
        meshes = [(subject, p) for p, _, _ in chunk]
        images = [(m, float(az[k]), k, can) for m, (_, az, can) in enumerate(chunk) for k in range(v)]
        return _Unit(meshes, images, [])

    if quads:  # quadruplets span all poses: the subject stays in one unit
        u = unit(poses)
        u.quads = quads
        return [u]
    per = max(1, shard_images // v)
    return [unit(poses[i:i + per]) for i in range(0, len(poses), per)]


def _pack(units: list[_Unit], split: str, cfg: SplitConfig, scene: SceneSetup, shard_images: int) -> list[ShardPlan]:
    shards: list[ShardPlan] = []
    current: list[_Unit] = []

    def flush() -> None:
        if not current:
            return
        meshes, views, quads = [], [], []
        for u in current:
            m0, i0 = len(meshes), len(views)
            meshes += u.meshes
            views += [(m0 + m, az, view, can) for m, az, view, can in u.images]
            quads += [tuple(i0 + q for q in quad) for quad in u.quads]
        rec = np.zeros(len(views), dtype=VIEW_DTYPE)
        rec["mesh"] = [m for m, _, _, _ in views]
        rec["subject"] = [meshes[m][0] for m, _, _, _ in views]
        rec["pose"] = [meshes[m][1] for m, _, _, _ in views]
        rec["view"] = [v for _, _, v, _ in views]
        rec["canonical"] = [c for _, _, _, c in views]
        rec["azimuth"] = [a for _, a, _, _ in views]
        rec["elevation"], rec["distance"], rec["fov_y"] = scene.elevation, scene.distance, scene.fov_y
        q = np.asarray(quads, dtype=np.int32).reshape(-1, 4)
        shards.append(ShardPlan(split, len(shards), meshes, rec, q))
        current.clear()

    count = 0
    for u in units:
        if current and count + len(u.images) > shard_images:
            flush()
            count = 0
        current.append(u)
        count += len(u.images)
    flush()
    return shards


def make_plan(config: GenerationConfig, source: BodySource) -> DatasetPlan:
    """The deterministic plan of a dataset: subject table and shards of every split.

    A split for which the source has no subject (a folder whose subjects are all test subjects) is
    planned empty, with no shards: a test-only dataset is for evaluation (readers refuse to read an
    empty split, naming it).

    Raises:
        ConfigError: if splits share a subject while the source promises disjoint subjects, no split
            has a subject, or a split with subjects would hold no image.
        BodyError: a subject of a ``pairs`` split with fewer than 2 poses.
    """
    table: list[SubjectRecord] = []
    index: dict[str, int] = {}
    shards: dict[str, list[ShardPlan]] = {}
    for split, cfg in config.splits.items():
        with source_contract(source, f"subjects({split!r}, ...)"):
            infos: list[Subject] = source.subjects(split, cfg.subjects, config.seed)
        if not infos:
            shards[split] = []
            continue
        for s in infos:
            if s.name in index:
                entry = table[index[s.name]]
                if not source.shared_subjects:
                    raise ConfigError(f"subject {s.name!r} is in splits {list(entry.splits)} and {split!r}; "
                                      "splits must hold disjoint subjects: give each split its own", key=f"splits.{split}.subjects")
                table[index[s.name]] = entry.in_split(split)
            else:
                index[s.name] = len(table)
                with source_contract(source, f"the info of subject {s.name!r} (it must be what JSON holds)"):
                    canonical = source.canonical_pose(s)
                    info = jsonable(s.info)
                    json.dumps(info, allow_nan=False)
                table.append(SubjectRecord(s.name, info, (split,), None if canonical is None else int(canonical)))
        units: list[_Unit] = []
        pair_counts = _spread(cfg.pairs, len(infos)) if (cfg.layout == "pairs" and cfg.pairs is not None) else None
        chunk = max(1, config.shard_images // 4)
        for pos, s in enumerate(infos):
            rng = np.random.default_rng([config.seed, _code(split), pos, _code(s.name)])
            if cfg.layout == "pairs":
                units += _pairs_units(index[s.name], s, cfg, None if pair_counts is None else pair_counts[pos],
                                      source, split, rng, chunk)
            else:
                units += _grid_units(index[s.name], s, cfg, source, split, rng, config.shard_images)
        shards[split] = _pack(units, split, cfg, config.scene, config.shard_images)
        if not shards[split]:
            raise ConfigError(f"split {split!r} would be empty (no image); raise its counts: `splits.{split}.pairs`, "
                              f"`splits.{split}.poses` or `splits.{split}.views`", key=f"splits.{split}")
    if not table:
        raise ConfigError(f"no split has a subject ({', '.join(config.splits)}); adjust the preset's `subjects` or "
                          "the body source's split options", key="splits")
    return DatasetPlan(table, shards)
