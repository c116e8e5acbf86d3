"""A trained run as one object: :class:`Run`.

``Run.load(path_or_name)`` opens a run folder, a ``model.safetensors`` export, a checkpoint ``.pt`` or a
shipped model (``Run.load("human")``) and holds what belongs together: the model, its config, the
weights file and the step it records (with the run's newer checkpoint, if any), the training data's
root and scene set-up. Its operations are the ones the CLI calls, so a notebook does what a command
does with the same call::

    from cerberus_core.run import EvalSettings, Run

    run = Run.load("human")
    run.evaluate("data/human", EvalSettings(limit=20), "eval")   # what `cerberus eval human --data ... --limit 20` does
    parts = run.model.reconstruct(images, camera)
"""
from __future__ import annotations

import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import torch

from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.looks import InputLook, LookedViews
from cerberus_core.datasets.scene import SceneSetup, read_scene
from cerberus_core.devices import check_device
from cerberus_core.errors import CerberusError, ConfigError
from cerberus_core.eval.compare import RESULTS
from cerberus_core.eval.diagnostics import DIAGNOSTICS, check_eval_packages, needed
from cerberus_core.eval.figures import FigureModels, evaluation_figures
from cerberus_core.eval.markdown import md_text
from cerberus_core.eval.report import images_scored, markdown_report, to_jsonable, write_json, write_text
from cerberus_core.eval.runner import EvalConfig, EvaluationResult, evaluate_dataset, limited_indices
from cerberus_core.eval.standard import VoxelScorer, check_scorer, open_ground_truths
from cerberus_core.eval.viewer import ViewerPage
from cerberus_core.fields import Range, check_kind, check_path, check_paths, check_value, ranged
from cerberus_core.model.cerberus import Cerberus
from cerberus_core.photo_mask import AUTO, require_segmenter
from cerberus_core.plumbing.names import printable
from cerberus_core.plumbing.outputs import check_output, writing_results
from cerberus_core.reconstruct.fit import FIT_STEPS
from cerberus_core.reconstruct.write import ImageInputs, Reconstruction, TrainedModel, mask_paths, write_reconstructions
from cerberus_core.render.backends import make_renderer
from cerberus_core.render.interface import Renderer
from cerberus_core.train.settings import TrainConfig
from cerberus_core.weights import WeightsInfo, describe_weights, load_weights, looks_like_path
from cerberus_core.zoo import available


def open_data(data: str | Path) -> Dataset:
    """The dataset ``data`` names.

    Raises:
        ConfigError: ``data`` is not a dataset folder (``key="data"``).
        DatasetError: its manifest does not read.
    """
    if not Dataset.is_dataset(data):
        raise ConfigError.about("data", Path(data), "not a Cerberus dataset folder (no manifest)")
    return Dataset.open(data)


def model_scene(config: TrainConfig, data: str | Path | None = None, saved: dict | None = None):
    """The scene set-up the model was trained with: from ``data`` (which must be a dataset), else the
    one the run recorded, else from the run's training data if it is still there. Never a silent
    default: without any of them the user is asked for ``data`` (:class:`ConfigError` with that key).

    Args:
        config: the run's config.
        data: a dataset folder whose scene the images follow.
        saved: the scene the weights record.
    Returns:
        A :class:`~cerberus_core.datasets.scene.SceneSetup`.
    """
    if data is not None:
        return open_data(data).scene  # a damaged scene record is a DatasetError naming the manifest
    if saved is not None:
        try:
            return read_scene(saved)
        except (ValueError, TypeError, AttributeError, KeyError) as exc:  # ConfigError is a ValueError
            raise ConfigError(f"the model's recorded scene: invalid scene set-up ({exc}); pass `data=DATASET` (the "
                              "dataset it was trained on)", key="data") from None
    root = Path(config.data.root)
    if Dataset.is_dataset(root):
        return Dataset.open(root).scene
    raise ConfigError.about("data", None, f"needed: the run does not record its scene set-up and its training data "
                            f"{root} is not here; pass `data=DATASET` (the dataset it was trained on, or one rendered "
                            "the same way)")


