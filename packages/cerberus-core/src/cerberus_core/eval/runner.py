"""One pass over a test set: standard voxel IoU and every diagnostic of
:data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS` (Hard Human, part quality, part visibility, depth across
views, body segments, allocation) together.

The model is any callable ``reconstruct(images (B, 3, H, W) in [0, 1], camera) -> PartSet``
(world-frame output; the camera is the one the image was rendered with, which the model needs to
unproject its translations); :meth:`cerberus_core.model.Cerberus.reconstruct` is one.
``cerberus eval`` (:meth:`cerberus_core.run.Run.evaluate`) wraps a trained checkpoint into that and calls
:func:`evaluate_dataset`, whose one loop feeds the per-metric accumulators of
:mod:`cerberus_core.eval.accumulators`.

Dataset contract (:class:`cerberus_core.datasets.readers.ViewDataset` follows it): ``len(ds)``; ``ds[i]``
a dict with ``images`` ``(3, H, W)`` float in [0, 1] (uint8 is accepted), ``azimuth``, ``elevation``
(degrees), ``distance``, ``fov_y`` (degrees), ``subject`` (a name, or an index into
``ds.subject_names``), ``pose``, ``view``, ``is_canonical``; ``ds.cameras(batch) -> Camera`` (the
cameras of a collated batch); and ``ds.gt_mesh(i) -> PosedBody``. Optional: ``ds.records`` or
``ds.metadata(i)``, to find the canonical images without reading every image.
"""
from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field, fields, replace
from typing import Any, Literal

import numpy as np
import torch
from tqdm import tqdm

from cerberus_core.config import check_known
from cerberus_core.errors import DatasetError, InputTypeError, ShapeError, UnknownEntryError
from cerberus_core.eval.accumulators import BatchResult, EvalContext, StandardIoU
from cerberus_core.eval.diagnostics import DIAGNOSTICS, check_eval_packages, check_skip, needed, running
from cerberus_core.eval.hard import CanonicalParts, ItemMeta, select_canonical
from cerberus_core.eval.standard import GroundTruthMemo, GtOpenMesh, IoUSummary, VoxelScorer
from cerberus_core.fields import Checked, ranged
from cerberus_core.parts import PartSet
from cerberus_core.plumbing.machine import MAX_WORKERS, capped_to_cores
from cerberus_core.plumbing.names import did_you_mean
from cerberus_core.render.backends import make_renderer
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Renderer

Tensor = torch.Tensor
Reconstructor = Callable[[Tensor, Camera], PartSet]


# ------------------------------------------------------------------ batches and cameras
def subject_label(dataset: Any, value: Any) -> str:
    """A subject's name: integer subject ids are looked up in ``dataset.subject_names`` if it has them.

    Example:
        >>> from types import SimpleNamespace
        >>> views = SimpleNamespace(subject_names=["alice", "bob"])
        >>> subject_label(views, torch.tensor(1)), subject_label(views, 0), subject_label(views, "carol")
        ('bob', 'alice', 'carol')
    """
    if isinstance(value, Tensor):
        value = value.item()
    names = getattr(dataset, "subject_names", None)
    if isinstance(value, (int, np.integer)) and names is not None:
        return str(names[int(value)])
    return str(value)


def dataset_metadata(dataset: Any) -> list[ItemMeta]:
    """Subject, pose, view and canonical flag of every item, read as cheaply as the dataset allows:
    ``dataset.records`` (a structured array with ``subject``, ``pose``, ``view``, ``canonical``, as
    :class:`~cerberus_core.datasets.readers.ViewDataset` has), else ``dataset.metadata(i)``, else
    ``dataset[i]``."""
    rec = getattr(dataset, "records", None)
    fields = {"subject", "pose", "view", "canonical"}
    if isinstance(rec, np.ndarray) and rec.dtype.names and fields <= set(rec.dtype.names):
        return [ItemMeta(i, subject_label(dataset, rec["subject"][i]), int(rec["pose"][i]), int(rec["view"][i]),
                         bool(rec["canonical"][i])) for i in range(len(rec))]
    getter = getattr(dataset, "metadata", None)
    out = []
    for i in range(len(dataset)):
        item = getter(i) if callable(getter) else dataset[i]
        try:
            out.append(ItemMeta(i, subject_label(dataset, item["subject"]), int(item["pose"]), int(item["view"]),
                                bool(item.get("is_canonical", False))))
        except KeyError as exc:
            raise missing_fields(i, [str(exc.args[0])]) from None
    return out


