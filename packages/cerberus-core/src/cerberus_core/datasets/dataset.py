"""A dataset as one object: :class:`Dataset`, the one way in to a dataset folder (docs/data_format.md).

* :meth:`Dataset.generate` makes one (or resumes it): the generation is checked whole (the config, the
  body source and its options, the renderer, the plan, the memory, the folder) before anything is
  written, the folder's lock is held while it is written, and the source's advice is warned;
  :meth:`Dataset.plan` stops after the checks (a dry run).
* :meth:`Dataset.open` reads one: its manifest, scene and part names, the training quadruplets and the
  evaluation views of a split (:meth:`quadruplets`, :meth:`views`), the whole-folder check
  (:meth:`verify`), a contact sheet (:meth:`contact_sheet`), and what is left to generate
  (:meth:`incomplete`, :meth:`request`, :meth:`resume`).
* :meth:`Dataset.is_dataset` says whether a folder holds one.

The manifest's file name is known to :mod:`cerberus_core.datasets.manifest` alone.
"""
from __future__ import annotations

import warnings
from collections.abc import Callable
from pathlib import Path

from tqdm import tqdm

from cerberus_core.bodies.body import BodySource, source_class
from cerberus_core.datasets.format import check_shard_arrays, check_shard_files, empty_views
from cerberus_core.datasets.generate import GenerationJob, ShardCallback, validate_generation, write_dataset
from cerberus_core.datasets.manifest import FORMAT_VERSION, MANIFEST, Manifest
from cerberus_core.datasets.plan import GenerationRequest
from cerberus_core.datasets.readers import QuadrupletDataset, ViewDataset
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.datasets.settings import GenerationConfig
from cerberus_core.datasets.show import save_contact_sheet
from cerberus_core.errors import CerberusError, ConfigError
from cerberus_core.fields import check_kind, check_path
from cerberus_core.plugins import RENDERER_GROUP, get_plugin
from cerberus_core.plumbing.lock import check_unlocked, folder_lock
from cerberus_core.plumbing.names import printable
from cerberus_core.plumbing.outputs import output_file, output_folder
from cerberus_core.render.backends import AUTO_RENDERER

MAX_SHEET_ROWS, MAX_SHEET_SCALE = 256, 16
"""A contact sheet stays a picture: at most 256 rows of 64 px tiles, upscaled at most 16 times."""