# ------------------------------------------------------------------ evaluation settings
@dataclass(frozen=True)
class EvalSettings(EvalConfig):
    """Everything :meth:`Run.evaluate` is told: what to measure (:class:`EvalConfig`'s fields) and what to
    score and write; checked when made (:class:`~cerberus_core.errors.ConfigError` naming the field),
    the protocol and the resolution through the metric's entry point (its bounds are the only ones:
    :func:`~cerberus_core.eval.standard.check_scorer`), the packages the diagnostics need before anything runs
    (:func:`~cerberus_core.eval.diagnostics.check_eval_packages`).

    Attributes:
        split: the split to score.
        limit: at most ``limit`` images, spread evenly over the split (``None``: all): whole poses while the depth
            diagnostic runs, since it compares each pose's views
            (:func:`~cerberus_core.eval.runner.limited_indices`); ``results.json`` records which under ``data``.
        figure_images, viewer_images: images in the figure and in the 3D viewer (0: no viewer).
        renderer: backend for the figure and the visibility render (``None``: the run's).
        input_look: the test images shown to the model in this look (:mod:`cerberus_core.datasets.looks`:
            ``shaded`` as stored, ``flat`` silhouettes, ``random`` appearances), scores, figures and viewer
            alike; the ground truth is the same. ``None``: the look the model learned (``data.input_look``).
    """

    split: str = "test"
    limit: int | None = ranged(None, ge=1, integer=True)
    figure_images: int = ranged(5, ge=1)
    viewer_images: int = ranged(12, ge=0)
    renderer: str | None = None
    input_look: InputLook | None = None

    def validate(self) -> None:
        super().validate()
        check_eval_packages(self.skip)
        check_scorer(self.protocol, self.resolution)


def _canonical_hint(dataset: Dataset) -> str:
    try:
        return dataset.source_class().canonical_hint
    except CerberusError:  # its source is not installed here: nothing to add
        return ""


@dataclass
class Evaluation:
    """What :meth:`Run.evaluate` measured and wrote.

    Attributes:
        result: the scores (:class:`~cerberus_core.eval.runner.EvaluationResult`).
        out: the result folder (``results.json``, ``results.md``, ``table2.png``, ``pictures/``).
        weights: which weights were scored (step, newer checkpoint).
        hard_requested: whether the Hard Human test was asked for.
        canonical_hint: how the data's body source gives its subjects canonical poses, said when the Hard
            Human test could not run (:attr:`BodySource.canonical_hint`; "": nothing to say).
        viewer: whether ``pictures/index.html`` was written.
        split_images: the images of the split scored from (more than those scored when ``limit`` chose some;
            ``None``: not known).
        data: which images were scored, as ``results.json`` records them under ``data`` (the dataset folder, its
            name and preset, the split, its size, the limit, the rule, the images scored; ``None``: not known, then
            ``split_images`` alone).
    """

    result: EvaluationResult
    out: Path
    weights: WeightsInfo
    hard_requested: bool = True
    canonical_hint: str = ""
    viewer: bool = True
    split_images: int | None = None
    data: Mapping[str, Any] | None = None

    def lines(self) -> list[str]:
        """The summary ``cerberus eval`` prints: the scores ("24 of 984 images" when a limit chose some), the
        predictions the metric rejected or clamped when there are any, then where the results are."""
        result, weights, out = self.result, self.weights, self.out
        policy = open_ground_truths(result.gt_open_mesh)
        line = (f"voxel IoU ({result.protocol}, {result.resolution}^3{', ' if policy else ''}{policy}) over "
                f"{images_scored(result.standard.count, self.data or {'split_images': self.split_images})}: "
                f"{result.standard.mean:.4f}")
        if result["hard"] is not None:
            line += f"; Hard Human: {result['hard'].mean:.4f}"
        elif self.hard_requested:
            line += "; Hard Human: not run (no canonical-pose images in this split"
            if self.canonical_hint:
                line += f"; {self.canonical_hint}"
            line += ")"
        lines = [line]
        for name, summary in (("voxel IoU", result.standard), ("Hard Human", result["hard"])):
            if summary is not None and (summary.failed or summary.clipped):
                lines.append(f"{name}: {summary.failed} rejected (scored 0), {summary.clipped} clamped to the grid")
        record = to_jsonable(result)  # each diagnostic's line reads its summary's JSON form, as results.md does
        lines += [row.line(record[row.key]) for row in DIAGNOSTICS if row.line is not None and record.get(row.key) is not None]
        if weights.stale_warning():  # said again under the scores, where it is read
            lines.append(f"note: these scores are for step {weights.step}; the run has a newer checkpoint "
                         f"{printable(weights.newer)} (step {weights.newer_step})")
        lines.append(f"results: {printable(out / 'results.json')}, {printable(out / 'results.md')}; figures: "
                     f"{printable(out / 'table2.png')}, {printable(out / 'pictures')}")
        if self.viewer:
            lines.append(f"3D viewer: {printable(out / 'pictures' / 'index.html')}")
        return lines