def missing_fields(index: int, names: Sequence[str]) -> DatasetError:
    """The error of a dataset item (``index``) that lacks the fields ``names`` the evaluation reads."""
    return DatasetError(f"dataset item {index} lacks the field{'s' if len(names) > 1 else ''} {', '.join(names)}; the "
                        "evaluation needs subject, pose, view (and is_canonical for the Hard Human test)")


def collate(items: Sequence[Mapping[str, Any]]) -> dict[str, Any]:
    """``default_collate``, with ``images`` as float32 in [0, 1] (uint8 images are divided by 255).

    Example: two ``(3, H, W)`` uint8 images, one white, one black, become a ``(B, 3, H, W)`` float batch:

        >>> white, black = torch.full((3, 2, 2), 255, dtype=torch.uint8), torch.zeros(3, 2, 2, dtype=torch.uint8)
        >>> batch = collate([{"images": white, "pose": 0}, {"images": black, "pose": 4}])
        >>> tuple(batch["images"].shape), batch["images"].dtype, batch["images"].amax().item(), batch["pose"].tolist()
        ((2, 3, 2, 2), torch.float32, 1.0, [0, 4])
    """
    batch = torch.utils.data.default_collate(list(items))
    images = batch["images"]
    batch["images"] = images.float() / 255.0 if images.dtype == torch.uint8 else images.float()
    return batch


def iterate_batches(dataset: Any, indices: Sequence[int], batch_size: int, num_workers: int = 0):
    """The items ``indices`` of ``dataset``, in that order, ``batch_size`` at a time (the last batch may be smaller).

    Args:
        dataset: see the module docstring (it must have ``cameras(batch)``).
        indices: the dataset indices to read; batch_size: images per batch; num_workers: data-loading workers.
    Yields:
        ``(batch indices, batch, cameras)``: the ``B`` dataset indices of the batch (a list of int), the items
        collated (:func:`collate`: ``batch["images"]`` ``(B, 3, H, W)`` float32 in [0, 1], every other field
        stacked, ``(B,)``) and the ``B`` cameras they were rendered with (:class:`Camera`, ``dataset.cameras(batch)``).
    Raises:
        InputTypeError: ``dataset`` has no ``cameras(batch)`` method.
    """
    subset = torch.utils.data.Subset(dataset, list(indices))
    loader = torch.utils.data.DataLoader(subset, batch_size=batch_size, shuffle=False, num_workers=num_workers,
                                         collate_fn=collate)
    if not callable(getattr(dataset, "cameras", None)):
        raise InputTypeError(f"{type(dataset).__name__} has no cameras(batch) method; the evaluation needs the "
                             "cameras the test images were rendered with (see "
                             "cerberus_core.datasets.readers.ViewDataset.cameras)")
    start = 0
    for batch in loader:
        n = batch["images"].shape[0]
        yield list(indices[start:start + n]), batch, dataset.cameras(batch)
        start += n


def reconstruct_batch(reconstruct: Reconstructor, images: Tensor, camera: Camera,
                      device: torch.device | str) -> PartSet:
    """Run the model without gradients; the result is a :class:`PartSet` on the CPU."""
    with torch.no_grad():
        recon = reconstruct(images.to(device), camera.to(device))
    if not isinstance(recon, PartSet):
        raise InputTypeError(f"the model must return a PartSet (cerberus_core.parts), got {type(recon).__name__}; "
                             "return `Cerberus.reconstruct`'s result from `reconstruct`")
    if recon.batch_size != images.shape[0]:
        raise ShapeError(f"the model returned {recon.batch_size} reconstructions for {images.shape[0]} images; "
                         "return one reconstruction per image")
    return recon.detach().to("cpu")


# ------------------------------------------------------------------ which images
def spread_evenly(count: int, n: int) -> list[int]:
    """``min(n, count)`` positions spread evenly over ``range(count)``, the first and the last included (each
    rounded to the nearest, half to even): the one rule by which the evaluation takes a few of many images
    (:func:`limited_indices`, the figure's images of :func:`~cerberus_core.eval.figures.evaluation_figures`).

    Example:
        >>> spread_evenly(12, 4), spread_evenly(8, 3), spread_evenly(3, 5), spread_evenly(5, 1), spread_evenly(0, 2)
        ([0, 4, 7, 11], [0, 4, 7], [0, 1, 2], [0], [])
    """
    return torch.linspace(0, count - 1, min(n, count)).round().long().unique().tolist()


