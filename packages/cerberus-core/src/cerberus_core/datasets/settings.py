"""The settings of a dataset's generation: :class:`GenerationConfig` (everything that determines its
content; its hash identifies the dataset) and :class:`SplitConfig` (how one split is built), both
:class:`~cerberus_core.fields.Checked` (ranges and choices in the fields, the checks between fields in
``validate``). The layouts are described in :mod:`cerberus_core.datasets.plan`; the manifest stores the
config typed (:attr:`Manifest.config <cerberus_core.datasets.manifest.Manifest.config>`).
"""
from __future__ import annotations

from dataclasses import asdict, dataclass, field, replace
from typing import Any, Literal

from cerberus_core.config import build, omit_defaults
from cerberus_core.datasets.scene import SceneSetup, read_scene
from cerberus_core.errors import ConfigError
from cerberus_core.fields import Checked, ranged

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
class SplitConfig(Checked):
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
        pose_set: ``grid`` layout: which poses it shows. ``"sampled"``: the source's pose pool (its
            training generator's draws); ``"heldout"``: poses its training generators do not make
            (:meth:`BodySource.heldout_poses`; human only: :mod:`cerberus_core.bodies.human_heldout`,
            the ``heldout_poses`` size). Omitted from :meth:`GenerationConfig.to_dict` when ``"sampled"``.
    """

    layout: Literal["pairs", "grid"]
    subjects: int | None = ranged(None, ge=0, le=MAX_SUBJECTS, integer=True)
    pairs: int | None = ranged(0, ge=0)
    poses: int | None = ranged(None, ge=0, integer=True)
    views: int = ranged(4, ge=1, le=MAX_VIEWS)
    azimuths: Literal["shared", "per_pose"] = "per_pose"
    quadruplets_per_pose: int = ranged(0, ge=0)
    canonical: bool = False
    meshes: bool = True
    pose_pairs: Literal["independent", "motion"] = "independent"
    pose_set: Literal["sampled", "heldout"] = "sampled"

    def validate(self) -> None:
        if self.layout != "pairs" and self.pose_pairs != "independent":
            raise ConfigError.about("pose_pairs", self.pose_pairs, "needs layout pairs (a grid has no pose pairs)",
                                    "drop `pose_pairs`, or set `layout=pairs`")
        if self.layout != "grid" and self.pose_set != "sampled":
            raise ConfigError.about("pose_set", self.pose_set, "needs layout grid (held-out poses are a test grid)",
                                    "drop `pose_set`, or set `layout=grid`")
        if self.layout == "grid" and self.quadruplets_per_pose and self.views < 2:
            raise ConfigError.about("views", self.views, "quadruplets need at least 2 views per pose",
                                    "set `views=2` or more, or `quadruplets_per_pose=0`")
        if self.layout == "grid" and self.quadruplets_per_pose and (self.poses or 0) > MAX_QUADRUPLET_POSES:
            raise ConfigError.about("poses", self.poses, f"at most {MAX_QUADRUPLET_POSES} per subject when "
                                    "quadruplets are drawn")
        images = self.planned_images_bound()
        if images is not None and images > MAX_SPLIT_IMAGES:
            raise ConfigError.about("views", self.views, f"this split would hold {images:,} images, more than "
                                    f"{MAX_SPLIT_IMAGES:,}; lower its `pairs`, `subjects`, `poses` or `views`")

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
            raise ConfigError("a dataset needs at least one split; add a splits: section (e.g. train: and test:)", key="splits")

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict (stored as the manifest's ``config``; keys added after format v1 only when
        set: :func:`~cerberus_core.config.omit_defaults`)."""
        d = {
            "dataset": self.dataset, "preset": self.preset, "seed": self.seed, "image_size": self.image_size,
            "renderer": self.renderer, "scene": self.scene.to_dict(), "shard_images": self.shard_images,
            "splits": {k: omit_defaults(asdict(v), {"pose_pairs": "independent", "pose_set": "sampled"}) for k, v in self.splits.items()},
            "source": self.source, "supersample": self.supersample,
        }
        return omit_defaults(d, {"supersample": 1})

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> GenerationConfig:
        """The config of :meth:`to_dict`'s form (a manifest's ``config``), checked.

        Raises:
            ConfigError: a key this version does not know, or a value out of range.
        """
        return replace(build(cls, {k: v for k, v in d.items() if k != "scene"}), scene=read_scene(d.get("scene")))


__all__ = ["MAX_IMAGE_SIZE", "GenerationConfig", "SplitConfig"]
