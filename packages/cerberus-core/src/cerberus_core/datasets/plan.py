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
``0, 360/views, ...`` (flagged ``canonical``; the Hard Human test takes its parts from these).

The plan is a pure function of the config and the body source, so any shard can be (re)built alone:
that is what makes generation resumable and deterministic.
"""
from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Literal

import numpy as np

from cerberus_core.bodies.body import BodySource, Subject, source_class
from cerberus_core.config import build, did_you_mean, flatten, load_raw, omit_defaults
from cerberus_core.datasets.format import VIEW_DTYPE
from cerberus_core.datasets.manifest import Manifest, SubjectRecord, jsonable
from cerberus_core.datasets.scene import SceneSetup, evenly_spaced
from cerberus_core.errors import CerberusError, ConfigError
from cerberus_core.fields import Checked, ranged

LAYOUTS = ("pairs", "grid")
POSE_PAIRS = ("independent", "motion")
"""How the two poses of a ``pairs`` training example relate (:attr:`SplitConfig.pose_pairs`)."""

MAX_SPLIT_IMAGES = 1_000_000
"""Most images a split may plan: 13x the paper's largest (78,000 human training images). The plan is
held in memory: 1,000,000 images (250,000 primitives pairs) plan in 1.6 s with 540 MB peak memory."""

MAX_SUBJECTS = 10_000
"""Most subjects a split may ask for (the paper uses at most 41)."""

MAX_VIEWS = 360
"""Most views per pose on a grid: one per degree of azimuth."""

MAX_QUADRUPLET_POSES = 1_000
"""Most poses per subject when a grid draws quadruplets (its pose pairs are enumerated; the paper: 47)."""

MAX_IMAGE_SIZE = 1024
"""Largest ``image_size`` of a dataset: 16x the paper's 64 px (a shard of 1024 such images is 3 GiB;
the memory a generation needs is checked too, by
:func:`cerberus_core.datasets.generate.validate_generation`)."""


@dataclass(frozen=True)
class SplitConfig:
    """How one split is built.

    Attributes:
        layout: ``"pairs"`` or ``"grid"`` (module docstring).
        subjects: number of subjects (``None``: all the source has for the split).
        pairs: ``pairs`` layout: pose pairs over all subjects (spread evenly); ``None``: as many
            pairs per subject as it has poses (fixed-pose sources such as folders).
        poses: ``grid`` layout: poses per subject (``None``: all the source offers).
        views: ``grid`` layout: views per pose.
        azimuths: ``grid`` layout: ``"shared"`` by all poses of a subject or ``"per_pose"``.
        quadruplets_per_pose: ``grid`` layout: quadruplets per subject = this x poses (0: none).
        canonical: add every subject's canonical pose (``grid`` layout).
        meshes: store ground-truth meshes and part labels (test splits always should; a training
            split may skip them to save space: the manifest then keeps (subject, pose) references
            that the source regenerates).
        pose_pairs: ``pairs`` layout: how the two poses of a pair relate. ``"independent"``: two
            independent poses from the source's pose pool; ``"motion"``: two nearby frames of one
            everyday motion (:meth:`BodySource.motion_pairs`; human only, the human presets'
            choice). Omitted from :meth:`GenerationConfig.to_dict` (so from the manifest and the
            config hash) when ``"independent"``, so configs from before the key hash as they did.
    """

    layout: Literal["pairs", "grid"]
    subjects: int | None = None
    pairs: int | None = 0
    poses: int | None = None
    views: int = 4
    azimuths: Literal["shared", "per_pose"] = "per_pose"
    quadruplets_per_pose: int = 0
    canonical: bool = False
    meshes: bool = True
    pose_pairs: Literal["independent", "motion"] = "independent"

    def __post_init__(self) -> None:
        if self.layout not in LAYOUTS:
            raise ValueError(f"SplitConfig.layout must be one of {LAYOUTS}, got {self.layout!r}")
        if self.pose_pairs not in POSE_PAIRS:
            raise ValueError(f"SplitConfig.pose_pairs must be one of {POSE_PAIRS}, got {self.pose_pairs!r}")
        if self.layout != "pairs" and self.pose_pairs != "independent":
            raise ValueError(f"SplitConfig.pose_pairs={self.pose_pairs!r} needs layout pairs (a grid has no pose "
                             "pairs); drop pose_pairs or set layout: pairs")
        if self.azimuths not in ("shared", "per_pose"):
            raise ValueError(f"SplitConfig.azimuths must be 'shared' or 'per_pose', got {self.azimuths!r}")
        if self.layout == "grid" and self.views < 1:
            raise ValueError("SplitConfig.views must be >= 1")
        if self.layout == "grid" and self.quadruplets_per_pose and self.views < 2:
            raise ValueError("quadruplets need at least 2 views per pose")
        for name in ("subjects", "pairs", "poses", "quadruplets_per_pose"):
            v = getattr(self, name)
            if v is not None and v < 0:
                raise ValueError(f"SplitConfig.{name} must be >= 0, got {v}")
        if self.subjects is not None and self.subjects > MAX_SUBJECTS:
            raise ValueError(f"SplitConfig.subjects {self.subjects}: at most {MAX_SUBJECTS}")
        if self.layout == "grid" and self.views > MAX_VIEWS:
            raise ValueError(f"SplitConfig.views {self.views}: at most {MAX_VIEWS} (one per degree)")
        if self.layout == "grid" and self.quadruplets_per_pose and (self.poses or 0) > MAX_QUADRUPLET_POSES:
            raise ValueError(f"SplitConfig.poses {self.poses}: at most {MAX_QUADRUPLET_POSES} per subject when "
                             "quadruplets are drawn")
        images = self.planned_images_bound()
        if images is not None and images > MAX_SPLIT_IMAGES:
            raise ValueError(f"this split would hold {images:,} images, more than {MAX_SPLIT_IMAGES:,}; lower its "
                             "pairs, subjects, poses or views")

    def planned_images_bound(self) -> int | None:
        """The most images the split can hold, from its counts alone (``None``: the source decides)."""
        if self.layout == "pairs":
            return None if self.pairs is None else 4 * self.pairs
        if self.poses is None:
            return None
        per_subject = (self.poses + (1 if self.canonical else 0)) * self.views
        return per_subject * (1 if self.subjects is None else max(self.subjects, 1))


@dataclass(frozen=True)
class GenerationConfig(Checked):
    """Everything that determines a dataset's content (its hash identifies the dataset).

    Attributes:
        dataset: the body source's registered name (``cerberus.bodies`` entry points: ``human``,
            ``animal``, ``primitives``, ``folder``, or a plugin's).
        preset: name of the size preset it came from (informational, recorded as ``preset`` in the manifest).
        splits: split name → :class:`SplitConfig`, in generation order.
        seed: the seed every random choice derives from.
        image_size: square image size in pixels.
        renderer: renderer backend name (``make_renderer``; ``auto``: warp if it works, else torch).
        scene: the scene set-up.
        shard_images: target images per shard (a grid training subject is never split).
        supersample: anti-aliasing of the stored images: each is rendered at ``supersample`` times
            the size and box-filtered down (``supersample**2`` samples per pixel), so thin limbs stay
            connected and edges carry partial coverage; 1 (the paper-faithful default): one sample
            per pixel, hard edges. Omitted from :meth:`to_dict` when 1 (older manifests keep
            their hash).
        source: the body source's :meth:`BodySource.describe` (versions, content fingerprints).
    """

    dataset: str
    preset: str
    splits: dict[str, SplitConfig]
    seed: int = ranged(0, ge=0)
    image_size: int = ranged(64, ge=8, le=MAX_IMAGE_SIZE)
    renderer: str = "auto"
    scene: SceneSetup = field(default_factory=SceneSetup)
    shard_images: int = ranged(1024, ge=4)
    source: dict[str, Any] = field(default_factory=dict)
    supersample: int = ranged(1, ge=1, le=8)

    def validate(self) -> None:
        if not self.splits:
            raise ConfigError("a dataset needs at least one split; add a splits: section (e.g. train: and test:)")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (stored as the manifest's ``config``; keys added after format v1 only when
        set: :func:`~cerberus_core.config.omit_defaults`)."""
        d = {
            "dataset": self.dataset, "preset": self.preset, "seed": self.seed, "image_size": self.image_size,
            "renderer": self.renderer, "scene": self.scene.to_dict(), "shard_images": self.shard_images,
            "splits": {k: omit_defaults(asdict(v), {"pose_pairs": "independent"}) for k, v in self.splits.items()},
            "source": self.source, "supersample": self.supersample,
        }
        return omit_defaults(d, {"supersample": 1})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> GenerationConfig:
        """The config of :meth:`to_dict`'s form (a manifest's ``config``), checked.

        Raises:
            ConfigError: a key this version does not know, or a value out of range.
        """
        return replace(build(cls, {k: v for k, v in d.items() if k != "scene"}), scene=SceneSetup.from_dict(d.get("scene")))


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
            raise ConfigError(f"{key}: set by {why}, not by a preset file or `overrides`")
    return build(GenerationConfig, {**raw, "dataset": dataset, "preset": size})