def limited_indices(dataset: Any, limit: int | None, *, whole_poses: bool = False) -> list[int]:
    """The dataset indices an evaluation of at most ``limit`` images scores.

    All of them when ``limit`` is ``None`` or not below ``len(dataset)``. Else ``limit`` images spread evenly over
    the dataset (:func:`spread_evenly`): a test split is ordered by subject, pose and view, so its first images
    would be a few poses of one subject. With ``whole_poses`` (what the depth diagnostic needs: it compares the
    views of each pose, :data:`~cerberus_core.eval.diagnostics.NEEDS` ``"poses"``), whole poses spread evenly over
    the dataset's poses, as many as ``limit`` images hold (``limit // `` the most views a pose has), so every
    pose chosen is measured as in the whole split; when not even one pose fits, ``limit`` views of the first
    pose, spread evenly over its views. Subject and pose are read as cheaply as the dataset allows
    (:func:`dataset_metadata`).

    Example: 2 subjects x 3 poses x 2 views, in that order; 4 images, or the views of 2 poses:

        >>> class Views:  # what a test split tells of its items (ViewDataset reads its records instead)
        ...     items = [{"subject": s, "pose": p, "view": v} for s in "ab" for p in range(3) for v in range(2)]
        ...     def __len__(self): return len(self.items)
        ...     def metadata(self, i): return self.items[i]
        >>> views = Views()
        >>> limited_indices(views, 4), limited_indices(views, 4, whole_poses=True)
        ([0, 4, 7, 11], [0, 1, 10, 11])
        >>> limited_indices(views, 1, whole_poses=True)  # not one pose fits: a view of the first
        [0]
        >>> limited_indices(views, None) == limited_indices(views, 20) == list(range(12))
        True
    """
    count = len(dataset)
    if limit is None or limit >= count:
        return list(range(count))
    if not whole_poses:
        return spread_evenly(count, limit)
    poses: dict[tuple[str, int], list[int]] = {}
    for item in dataset_metadata(dataset):
        poses.setdefault((item.subject, item.pose), []).append(item.index)
    groups = list(poses.values())
    fits = limit // max(len(g) for g in groups)
    if fits == 0:
        return [groups[0][k] for k in spread_evenly(len(groups[0]), limit)]
    return [i for k in spread_evenly(len(groups), fits) for i in groups[k]]


