"""The posed-body record that every body source (human, animal, mesh folder) produces, and the
contract of those sources (:class:`BodySource`, :class:`Subject`). Sources are plugins: each registers
its class under the ``cerberus.bodies`` entry-point group (the core's own in its ``pyproject.toml``,
exactly as a third party would: docs/bodies.md), and :func:`source_class` finds one by name.

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

import contextlib
import typing
from abc import ABC, abstractmethod
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import asdict, dataclass, field, fields, is_dataclass, replace
from importlib.util import find_spec
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from cerberus_core.config import Presets, build
from cerberus_core.errors import BodyError, CerberusError, ConfigError, DatasetError, MissingPackageError, shown
from cerberus_core.fields import RANGE, Checked, Range
from cerberus_core.plugins import BODY_GROUP, get_plugin, plugin_origin
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
            raise BodyError(f"PosedBody {self.subject}/{self.pose_id}: vertices contain NaN or inf")
        if f.size and (f.min() < 0 or f.max() >= len(v)):
            raise BodyError(f"PosedBody {self.subject}/{self.pose_id}: faces index outside 0..{len(v) - 1}")
        if np.asarray(self.vertex_parts).shape != (len(v),):
            raise BodyError("PosedBody.vertex_parts must have one label per vertex")
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
        raise BodyError("normalise_subject needs at least one pose")
    extents = [float((p.max(0) - p.min(0)).max()) for p in poses]
    largest = max(extents)
    if not np.isfinite(largest) or largest <= 0:
        raise BodyError(f"normalise_subject: degenerate subject (largest extent {largest})")
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
        """``info[key]`` for each key, or a :class:`DatasetError` naming the missing ones (an older manifest)."""
        missing = [k for k in keys if k not in self.info]
        if missing:
            raise DatasetError(f"{source} subject {self.name!r} lacks {missing} in its record; the manifest predates "
                           "self-contained subject records: rerun the same `cerberus data generate` command (it "
                           "resumes and rewrites the manifest)")
        return [self.info[k] for k in keys]


DATA_PRESETS = Presets("configs/data", kind="dataset preset")
"""The core's dataset presets, ``cerberus_core/configs/data/<source>_<size>.yaml``: ``paper`` follows
the paper's counts, ``small`` generates on a CPU in minutes, ``tiny`` in seconds (tests); ``folder``
has ``pairs`` (the Human protocol) and ``grid`` (the Animal protocol) instead."""


@dataclass(frozen=True)
class NoOptions(Checked):
    """The options of a body source that takes none."""


FLAG = "cerberus.flag"
"""The ``dataclasses.field`` metadata key of a source option that has a command-line flag of its own."""


@dataclass(frozen=True)
class OptionFlag:
    """How ``cerberus data generate`` takes one option of a body source as a flag of its own (any option is
    also given as ``KEY=VALUE``); a list option is given comma-separated.

    Attributes:
        flag: the flag's name, a word (``source``, ``test_fraction``): the command writes it as its flag.
        help: the flag's help line (settings in backticks, as in any library message: `` `test_fraction` ``).
        metavar: what ``--help`` shows as its value (``None``: argparse's default).
    """

    flag: str
    help: str
    metavar: str | None = None
    listed: bool = False
    """Whether the option is a list (given comma-separated; :meth:`BodySource.option_flags` says so)."""


def flagged(default: Any, flag: str, help: str, *, metavar: str | None = None, allowed: Range | None = None) -> Any:
    """A field of a source's ``Options`` with a flag of its own (:class:`OptionFlag`) and, optionally, its range
    (``allowed``, as :func:`~cerberus_core.fields.ranged` declares one)."""
    metadata: dict[str, Any] = {FLAG: OptionFlag(flag, help, metavar)}
    if allowed is not None:
        metadata[RANGE] = allowed
    return field(default=default, metadata=metadata)


class BodySource(ABC):
    """Geometry provider of a dataset (:mod:`cerberus_core.bodies.sources` describes the calls).

    A source is a plugin: its class is registered under the ``cerberus.bodies`` entry-point group by
    the name it is generated by (``GenerationConfig.dataset``), and a dataset is generated from it,
    and read back, through that name alone (docs/bodies.md shows a minimal one).

    Attributes:
        name: the name the source is registered by (``GenerationConfig.dataset``, ``Manifest.dataset``).
        part_names: names of the ground-truth parts indexed by ``PosedBody.vertex_parts``.
        shared_subjects: ``True`` if every split holds the same subjects with disjoint poses (the
            animal protocol); ``False`` if splits hold disjoint subjects (human, folder).
        Options: its options, one :class:`~cerberus_core.fields.Checked` dataclass (checked when made;
            :meth:`options`); what :meth:`stored_options` gives is stored in the manifest, and
            :meth:`from_options` builds the source from it again.
        presets: where its size presets live: files ``<name>_<size>.yaml`` (:meth:`sizes`).
        default_size: the size preset used when none is named.
        body_kind: the kind of bodies it holds (``None``: any kind, e.g. a folder of your meshes), which
            a model trained on one kind is compared with.
        canonical_hint: how to give its subjects canonical poses, where it may lack them ("" if it
            always has them): said when the Hard Human test cannot run.
        packages: the optional packages its bodies need, import name → what brings it
            (``{"anny": "cerberus-core[human]"}``), checked before a generation starts (:meth:`check_packages`).
        photo_subject: what a photograph of its kind of body shows that the untextured grey renders do
            not, as a noun phrase (``"a clothed or coloured person"``): said when a model trained on it is
            given such a photo (:func:`cerberus_core.reconstruct.input_domain.appearance_check`).
    """

    name: ClassVar[str] = "abstract"
    part_names: list[str]
    shared_subjects: ClassVar[bool] = False
    Options: ClassVar[type] = NoOptions
    presets: ClassVar[Presets] = DATA_PRESETS
    default_size: ClassVar[str] = "small"
    canonical_hint: ClassVar[str] = ""
    packages: ClassVar[Mapping[str, str]] = {}
    photo_subject: ClassVar[str] = "a coloured or textured body"

    @classmethod
    def body_kind(cls) -> str | None:
        """The kind of bodies this source holds (default: its name; ``None``: any)."""
        return cls.name

    # ---------------------------------------------------------------------------- options, presets
    @classmethod
    def options(cls, given: Mapping[str, Any] | None = None) -> Any:
        """``given`` (Python values or a manifest's stored options) as a checked :attr:`Options`.

        Raises:
            ConfigError: an option this source does not take (naming the ones it takes), or a value of
                the wrong type or out of range (naming the key).
        """
        given = dict(given or {})
        known = [f.name for f in fields(cls.Options) if f.init]
        for key, value in given.items():
            if key not in known:
                takes = f"its options are {', '.join(f'`{k}`' for k in known)}" if known else "it takes none"
                raise ConfigError.about(key, value, f"not an option of the {cls.name} body source ({takes}); "
                                        "drop it, or choose the source that takes it")
        return build(cls.Options, given)

    @classmethod
    def option_flags(cls) -> dict[str, OptionFlag]:
        """``{option: its flag}`` of the options of :attr:`Options` that have a flag of their own (:func:`flagged`)."""
        hints = typing.get_type_hints(cls.Options)
        return {f.name: replace(f.metadata[FLAG], listed="list" in str(hints[f.name]))
                for f in fields(cls.Options) if FLAG in f.metadata}

    def reads(self) -> list[Path]:
        """The folders this source reads its bodies from, which a dataset is never written into (default: none;
        the folder source: its folder of meshes)."""
        return []

    @classmethod
    def stored_options(cls, options: Any) -> dict[str, Any]:
        """The JSON form of checked ``options`` that the manifest stores (``None`` values left out)."""
        return {k: v for k, v in asdict(options).items() if v is not None}

    @classmethod
    def from_options(cls, options: Any, *, device: str = "cpu") -> BodySource:
        """The source built from checked ``options``; ``device`` is where it may pose bodies (no effect on
        them). The default passes every option as a keyword argument."""
        return cls(**{f.name: getattr(options, f.name) for f in fields(options)})

    @classmethod
    def check_packages(cls) -> None:
        """Every package of :attr:`packages` is installed, else one :class:`MissingPackageError` naming all that
        are missing and the ``pip install`` that brings them (before anything is generated)."""
        missing = [name for name in cls.packages if find_spec(name) is None]
        if missing:
            bring = " ".join(f"'{extra}'" for extra in dict.fromkeys(cls.packages[name] for name in missing))
            raise MissingPackageError(f"the {cls.name} body source needs {' and '.join(missing)}, which "
                                      f"{'are' if len(missing) > 1 else 'is'} not installed: pip install {bring}")

    @classmethod
    def sizes(cls) -> list[str]:
        """Its size presets (``paper``, ``small``, ``tiny`` ...): the files ``<name>_<size>.yaml`` of :attr:`presets`."""
        prefix = f"{cls.name}_"
        return [n[len(prefix):] for n in cls.presets.names() if n.startswith(prefix)]

    def warnings(self) -> list[str]:
        """Advice about what the source found (one line each; the generation warns with them)."""
        return []

    @classmethod
    def empty_split_hint(cls, options: Mapping[str, Any], subjects: int, split: str, root: str | Path) -> str:
        """Why ``split`` of a dataset of this source has no subject and what to do, one line.

        Args:
            options: the source's stored options (the manifest's).
            subjects: how many subjects the dataset holds.
            split: the empty split.
            root: the dataset folder (for the fix the hint names).
        """
        return no_subjects_hint(split, subjects, root)

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

    def heldout_poses(self, subject: Subject, split: str, n: int | None) -> list[int]:
        """``n`` pose ids of ``subject`` from poses its training generators do not make (the ``pose_set:
        heldout`` mode of a ``grid`` split: a test of bodies in unseen poses); sources without them refuse.

        Raises:
            ConfigError: the source has no held-out poses (or, for ``n=None``, no fixed number of them).
        """
        raise ConfigError.about(f"splits.{split}.pose_set", "heldout", f"the {self.name} source has no held-out "
                                f"poses; use `splits.{split}.pose_set=sampled`")

    def prepare(self) -> None:
        """Load now what posing needs (a body model, its one-time cache) rather than in the first :meth:`bodies`
        call: the generator calls it before its progress bar starts, so a slow first load is neither hidden
        under a bar nor counted in its rate. A one-time cost of a minute or more is announced here, before it
        starts, with what it is and about how long it takes
        (:func:`~cerberus_core.plumbing.stdio.announce`). Default: nothing to load."""
        return None

    @abstractmethod
    def bodies(self, subject: Subject, pose_ids: Sequence[int]) -> list[PosedBody]:
        """Normalised posed bodies of one subject, one per pose id, in order; each depends only on
        ``(subject, pose id)``, never on the other ids asked for."""

    def describe(self) -> dict[str, Any]:
        """Options that determine the geometry (stored in the manifest's config; part of its hash)."""
        return {}


def no_subjects_hint(split: str, subjects: int, root: str | Path, cause: str = "", fix: str = "") -> str:
    """The one-line hint of an empty split (:meth:`BodySource.empty_split_hint`): its ``cause`` (default: the
    subjects are all in other splits) and ``fix`` (default: use another dataset)."""
    head = f"the dataset has no {split} subjects"
    if split == "train":
        cause = cause or (" (its only subject is a test subject)" if subjects == 1
                          else f" (all {subjects} subjects are test subjects)")
        return (f"{head}{cause}; a dataset without train subjects is for evaluation (`Run.evaluate` on {root}, or "
                "`cerberus eval`); train on a dataset with train subjects")
    cause = cause or f" (its {subjects} subject{'' if subjects == 1 else 's'} are all in other splits)"
    return f"{head}{cause}; {fix or 'use a dataset with test subjects'}"


def source_class(name: str) -> type[BodySource]:
    """The body source registered as ``name`` under the ``cerberus.bodies`` entry points.

    Raises:
        UnknownPluginError: no source of that name is installed (naming the closest and the installed ones).
        PluginLoadError: it is registered but cannot be imported (a missing optional package: its message).
        ConfigError: what is registered is not a :class:`BodySource` class.
    """
    cls = get_plugin(BODY_GROUP, name)
    if not (isinstance(cls, type) and issubclass(cls, BodySource)):
        raise ConfigError.about("dataset", name, f"the {BODY_GROUP} entry point {plugin_origin(BODY_GROUP, name)} is "
                                "not a BodySource class", "register the source's class")
    if getattr(cls, "name", None) != name:  # a dataset labelled with both names resolved to the other source
        raise ConfigError.about("dataset", name, f"the {BODY_GROUP} entry point {plugin_origin(BODY_GROUP, name)} "
                                f"holds a source whose `name` is {shown(getattr(cls, 'name', None))}; a source has one "
                                "name: make the entry point's and the class's the same")
    if not (isinstance(cls.Options, type) and is_dataclass(cls.Options)):
        raise ConfigError.about("dataset", name, f"the body source {plugin_origin(BODY_GROUP, name)} has `Options` "
                                f"{shown(cls.Options)}, not a dataclass; a source's options are a dataclass "
                                "(docs/bodies.md)")
    return cls


@contextlib.contextmanager
def source_contract(source: BodySource | type[BodySource], what: str) -> Iterator[None]:
    """Run a body source's own code (``subjects``, ``bodies``, its subjects' ``info``): any exception it raises
    that is not one of the toolkit's own becomes one :class:`BodyError` naming the plugin, its distribution and
    ``what`` it broke (issue 39: a traceback that did not name the plugin)."""
    try:
        yield
    except CerberusError:
        raise
    except Exception as exc:  # noqa: BLE001 - whatever a plugin raises is named the same way
        raise BodyError(f"the body source {plugin_origin(BODY_GROUP, source.name)} failed in {what}: "
                        f"{type(exc).__name__}: {shown(str(exc))[1:-1]}; fix the source or uninstall it") from exc