def preset_config(dataset: str, size: str, **overrides: Any) -> GenerationConfig:
    """The :class:`GenerationConfig` of a bundled preset, with ``overrides`` (Python values for
    ``seed``, ``image_size``, ``renderer``, ``scene``, ``shard_images``, ``splits``) applied."""
    return replace(load_generation_config(dataset, size), **overrides)


@dataclass(frozen=True)
class GenerationRequest:
    """A dataset as it is asked for: a body source, a size preset, the config keys set over the preset and
    the source's options. :meth:`Dataset.request <cerberus_core.datasets.dataset.Dataset.request>` gives the
    one that resumes a dataset; ``cerberus data`` says it as a command.

    Attributes:
        dataset: the body source's name.
        size: the size preset.
        overrides: flat config key (``seed``, ``splits.train.pairs``) → value, where it differs from the preset.
        source_options: the source's stored options.
    """

    dataset: str
    size: str
    overrides: Mapping[str, Any] = field(default_factory=dict)
    source_options: Mapping[str, Any] = field(default_factory=dict)

    def config(self) -> GenerationConfig:
        """The config asked for (:func:`load_generation_config`)."""
        return load_generation_config(self.dataset, self.size, [f"{k}={json.dumps(v)}" for k, v in self.overrides.items()])

    @classmethod
    def of(cls, manifest: Manifest) -> GenerationRequest:
        """The request that rebuilds exactly the config ``manifest`` stores (so a generation resumes it): every
        stored key whose value differs from the size preset's (every key, if this version lacks the preset)."""
        dataset, size = manifest.dataset, str(manifest.preset)
        try:
            preset = flatten(json.loads(json.dumps(load_generation_config(dataset, size).to_dict())))
        except CerberusError:  # a preset (or a source) this version no longer has: every stored key is given
            preset = {}
        stored = flatten({k: v for k, v in manifest.config.items() if k not in ("dataset", "preset", "source")})
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
        raise ValueError(f"subject {who.name!r} has {len(pool)} pose(s) for split {split!r}; a pose pair needs 2")
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
        ValueError: if splits share a subject while the source promises disjoint subjects, no split
            has a subject, or a split with subjects would hold no image.
    """
    table: list[SubjectRecord] = []
    index: dict[str, int] = {}
    shards: dict[str, list[ShardPlan]] = {}
    for split, cfg in config.splits.items():
        infos: list[Subject] = source.subjects(split, cfg.subjects, config.seed)
        if not infos:
            shards[split] = []
            continue
        for s in infos:
            if s.name in index:
                entry = table[index[s.name]]
                if not source.shared_subjects:
                    raise ValueError(f"subject {s.name!r} is in splits {list(entry.splits)} and {split!r}; "
                                     "splits must hold disjoint subjects")
                table[index[s.name]] = entry.in_split(split)
            else:
                index[s.name] = len(table)
                canonical = source.canonical_pose(s)
                table.append(SubjectRecord(s.name, jsonable(s.info), (split,),
                                           None if canonical is None else int(canonical)))
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
            raise ValueError(f"split {split!r} would be empty; check the preset's counts")
    if not table:
        raise ValueError(f"no split has a subject ({', '.join(config.splits)}); adjust the preset or the folder's "
                         "split options")
    return DatasetPlan(table, shards)