# ------------------------------------------------------------------ results
@dataclass
class EvaluationResult:
    """Everything one evaluation measured.

    Attributes:
        protocol, resolution: the voxel-IoU protocol and grid size.
        standard: per-image voxel IoU, averaged overall and per subject/species.
        gt_open_mesh: what the metric did with a ground truth that is not watertight
            (:data:`~cerberus_core.eval.standard.GT_OPEN_MESH`; ``"error"``: refused it, so every ground truth scored
            was watertight).
        diagnostics: each diagnostic's entries (:meth:`Diagnostic.results
            <cerberus_core.eval.diagnostics.Diagnostic.results>`), in
            :data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS` order, ``None`` for one skipped: ``hard``
            (an :class:`IoUSummary`) and ``canonical`` (``{subject: dataset index}`` of the images the Hard
            Human shapes came from), ``part_quality``, ``part_visibility``, ``depth``, ``segments``,
            ``allocation`` (dicts; see each module). ``result["hard"]`` reads one.
        records: one dict per image: index, subject, pose, view, iou, clipped, error, then each
            diagnostic's fields (visible_pixels, hard_iou, ..., deletion_loss, keypoints, unique_coverage).
        seconds: wall time of :func:`evaluate_dataset`, in seconds: the model's pass over the images and every
            metric's summary (depth's renders included); not what a caller does after it (``cerberus eval``'s
            figures, pictures and viewer: its ``results.json`` records the whole command's time as
            ``total_seconds``).

    Example: a result made by hand (:func:`evaluate_dataset` makes them), the Hard Human test skipped:

        >>> records = [{"index": 0, "subject": "s1", "iou": 0.4}, {"index": 7, "subject": "s1", "iou": 0.6}]
        >>> result = EvaluationResult("kato", 32, IoUSummary(0.5, 2, {"s1": 0.5}), {"hard": None, "canonical": {}},
        ...                           records, seconds=1.23456)
        >>> result.image_ious(), "hard" in result, result["hard"]
        ({0: 0.4, 7: 0.6}, True, None)
        >>> d = result.to_dict()  # the JSON form (results.json); seconds rounded to ms
        >>> list(d), d["standard"]["per_group"], d["seconds"]
        (['protocol', 'resolution', 'gt_open_mesh', 'standard', 'hard', 'canonical', 'seconds', 'records'],
         {'s1': 0.5}, 1.235)
        >>> result["hrad"]
        Traceback (most recent call last):
        ...
        cerberus_core.errors.UnknownEntryError: EvaluationResult has no entry 'hrad' (did you mean 'hard'?); ...
    """

    protocol: str
    resolution: int
    standard: IoUSummary
    diagnostics: dict[str, Any] = field(default_factory=dict)
    records: list[dict[str, Any]] = field(default_factory=list)
    seconds: float = 0.0
    gt_open_mesh: str = "error"

    def __getitem__(self, key: str) -> Any:
        """A diagnostic's entry (``result["hard"]``, ``result["segments"]``), ``None`` when it was skipped; an
        :class:`~cerberus_core.errors.UnknownEntryError` (a ``KeyError``) naming the entries for another key."""
        if key not in self.diagnostics:
            raise UnknownEntryError(f"EvaluationResult has no entry {key!r}" + did_you_mean(str(key), self.diagnostics)
                                    + f"; its entries: {', '.join(self.diagnostics)}")
        return self.diagnostics[key]

    def __contains__(self, key: object) -> bool:
        """Whether the result has the entry ``key`` (a diagnostic's, skipped or not: ``"hard" in result``)."""
        return key in self.diagnostics

    def part_labels(self) -> list[str | None] | None:
        """Each learned part's label (the ground-truth part it covers most over the images scored; ``None`` where
        it covers none), in part order; ``None`` when part quality was not scored (not run, or no part labels)."""
        parts = (self.diagnostics.get("part_quality") or {}).get("parts") or []
        return [p["label"] for p in sorted(parts, key=lambda p: p["part"])] or None

    def image_ious(self) -> dict[int, float]:
        """``{dataset index: voxel IoU}`` of every image scored."""
        return {int(r["index"]): float(r["iou"]) for r in self.records if r.get("iou") is not None}

    def to_dict(self) -> dict[str, Any]:
        entries = {k: v.to_dict() if isinstance(v, IoUSummary) else v for k, v in self.diagnostics.items()}
        return {"protocol": self.protocol, "resolution": self.resolution, "gt_open_mesh": self.gt_open_mesh,
                "standard": self.standard.to_dict(), **entries, "seconds": round(self.seconds, 3),
                "records": self.records}


# ------------------------------------------------------------------ the pass
def extract_canonical(dataset: Any, reconstruct: Reconstructor, indices: dict[str, int], device: torch.device | str,
                      batch_size: int = 16) -> CanonicalParts:
    """Reconstruct each subject's canonical image once and keep its part shapes.

    Args:
        dataset: see the module docstring; reconstruct: the model (``(images, camera) -> PartSet``).
        indices: ``{subject: dataset index}`` of the canonical images (:func:`~cerberus_core.eval.hard.select_canonical`).
        device: the model's device; batch_size: images per forward pass.
    Returns:
        :class:`~cerberus_core.eval.hard.CanonicalParts`: per subject its canonical image's reconstruction (a
        :class:`PartSet` of batch 1, ``P`` parts, on the CPU, world frame) and the dataset index it came from.
    """
    subject_of = {idx: s for s, idx in indices.items()}
    shapes: dict[str, PartSet] = {}
    for batch_idx, batch, camera in iterate_batches(dataset, list(subject_of), batch_size):
        recon = reconstruct_batch(reconstruct, batch["images"], camera, device)
        for b, idx in enumerate(batch_idx):
            shapes[subject_of[idx]] = recon.index(b)
    return CanonicalParts(shapes, indices)