class Dataset:
    """A generated dataset folder: :meth:`open` one, :meth:`generate` one.

    Attributes:
        manifest: its :class:`~cerberus_core.datasets.manifest.Manifest`.
    """

    def __init__(self, manifest: Manifest) -> None:
        self.manifest = manifest

    def __repr__(self) -> str:
        return f"Dataset({str(self.root)!r}: {self.name}/{self.manifest.preset}, splits {sorted(self.manifest.splits)})"

    # ---------------------------------------------------------------------------- opening
    @staticmethod
    def is_dataset(path: str | Path) -> bool:
        """Whether the folder ``path`` holds a dataset (its manifest; whether it reads is :meth:`open`'s)."""
        return (Path(path) / MANIFEST).is_file()

    @classmethod
    def open(cls, root: str | Path) -> Dataset:
        """The dataset in the folder ``root``.

        Raises:
            DatasetError: no dataset there, or a manifest that does not read (naming the problem and the fix).
        """
        return cls(Manifest.read(check_path("root", root)))

    @property
    def root(self) -> Path:
        return self.manifest.root

    @property
    def name(self) -> str:
        """The body source it was generated from (``human``, ``folder``, a plugin's name)."""
        return self.manifest.dataset

    @property
    def scene(self) -> SceneSetup:
        """The scene set-up its images were rendered with."""
        return self.manifest.scene

    @property
    def body_kind(self) -> str | None:
        """The kind of bodies it holds (its source's :meth:`BodySource.body_kind`; ``None``: any kind, or a
        source not installed here that is not named after a kind)."""
        try:
            return self.source_class().body_kind()
        except CerberusError:  # a source not installed here (or failing to load): its name is the best guess
            return self.name

    def source_class(self) -> type[BodySource]:
        """The class of its body source (found by entry point)."""
        return source_class(self.manifest.source.name)

    def quadruplets(self, split: str = "train", *, allow_partial: bool = False, verify: bool = False) -> QuadrupletDataset:
        """The training quadruplets of ``split`` (:class:`~cerberus_core.datasets.readers.QuadrupletDataset`)."""
        return QuadrupletDataset(self.root, split, allow_partial=allow_partial, verify=verify)

    def views(self, split: str = "test", *, allow_partial: bool = False, verify: bool = False) -> ViewDataset:
        """The single views of ``split`` with their ground truth (:class:`~cerberus_core.datasets.readers.ViewDataset`)."""
        return ViewDataset(self.root, split, allow_partial=allow_partial, verify=verify)

    # ---------------------------------------------------------------------------- checking
    def verify(self, *, checksums: bool = True, progress: bool = False) -> list[str]:
        """Check the whole dataset: every shard file (size, sha256 unless not ``checksums``, array shapes),
        views that render empty (:func:`~cerberus_core.datasets.format.empty_views`, on shards whose files
        are sound), and completeness (:meth:`incomplete`, one problem per split). Empty: the dataset is sound.
        Each problem is printable as it is: a name from the manifest is escaped (:func:`printable`)."""
        manifest, problems = self.manifest, []
        shards = [(name, s) for name, info in manifest.splits.items() for s in info.shards]
        for split, shard in tqdm(shards, desc="checking shards", unit="shard", disable=not progress):
            problems.extend(check_shard_files(self.root, shard, checksums=checksums)
                            or check_shard_arrays(manifest, split, shard) or empty_views(manifest, split, shard))
        return [printable(p) for p in problems + list(self.incomplete().values())]

    def summary(self) -> list[str]:
        """What it holds: the source, preset, image size, subjects and parts, then per split the shards
        written of those planned and their images, quadruplets and meshes (names from the manifest escaped)."""
        m = self.manifest
        lines = [f"{self.root}: {m.dataset}/{m.preset}, format v{FORMAT_VERSION}, {m.image_size}px, "
                 f"{len(m.subjects)} subjects, {len(m.part_names)} parts"]
        for split, info in m.splits.items():
            count = info.totals()
            lines.append(f"  {split:<6} {len(info.shards)}/{info.planned_shards} shards, {count['images']} images, "
                         f"{count['quadruplets']} quadruplets, {count['meshes']} meshes")
        return [printable(line) for line in lines]

    # ---------------------------------------------------------------------------- what is left to generate
    def incomplete(self) -> dict[str, str]:
        """What is left to generate: split → the problem (``"split 'train' is incomplete (1 of 3 shards)"``);
        empty when every split is complete."""
        return {name: problem for name in self.manifest.splits if (problem := self.manifest.incomplete(name))}

    def request(self) -> GenerationRequest:
        """How this dataset is asked for: its source, size preset, the keys its config sets over the
        preset and its source's options. Generating it into this folder resumes it."""
        return GenerationRequest.of(self.manifest)

    def resume(self, *, device: str = "cpu", batch_size: int = 64, progress: bool = True,
               log: Callable[[str], None] = print) -> Dataset:
        """Finish generating this dataset (the shards written are kept): :meth:`generate` with its :meth:`request`."""
        return Dataset.generate(self.request(), self.root, device=device, batch_size=batch_size, progress=progress,
                                log=log)

    # ---------------------------------------------------------------------------- looking
    def contact_sheet(self, out: str | Path | None = None, *, split: str = "train", count: int = 8, parts: bool = False,
                      renderer: str = AUTO_RENDERER, scale: int = 2) -> Path:
        """Write a contact sheet PNG of ``split`` (:func:`~cerberus_core.datasets.show.contact_sheet`): ``count``
        rows (quadruplets, or the views of one pose), ``parts`` adds the ground-truth parts in colour.

        Args:
            out: the PNG (default ``ROOT/contact_<split>.png``).
            count: rows, at most :data:`MAX_SHEET_ROWS`; scale: tile upscaling, at most :data:`MAX_SHEET_SCALE`.
            renderer: the backend of the part renderings (checked even without ``parts``).

        Returns:
            The PNG written.
        """
        for key, value, most in (("count", count, MAX_SHEET_ROWS), ("scale", scale, MAX_SHEET_SCALE)):
            if not 1 <= value <= most:
                raise ConfigError.about(key, value, f"must be an integer in [1, {most}]")
        self.manifest.split(split)
        out = output_file(check_path("out", out) if out is not None else self.root / f"contact_{split}.png")
        if renderer != AUTO_RENDERER:
            get_plugin(RENDERER_GROUP, renderer)  # a known backend, even without parts
        has_quads = any(shard.quadruplets for shard in self.manifest.split(split).shards)
        return save_contact_sheet(self.views(split, allow_partial=True), out, self.manifest,
                                  quads=self.quadruplets(split, allow_partial=True) if has_quads else None,
                                  count=count, parts=parts, renderer=renderer, scale=scale)

    # ---------------------------------------------------------------------------- making
    @classmethod
    def plan(cls, config: GenerationConfig | GenerationRequest, out: str | Path | None = None, *,
             source: BodySource | None = None, overwrite: bool = False, device: str = "cpu",
             batch_size: int = 64) -> GenerationJob:
        """Check a whole generation and plan it, writing nothing (a dry run): the config, the body source
        registered as ``config.dataset`` and its options, the renderer, the shard plan, the memory a shard
        needs and, with ``out``, the folder (:func:`~cerberus_core.datasets.generate.validate_generation`);
        the source's advice (:meth:`BodySource.warnings`) is warned. Arguments as in :meth:`generate`.

        Returns:
            The job: :meth:`GenerationJob.plan_lines` says the counts of each split.
        """
        source_options = None  # a config's source takes its default options; a request carries its own
        if isinstance(config, GenerationRequest):
            config, source_options = config.config(), config.source_options
        check_kind("config", config, GenerationConfig, "a GenerationRequest or a GenerationConfig (from load_generation_config)")
        if out is not None:
            output_folder(check_path("out", out))
        job = validate_generation(config, source=source, source_options=source_options, device=device,
                                  batch_size=batch_size, out=out, overwrite=overwrite)
        for advice in job.source.warnings():
            warnings.warn(advice, UserWarning, stacklevel=3)
        return job

    @classmethod
    def generate(cls, config: GenerationConfig | GenerationRequest, out: str | Path, *,
                 source: BodySource | None = None, overwrite: bool = False, device: str = "cpu", batch_size: int = 64,
                 progress: bool = True, log: Callable[[str], None] = print,
                 on_shard: ShardCallback | None = None) -> Dataset:
        """Generate (or resume) a dataset in ``out``: :meth:`plan`, then the shards written under the folder's
        lock (one writer per dataset folder).

        Rerunning the same config in the same folder resumes it (finished shards are kept); a folder that
        holds another dataset is refused unless ``overwrite``, and one holding anything else always
        (:func:`~cerberus_core.plumbing.outputs.check_output`).

        Args:
            config: what to generate: a :class:`~cerberus_core.datasets.plan.GenerationRequest` (source, size
                preset, overrides and the source's options, checked by its ``Options`` and stored in the manifest:
                what ``cerberus data generate`` asks for, and :meth:`request` of a dataset), the one way to give a
                source options; or a config (:func:`~cerberus_core.datasets.plan.load_generation_config`), whose
                source takes its default options.
            out: the dataset folder (created if needed).
            source: a body source built by the caller instead (a request's options are then stored as given).
            overwrite: replace a different dataset the toolkit wrote in ``out`` (its own files only).
            device: torch device for posing and rendering (no effect on the dataset).
            batch_size: views per render call (no effect on the dataset).
            progress: show a progress bar; log: where progress lines go.
            on_shard: called as ``on_shard(split, record)`` after each shard is listed in the manifest.

        Raises:
            ConfigError: the generation is invalid (nothing written).
            DatasetError, ConfigError: ``out`` holds another dataset (without ``overwrite``), or anything else.
            LockedError: another live process writes into ``out``.
        """
        out = check_path("out", out)
        job = cls.plan(config, out, source=source, overwrite=overwrite, device=device, batch_size=batch_size)
        if out.is_dir():
            check_unlocked(out)  # a live writer: refused before the lock file is even attempted
        with folder_lock(out):
            manifest = write_dataset(job, out, overwrite=overwrite, device=device, batch_size=batch_size,
                                     progress=progress, log=log, on_shard=on_shard)
        return cls(manifest)


__all__ = ["MAX_SHEET_ROWS", "MAX_SHEET_SCALE", "Dataset"]