class Run:
    """A trained run: its model, config and weights, loaded once (:meth:`load`).

    >>> import torch
    >>> from cerberus_core.run import Run
    >>> run = Run.load("human")  # a shipped model, by name
    >>> run.step, run.shipped, run.model.config.num_parts, run.training_kind()
    (20000, True, 9, 'human')
    >>> parts = run.model.reconstruct(torch.ones(1, 3, 64, 64), run.scene.cameras([0.0], 64))
    >>> tuple(parts.posed().shape)  # (B, parts, vertices, 3), world space
    (1, 9, 162, 3)

    Attributes:
        model: the :class:`~cerberus_core.model.Cerberus` model, in eval mode on :attr:`device`.
        config: its :class:`~cerberus_core.train.settings.TrainConfig`.
        weights_info: which file was loaded, its step and the run's newer checkpoint, if any
            (:meth:`WeightsInfo.stale_warning`).
        source: the argument it was loaded from (a path, or a shipped model's name).
        recorded_scene: the training data's scene set-up as the weights record it (``None``: none).
        device: where the model is.
    """

    def __init__(self, model: Cerberus, config: TrainConfig, weights_info: WeightsInfo, *,
                 source: str | Path | None = None, recorded_scene: dict | None = None,
                 device: str | torch.device = "cpu") -> None:
        self.model = model
        self.config = config
        self.weights_info = weights_info
        self.source = weights_info.path if source is None else source
        self.recorded_scene = recorded_scene
        self.device = device

    @classmethod
    def load(cls, path: str | Path, device: str | torch.device = "cpu") -> Run:
        """Load a run folder (its ``model.safetensors``, else ``checkpoints/last.pt``), a ``.safetensors``
        export, a ``.pt`` checkpoint or a shipped model by name (``cerberus models``; a bare name a
        shipped model has is that model: see :func:`resolve_weights`).

        >>> Run.load("human").path.name
        'human.safetensors'

        Raises:
            ConfigError: an unknown device.
            CheckpointError: a missing path, a folder that is not a run, a truncated, foreign or pickled file,
                weights that do not fit the saved config or are not finite (:func:`~cerberus_core.weights.load_weights`).
            ZooError: a shipped model's file is missing or damaged.
        """
        check_device(str(device))
        check_path("path", path)  # a str stays one: a bare name is a shipped model's
        weights = describe_weights(path)
        loaded = load_weights(weights.path, device)
        return cls(loaded.model, loaded.config, weights, source=path, recorded_scene=loaded.scene, device=device)

    def __repr__(self) -> str:
        at = "" if self.step is None else f", step {self.step}"
        return f"Run({printable(self.path)}{at})"

    @property
    def path(self) -> Path:
        """The weights file loaded (``RUN/model.safetensors``, a checkpoint, a shipped model's file)."""
        return self.weights_info.path

    @property
    def step(self) -> int | None:
        """The training step the weights record (``None``: none recorded)."""
        return self.weights_info.step

    @property
    def data_root(self) -> Path:
        """The dataset the run was trained on (it may not be on this machine)."""
        return Path(self.config.data.root)

    @property
    def scene(self) -> SceneSetup:
        """The scene set-up the model was trained with: :meth:`scene_for` without a dataset."""
        return self.scene_for(None)

    def scene_for(self, data: str | Path | None = None) -> SceneSetup:
        """The scene set-up of ``data`` (a dataset folder), else the one the weights record, else the
        training data's (:func:`model_scene`; :class:`ConfigError` naming
        ``data`` when none is known)."""
        return model_scene(self.config, data, self.recorded_scene)

    def training_kind(self) -> str | None:
        """The kind of bodies the model was trained on (``human``, ``animal``...: a body source's name): a shipped
        model's training dataset (its registry entry), else its training data's manifest if that is still
        here; ``None`` when unknown."""
        if self.shipped:
            return available()[str(self.source)].data.get("dataset")
        if Dataset.is_dataset(self.data_root):
            return Dataset.open(self.data_root).body_kind
        return None

    def part_labels(self) -> list[str | None] | None:
        """Each learned part's label as a shipped model's card gives it (:attr:`PretrainedModel.part_labels
        <cerberus_core.zoo.PretrainedModel.part_labels>`: the ground-truth part it covers most; ``None`` where it
        covers none); ``None`` when not known (a run folder or model file, or a card without the table)."""
        if not self.shipped:
            return None
        labels = available()[str(self.source)].part_labels
        return list(labels) if len(labels) == self.model.config.num_parts else None

    def domain_notes(self, data: str | Path) -> list[str]:
        """How the dataset ``data`` differs from what the model was trained on (the kind of bodies, the
        camera and the look), one sentence each; empty when nothing known differs."""
        notes = []
        kind, theirs = self.training_kind(), Dataset.open(data).body_kind
        if kind and theirs and kind != theirs:  # None: a source of any kind of body (a folder of meshes)
            notes.append(f"the model was trained on {kind} bodies and {printable(data)} holds {theirs} bodies")
        if self.recorded_scene is not None:
            mine, other = read_scene(self.recorded_scene).to_dict(), self.scene_for(data).to_dict()
            keys = ("distance", "elevation", "fov_y", "background", "albedo")
            diff = [f"{k} {other[k]} (trained: {mine[k]})" for k in keys if mine.get(k) != other.get(k)]
            if diff:
                notes.append(f"the scene of {printable(data)} differs from the model's training scenes: "
                             + ", ".join(diff))
        return notes

    def default_out(self, folder: str = "eval") -> Path:
        """``RUN/<folder>`` for a run folder (``runs/a`` or a bare ``a``), beside a model file, or
        ``./<folder>`` for a shipped model's name."""
        if self.shipped:
            return Path(folder)
        given = Path(self.source)
        return (given if given.is_dir() else given.parent) / folder

    @property
    def shipped(self) -> bool:
        """Whether the run was loaded by a shipped model's name (``Run.load("human")``), not a path."""
        return not looks_like_path(self.source) and str(self.source) in available()

    def evaluate(self, data: str | Path | None = None, settings: EvalSettings | None = None,
                 out: str | Path | None = None, *, baselines: Mapping[str, Run | Cerberus] | None = None,
                 verbose: bool = True) -> Evaluation:
        """Score the run on a split and write the results folder: what ``cerberus eval`` does.

        Voxel IoU and every diagnostic of :data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS` that ``settings``
        does not skip in one pass (:func:`~cerberus_core.eval.runner.evaluate_dataset`), then ``results.json``,
        ``results.md``, the figure ``table2.png`` and ``pictures/`` (with the 3D viewer), all replacing
        ``out`` in one step once written (an error leaves it as it was).

        Args:
            data: dataset folder (default: the run's training data root).
            settings: what to measure and write (:class:`EvalSettings`; default: everything, the
                paper's protocol, the test split).
            out: the result folder (default :meth:`default_out`); replaced whole, refused unless it is new,
                empty or earlier evaluation results (:func:`~cerberus_core.plumbing.outputs.check_output`).
            baselines: ``{name: Run or model}`` drawn beside this one in the figure.
            verbose: print what is scored and the summary (:meth:`Evaluation.lines`).
        Raises:
            ConfigError: ``data`` is not a dataset folder (``key="data"``), or ``out`` may not be written.
        """
        start = time.perf_counter()
        s = check_kind("settings", settings, EvalSettings, "an EvalSettings") if settings is not None else EvalSettings()
        s = s if s.input_look is not None else replace(s, input_look=self.config.data.input_look)
        for name, baseline in (baselines or {}).items():
            check_kind(f"baselines[{name!r}]", baseline, (Run, Cerberus), "a Run or a Cerberus model")
        data = None if data is None else open_data(check_path("data", data)).root
        keep = [] if self.shipped else [Path(self.source)]
        out = check_path("out", out) if out is not None else self.default_out()
        check_output(out, "eval", keep=[*keep, *([data] if data else [])])
        baseline_models = {name: b.model if isinstance(b, Run) else b for name, b in (baselines or {}).items()}
        if data is None and not Dataset.is_dataset(self.data_root):
            raise ConfigError.about("data", None, f"needed: the run's training data {self.data_root} is not a dataset "
                                    "folder from here; give the dataset")
        source = Dataset.open(data or self.data_root)
        dataset = source.views(s.split)
        dataset.scene  # noqa: B018 - read (and checked) now, not midway through the evaluation
        if s.input_look != "shaded":
            dataset = LookedViews(dataset, s.input_look)
        for note in self.domain_notes(data or self.data_root):
            warnings.warn(f"{note}: the scores measure the model outside what it learned", UserWarning, stacklevel=2)
        backend = make_renderer(s.renderer or self.config.renderer)
        weights, at_step = self.weights_info, "" if self.step is None else f" at step {self.step}"
        if verbose:
            look = "" if s.input_look == "shaded" else f", the test images in the {s.input_look} input look"
            print(f"evaluating {printable(self.path)}{at_step}{look}")
        if weights.stale_warning():
            warnings.warn(weights.stale_warning(), UserWarning, stacklevel=2)
        with writing_results(out, "eval") as tmp:  # out is replaced only once all is written
            whole_poses = needed(s.skip, "poses")  # depth compares the views of each pose: keep a pose's together
            indices = limited_indices(dataset, s.limit, whole_poses=whole_poses)
            # one ground-truth grid cache for scores and figure
            scorer = VoxelScorer(s.protocol, s.resolution, gt_open_mesh=s.gt_open_mesh)
            result = evaluate_dataset(dataset, self.model.reconstruct, s, indices=indices, renderer=backend,
                                      device=self.device, scorer=scorer)
            look = "" if s.input_look == "shaded" else f", {s.input_look} input look"
            page = ViewerPage(title=f"cerberus eval: {printable(self.source)}{at_step} ({s.split} split{look})",
                              limit=s.viewer_images, limit_hint="viewer_images",
                              part_labels=result.part_labels() or self.part_labels())
            evaluation_figures(backend, dataset, FigureModels(self.model, baseline_models, self.device, s.progress),
                               tmp, n_images=s.figure_images, scorer=scorer, page=page, ious=result.image_ious())
            selection = ("all" if len(indices) == len(dataset) else
                         "whole poses, spread evenly" if whole_poses else "spread evenly")
            scored = {"root": str(source.root), "dataset": source.name, "preset": source.manifest.preset,
                      "split": s.split, "split_images": len(dataset), "limit": s.limit, "selection": selection,
                      "images": len(indices)}
            self._write_report(result, tmp, at_step, backend, s.input_look, scored, time.perf_counter() - start,
                               data_id=source.manifest.split(s.split).content_id)
        evaluation = Evaluation(result, out, weights, hard_requested="hard" not in s.skip, viewer=s.viewer_images > 0,
                                canonical_hint=_canonical_hint(source), split_images=len(dataset), data=scored)
        if verbose:
            print("\n".join(evaluation.lines()))
        return evaluation

    def reconstruct_images(self, images: Sequence[str | Path], out: str | Path, *,
                           masks: Sequence[str | Path] | str | None = None,
                           data: str | Path | None = None, azimuth: float = 0.0, renderer: str | None = None,
                           viewer_images: int = 12, fit: int = FIT_STEPS) -> Reconstruction:
        """Reconstruct image files: what ``cerberus reconstruct`` does (meshes, Figure 1's pictures,
        the 3D viewer; :func:`cerberus_core.reconstruct.write.write_reconstructions`).

        Args:
            images: the input files.
            out: the result folder, replaced whole once everything is written; refused when it holds an
                input or mask, or unless it is new, empty or earlier reconstructions
                (:func:`~cerberus_core.plumbing.outputs.check_output`).
            masks: the body's silhouette per image (or one folder of ``NAME.png``), or ``"auto"``: the person
                found in each image by the photo extra's segmenter (:mod:`cerberus_core.photo_mask`; its mask
                is written beside the result); an RGBA input's
                alpha is used without one.
            data: a dataset whose scene set-up the images follow (default: the run's recorded one).
            azimuth: the camera azimuth assumed for the inputs, degrees.
            renderer: the backend for the pictures (default: the run's).
            viewer_images: cards in ``out/index.html`` (0: no viewer).
            fit: steps of fitting each reconstruction that has a silhouette (a mask, ``"auto"``, an alpha channel)
                to it after the network's prediction (:mod:`cerberus_core.reconstruct.fit`; 0: the network's own).
        """
        check_value("viewer_images", viewer_images, Range(ge=0, integer=True), "0: no viewer")
        check_value("fit", fit, Range(ge=0, integer=True), "0: the network's prediction, not fitted")
        check_value("azimuth", azimuth, Range())
        images = check_paths("images", images)
        if not images:
            raise ConfigError.about("images", None, "no image given; pass at least one image file")
        if isinstance(masks, str) and masks == AUTO:
            require_segmenter()  # before anything is read or written
            mask_list: list = [AUTO] * len(images)
        else:
            mask_list = mask_paths(check_paths("masks", masks) if masks else None, images)
        keep = images + [m for m in mask_list if isinstance(m, Path)] + ([] if self.shipped else [Path(self.source)])
        out = check_path("out", out)
        check_output(out, "reconstruct", keep=keep)
        trained = TrainedModel(self.model, self.scene_for(data), int(self.config.data.image_size or 64),
                               renderer or self.config.renderer, self.device, self.training_kind(),
                               self.config.data.input_look)
        page = ViewerPage(title=f"cerberus reconstruct: {printable(self.source)}", limit=viewer_images,
                          limit_hint="viewer_images", part_labels=self.part_labels())
        return write_reconstructions(trained, ImageInputs(images, mask_list, azimuth), out, page, fit=fit)

    def _write_report(self, result: EvaluationResult, folder: Path, at_step: str, backend: Renderer,
                      input_look: str = "shaded", data: dict | None = None, total_seconds: float | None = None,
                      data_id: str | None = None) -> None:
        """``results.json`` (the scores, which weights, the input look, where they were computed: renderer,
        device, dtype; the identity of the split's content, ``data_id``
        (:attr:`~cerberus_core.datasets.manifest.SplitRecord.content_id`: ``cerberus compare`` pairs only
        evaluations of the same); which images: ``data``, the dataset folder, its name and preset, split, limit and
        the images scored; and the whole command's wall time, ``total_seconds``, beside the pass's ``seconds``) and
        ``results.md`` (with the stale warning; its title says "N of M images" when a limit chose some)."""
        weights = self.weights_info
        record = to_jsonable(result) | {"model": {"path": str(weights.path), "step": weights.step,
                                                  "newer_checkpoint": None if weights.newer is None else
                                                  {"path": str(weights.newer), "step": weights.newer_step}},
                                        "computed_with": {"renderer": backend.name, "device": str(self.device),
                                                          "dtype": str(next(self.model.parameters()).dtype)},
                                        "input_look": input_look, "data_id": data_id, "data": data,
                                        "total_seconds": None if total_seconds is None else round(total_seconds, 3)}
        write_json(record, folder / RESULTS)
        look = "" if input_look == "shaded" else f" ({input_look} input look)"
        count = len(result.records)
        limited = f", {images_scored(count, data)}" if data and data.get("split_images", count) > count else ""
        report = markdown_report(record, title=f"Evaluation of {self.source}{at_step}{look}{limited}")
        if weights.stale_warning():
            title, _, rest = report.partition("\n")
            report = f"{title}\n\n> **Warning:** {md_text(weights.stale_warning())}\n{rest}"
        write_text(report, folder / "results.md")


__all__ = ["EvalSettings", "Evaluation", "Run"]