@dataclass(frozen=True)
class EvalConfig(Checked):
    """What one evaluation measures and how (:func:`evaluate_dataset`); checked when made.

    Attributes:
        protocol, resolution: voxel-IoU protocol (``kato``, 32: the paper's); the metric bounds both
            (:class:`cerberus_core.run.EvalSettings` checks them through its entry point before anything runs).
        gt_open_mesh: what the metric does with a ground truth that is not watertight
            (:data:`~cerberus_core.eval.standard.GT_OPEN_MESH`): ``"error"`` (default: the evaluation stops with a
            :class:`~cerberus_core.errors.DatasetError` naming the image, since the flood fill would score it as a
            hollow shell), ``"close"`` (its holes closed with pymeshlab, a warning each) or ``"warn"`` (scored as
            it is, a warning each). Recorded in the result (``gt_open_mesh``).
        skip: the diagnostics not to run, by name (:data:`~cerberus_core.eval.diagnostics.DIAGNOSTICS`:
            ``hard``, ``part_quality``, ``visibility``, ``depth``, ``segments``, ``allocation``, in its order; default: none
            skipped, every diagnostic runs). The standard IoU always runs.
        canonical_view: the view of the canonical pose to extract shapes from (default the lowest).
        batch_size, num_workers: model batching, data-loading workers.
        weighting: part-quality vertex weights, ``"area"`` or ``"count"``.
        density: part-quality surface lattice steps per predicted triangle edge (see
            :mod:`cerberus_core.eval.part_quality`).
        progress: show a progress bar.
    Raises:
        ConfigError: a field out of its range, or a name in ``skip`` that is not a diagnostic.

    Example:
        >>> config = EvalConfig(skip=("hard", "depth"), batch_size=4)
        >>> config.protocol, config.resolution, config.skip, config.batch_size
        ('kato', 32, ('hard', 'depth'), 4)
        >>> EvalConfig(batch_size=0)
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ConfigError: batch_size = 0: must be an integer >= 1 (EvalConfig(batch_size=...))
        >>> EvalConfig(skip=("hardd",))
        Traceback (most recent call last):
        ...
        cerberus_core.errors.ConfigError: skip = 'hardd': is not a diagnostic (did you mean 'hard'?); ...
    """

    FIX = "{cls}({key}=...)"

    protocol: str = "kato"
    resolution: int = ranged(32, integer=True)
    gt_open_mesh: GtOpenMesh = "error"
    skip: tuple[str, ...] = ()
    canonical_view: int | None = ranged(None, ge=0, integer=True)
    batch_size: int = ranged(16, ge=1)
    num_workers: int = ranged(0, ge=0, le=MAX_WORKERS)
    weighting: Literal["area", "count"] = "area"
    density: int = ranged(4, ge=1)
    progress: bool = True

    def validate(self) -> None:
        object.__setattr__(self, "skip", check_skip(self.skip))


def metric_accumulators(dataset: Any, reconstruct: Reconstructor, config: EvalConfig, scorer: VoxelScorer,
                        renderer: Renderer | None, device: torch.device | str) -> dict[str, Any]:
    """``{name: accumulator}`` of every diagnostic ``config`` does not skip, in table order (the order they
    fill each record), made from one :class:`EvalContext`; the renderer is made only when one of them
    needs it, the canonical shapes reconstructed only when the Hard Human test runs."""
    if renderer is None and needed(config.skip, "renderer"):
        renderer = make_renderer("auto")

    def canonical() -> CanonicalParts:
        chosen = select_canonical(dataset_metadata(dataset), config.canonical_view)
        if not chosen:  # no canonical image: the test scores nothing
            return CanonicalParts({}, {})
        return extract_canonical(dataset, reconstruct, chosen, device, config.batch_size)

    context = EvalContext(config, scorer, renderer, canonical)
    return {d.name: d.accumulator.for_evaluation(context) for d in running(config.skip)}


def batch_result(dataset: Any, batch: dict[str, Any], batch_idx: list[int], recon: PartSet, camera: Camera,
                 gt_memo: GroundTruthMemo) -> BatchResult:
    """What every metric needs of one batch: each image's identity, ground truth and record."""
    flags = batch.get("is_canonical", [False] * len(batch_idx))
    missing = [k for k in ("subject", "pose", "view") if k not in batch]
    if missing:
        raise missing_fields(batch_idx[0], missing)
    items = [ItemMeta(idx, subject_label(dataset, batch["subject"][b]), int(batch["pose"][b]), int(batch["view"][b]),
                      bool(flags[b])) for b, idx in enumerate(batch_idx)]
    bodies = [gt_memo.get((m.subject, m.pose), m.index) for m in items]
    records = [{"index": m.index, "subject": m.subject, "pose": m.pose, "view": m.view} for m in items]
    return BatchResult(recon, camera, items, bodies, records)


def evaluate_dataset(dataset: Any, reconstruct: Reconstructor, config: EvalConfig | None = None, *,
                     renderer: Renderer | None = None, indices: Sequence[int] | None = None,
                     device: torch.device | str = "cpu", scorer: VoxelScorer | None = None,
                     **options: Any) -> EvaluationResult:
    """Evaluate a model on a test set in one pass (one forward per image) that feeds one accumulator
    per metric (:mod:`cerberus_core.eval.accumulators`).

    Args:
        dataset: see the module docstring.
        reconstruct: ``(images, camera) -> PartSet`` in world coordinates.
        config: what to measure (:class:`EvalConfig`; default: everything, the paper's protocol).
        renderer: the backend of the part-visibility render (default ``make_renderer("auto")``).
        indices: evaluate these dataset indices only (default all). Canonical images are looked
            up in the whole dataset.
        device: the model's device.
        scorer: a prepared :class:`VoxelScorer` (e.g. with a disk-backed grid cache); its protocol, resolution and
            ``gt_open_mesh`` are the ones used and recorded, not ``config``'s.
        options: :class:`EvalConfig` fields that replace ``config``'s (``skip=("hard",)``, ``batch_size=6``...);
            another name is a :class:`~cerberus_core.errors.ConfigError` (:func:`~cerberus_core.config.check_known`).
    Raises:
        MissingPackageError: before anything runs, when a diagnostic that runs needs a package that is not
            installed (:func:`~cerberus_core.eval.diagnostics.check_eval_packages`).
        DatasetError: a ground truth the metric refuses (one not watertight while ``gt_open_mesh`` is ``"error"``),
            naming its image.
    """
    t0 = time.perf_counter()
    check_known(options, (f.name for f in fields(EvalConfig)))
    config = replace(config or EvalConfig(), **options)
    check_eval_packages(config.skip, metric=scorer is None)  # before any image is reconstructed
    scorer = scorer or VoxelScorer(config.protocol, config.resolution, gt_open_mesh=config.gt_open_mesh)
    indices = list(range(len(dataset))) if indices is None else [int(i) for i in indices]
    if not indices:
        raise DatasetError("evaluate_dataset: no images to evaluate (empty dataset or index list); pass a split that "
                           "holds views, or `indices=None`")
    if not callable(getattr(dataset, "gt_mesh", None)):
        raise InputTypeError(f"{type(dataset).__name__} has no gt_mesh(i) method; evaluation needs the ground-truth "
                             "meshes (pass a ViewDataset)")
    standard = StandardIoU(scorer)
    accumulators = metric_accumulators(dataset, reconstruct, config, scorer, renderer, device)
    gt_memo = GroundTruthMemo(dataset.gt_mesh)
    records: list[dict[str, Any]] = []
    # closed on the way out, an error's too, so that the error's line starts a line of its own
    with tqdm(total=len(indices), desc="evaluate", unit="img", disable=not config.progress) as bar:
        for batch_idx, batch, camera in iterate_batches(dataset, indices, config.batch_size,
                                                        capped_to_cores("num_workers", config.num_workers)):
            recon = reconstruct_batch(reconstruct, batch["images"], camera, device)
            result = batch_result(dataset, batch, batch_idx, recon, camera.to(device), gt_memo)
            for accumulator in (standard, *accumulators.values()):
                accumulator.update(result)
            records.extend(result.records)
            bar.update(len(batch_idx))
            bar.set_postfix(iou=f"{standard.running_mean():.4f}")
    entries: dict[str, Any] = {}
    for row in DIAGNOSTICS:
        entries |= row.results(accumulators.get(row.name))
    return EvaluationResult(
        protocol=scorer.protocol,
        resolution=scorer.resolution,
        standard=standard.summary(),
        diagnostics=entries,
        records=records,
        seconds=time.perf_counter() - t0,
        gt_open_mesh=getattr(scorer, "gt_open_mesh", config.gt_open_mesh),
    )
