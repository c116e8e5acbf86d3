"""The generation driver: plan → pose → render in batches → write shards atomically → manifest.

Resumable and deterministic: the plan (:mod:`cerberus_core.datasets.plan`) is a pure function of the
config, every shard is rebuilt from it alone, and the manifest lists a shard (with the sha256 of its
files) only after its files are complete on disk. Rerunning the same config in the same folder skips
the finished shards; a config that differs from the folder's refuses unless ``overwrite=True``, which
replaces only a dataset the toolkit wrote (``docs/outputs.md``).
"""
from __future__ import annotations

import hashlib
import os
import shutil
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from cerberus_core.bodies.body import BodySource, PosedBody, source_class, source_contract
from cerberus_core.datasets.format import (
    DatasetError,
    check_shard_files,
    clean_temporaries,
    config_hash,
    pack_meshes,
    write_shard,
)
from cerberus_core.datasets.manifest import (
    MANIFEST,
    Manifest,
    ShardRecord,
    SourceRecord,
    SplitRecord,
    SubjectRecord,
    jsonable,
)
from cerberus_core.datasets.plan import DatasetPlan, ShardPlan, make_plan
from cerberus_core.datasets.scene import SceneSetup
from cerberus_core.datasets.settings import GenerationConfig
from cerberus_core.devices import check_device
from cerberus_core.errors import BodyError, ConfigError
from cerberus_core.plumbing.machine import memory_bytes
from cerberus_core.plumbing.outputs import check_apart, check_output, write_marker
from cerberus_core.release import VERSION
from cerberus_core.render.api import render
from cerberus_core.render.backends import make_renderer, resolve_renderer
from cerberus_core.render.interface import Renderer

ShardCallback = Callable[[str, ShardRecord], None]


# ------------------------------------------------------------------------------------ validation
RENDER_BYTES_PER_PIXEL = 160
"""Memory one view takes per pixel while it is rendered (rasterizer and shading buffers), an upper
bound: measured 133-136 bytes with the torch backend and 65-70 with Warp (peak RSS growth of one
:func:`render_views` call of 16 views at 256 and 512 px on a CPU: ``benchmarks/bench_render_memory.py``)."""


@dataclass(frozen=True)
class GenerationJob:
    """A generation that passed :func:`validate_generation`: everything :func:`generate` needs.

    Attributes:
        config: the config with its renderer resolved (``auto`` → the backend) and the source's
            description filled in: what the manifest stores.
        source: the body source.
        source_options: the source's options as the manifest stores them
            (:meth:`BodySource.stored_options`).
        plan: the shard plan of every split.
        peak_bytes: the memory the largest shard needs while it is built (images and render buffers).
    """

    config: GenerationConfig
    source: BodySource
    source_options: dict[str, Any]
    plan: DatasetPlan
    peak_bytes: int

    def plan_lines(self) -> list[str]:
        """What ``cerberus data generate --dry-run`` prints: the dataset, its memory and scene, then
        the counts of each split."""
        config, plan = self.config, self.plan
        lines = [f"{config.dataset}/{config.preset}: {len(plan.subjects)} subjects, renderer {config.renderer}, "
                 f"about {self.peak_bytes / 2**30:.2f} GiB of memory per shard, scene {config.scene.to_dict()}"]
        for split in config.splits:
            t = plan.totals(split)
            lines.append(f"  {split:<6} {t['shards']:>5} shards {t['images']:>8} images {t['quadruplets']:>8} "
                         f"quadruplets {t['meshes']:>7} meshes")
        return lines


def _memory_places(device: str) -> list[tuple[str, int | None, bool]]:
    """``(what, bytes or None if unknown, holds the render buffers)`` for each memory a generation uses:
    this machine's RAM (the shard's images, and the render buffers on a CPU) and the GPU's."""
    ram = memory_bytes("cpu")
    if not device.startswith("cuda"):
        return [("this machine", ram, True)]
    return [("this machine", ram, False), (f"GPU {device}", memory_bytes(device), True)]


def validate_generation(config: GenerationConfig, *, source: BodySource | None = None,
                        source_options: Mapping[str, Any] | None = None, device: str = "cpu", batch_size: int = 64,
                        out: str | Path | None = None, overwrite: bool = False) -> GenerationJob:
    """Check a whole generation before anything is written (``--dry-run`` stops after this).

    Checks the device, the batch size, the body source (its optional packages installed) and its options,
    the renderer (resolved through the ``cerberus.renderers`` entry points and built once), the shard plan
    (split sizes: a split with subjects, subjects disjoint) and the memory the largest shard needs against the
    machine's (or the GPU's); with ``out``, also the folder (:func:`check_folder`: a file, another
    dataset or other files without ``overwrite``). The image size bound itself is
    :class:`GenerationConfig`'s; the folder's lock is the caller's (:mod:`cerberus_core.plumbing.lock`).

    Args:
        source: the body source, built by the caller (default: the source registered as ``config.dataset``,
            built from ``source_options`` checked by its ``Options``, posing on ``device``).
        source_options: the source's options (stored in the manifest: with ``source`` given, as they are).
        out, overwrite: the dataset folder to check, and whether it may be replaced.

    Raises:
        ConfigError: what is wrong and how to fix it (one line); plugin errors for the renderer.
    """
    check_device(device)
    if batch_size < 1:
        raise ConfigError.about("batch_size", batch_size, "must be >= 1")
    try:
        if source is None:
            cls = source_class(config.dataset)
            cls.check_packages()
            options = cls.options(source_options)
            source, stored = cls.from_options(options, device=device), cls.stored_options(options)
        else:
            type(source).check_packages()
            stored = dict(source_options or {})
        if out is not None:  # the meshes read stay apart from the output, before they are listed
            check_apart(Path(out), source.reads(), what="a dataset is written there")
        renderer = resolve_renderer(config.renderer)
        make_renderer(renderer)  # installed, imports, builds: before the manifest names it
        # The manifest names the backend that draws the images (``auto`` resolved).
        config = replace(config, source=jsonable(source.describe()), renderer=renderer)
        plan = make_plan(config, source)
    except ImportError as exc:  # a source's optional package missing (the sources' and the plan's checks are typed)
        raise ConfigError(str(exc), key="dataset", value=config.dataset) from exc
    views = max(len(s.views) for shards in plan.shards.values() for s in shards)
    pixels = config.image_size ** 2
    rendered = (config.image_size * config.supersample) ** 2  # each image is rendered supersampled
    images, buffers = views * 3 * pixels, min(batch_size, views) * rendered * RENDER_BYTES_PER_PIXEL
    for where, total, renders in _memory_places(device):
        need = images + buffers if renders else images
        if total is not None and need > total:
            raise ConfigError(f"image_size {config.image_size} needs about {need / 2**30:.1f} GiB of memory on "
                              f"{where} ({images / 2**30:.1f} GiB for a shard of {views} images"
                              + (f", {buffers / 2**30:.1f} GiB to render {min(batch_size, views)} views at once"
                                 if renders else "")
                              + f"), more than it has ({total / 2**30:.1f} GiB); lower `image_size`, `batch_size` "
                              "or `shard_images`", key="image_size", value=config.image_size)
    if out is not None:
        check_folder(Path(out), jsonable(config.to_dict()), overwrite)
    return GenerationJob(config, source, jsonable(stored), plan, images + buffers)


# ------------------------------------------------------------------------------------ rendering
def render_views(renderer: Renderer, bodies: list[PosedBody], mesh_index: np.ndarray, azimuth: np.ndarray,
                 scene: SceneSetup, image_size: int, *, batch_size: int = 64, device: str | torch.device = "cpu",
                 on_batch: Callable[[int], None] | None = None, supersample: int = 1) -> np.ndarray:
    """Render views of posed bodies with the scene set-up, in batches.

    Views of bodies that share a topology (faces) are batched together; each batch is one
    :func:`~cerberus_core.render.api.render` call.

    Args:
        bodies: ``M`` posed bodies.
        mesh_index: ``(N,)`` the body of each view.
        azimuth: ``(N,)`` degrees.
        batch_size: views per render call.
        on_batch: called with the number of views rendered after each batch.
        supersample: render at ``supersample * image_size`` and average each ``supersample`` x
            ``supersample`` block (a box filter in linear float, before quantisation).

    Returns:
        ``(N, 3, H, W)`` uint8 images (``round(255 * rgb)``).
    """
    n = len(mesh_index)
    out = np.empty((n, 3, image_size, image_size), dtype=np.uint8)
    topo: dict[bytes, int] = {}
    seen: dict[int, int] = {}  # id(faces) -> topology: sources usually share one faces array
    keys = []
    for b in bodies:  # group meshes by identical faces
        if id(b.faces) not in seen:
            seen[id(b.faces)] = topo.setdefault(hashlib.sha1(b.faces.tobytes()).digest(), len(topo))
        keys.append(seen[id(b.faces)])
    order = sorted(range(n), key=lambda i: (keys[mesh_index[i]], i))
    groups: list[list[int]] = []
    for i in order:
        if groups and keys[mesh_index[groups[-1][0]]] == keys[mesh_index[i]] and len(groups[-1]) < batch_size:
            groups[-1].append(i)
        else:
            groups.append([i])
    with torch.no_grad():
        for idx in groups:
            faces = torch.as_tensor(bodies[mesh_index[idx[0]]].faces, device=device)
            verts = torch.as_tensor(np.stack([bodies[mesh_index[i]].vertices for i in idx]), device=device)
            camera = scene.cameras(azimuth[idx], image_size * supersample, device=device)
            res = render(renderer, verts, faces, camera, scene.light(camera), albedo=scene.albedo,
                         background=scene.background)
            image = res.image.clamp(0, 1)
            if supersample > 1:
                image = torch.nn.functional.avg_pool2d(image, supersample)
            out[idx] = (image * 255 + 0.5).to(torch.uint8).cpu().numpy()
            if on_batch is not None:
                on_batch(len(idx))
    return out


def warm_up(renderer: Renderer, scene: SceneSetup, device: str | torch.device = "cpu") -> None:
    """Render one triangle (8 x 8 pixels) the way :func:`render_views` renders, so that a backend's one-time
    start happens now: Warp compiles its kernels into its cache on a machine's first use (announced by the
    backend; about 5 s on 2 CPU cores)."""
    verts = torch.tensor([[[-0.3, -0.3, 0.0], [0.3, -0.3, 0.0], [0.0, 0.3, 0.0]]], device=device)
    camera = scene.cameras(np.zeros(1), 8, device=device)
    with torch.no_grad():
        render(renderer, verts, torch.tensor([[0, 1, 2]], device=device), camera, scene.light(camera),
               albedo=scene.albedo, background=scene.background)


def build_bodies(source: BodySource, subjects: list[SubjectRecord], meshes: list[tuple[int, int]],
                 n_parts: int) -> list[PosedBody]:
    """Pose every (subject index, pose id) of a shard, one batched call per subject, and check them.

    Raises:
        BodyError: a body outside ``[-0.5, 0.5]^3`` or with part labels outside ``0..n_parts-1``.
    """
    by_subject: dict[int, list[int]] = {}
    for s, p in meshes:
        by_subject.setdefault(s, [])
        if p not in by_subject[s]:
            by_subject[s].append(p)
    built: dict[tuple[int, int], PosedBody] = {}
    for s, poses in by_subject.items():
        who = subjects[s].subject
        name = who.name
        with source_contract(source, f"bodies() of subject {name}"):
            bodies = source.bodies(who, poses)
        if len(bodies) != len(poses):
            raise BodyError(f"source {source.name} returned {len(bodies)} bodies for {len(poses)} poses of {name}; "
                            "BodySource.bodies must return one body per pose id")
        for p, b in zip(poses, bodies, strict=True):
            reach = float(np.abs(b.vertices).max()) if len(b.vertices) else 0.0
            if reach > 0.5 + 1e-6:
                raise BodyError(f"{source.name} body {name} pose {p} reaches {reach:.3f}, outside the unit cube "
                                 "[-0.5, 0.5]^3 every body must lie in (see cerberus_core.bodies.body)")
            if len(b.vertex_parts) and (b.vertex_parts.min() < 0 or b.vertex_parts.max() >= n_parts):
                raise BodyError(f"{source.name} body {name} pose {p}: part labels outside 0..{n_parts - 1}; label "
                                f"each vertex with a part of the source's {n_parts} `part_names`")
            built[(s, p)] = b
    return [built[m] for m in meshes]


# ------------------------------------------------------------------------------------ folder state
def _differences(a: Any, b: Any, prefix: str = "") -> list[str]:
    if isinstance(a, dict) and isinstance(b, dict):
        out = []
        for k in sorted(set(a) | set(b)):
            out += _differences(a.get(k), b.get(k), f"{prefix}.{k}" if prefix else str(k))
        return out
    return [] if a == b else [f"{prefix}: {a!r} (folder) vs {b!r} (requested)"]


def _remove_dataset(out: Path, splits: list[str]) -> None:
    """Delete what a dataset wrote in ``out`` (manifest, the split folders its manifest names, temporaries);
    nothing else."""
    (out / MANIFEST).unlink(missing_ok=True)
    for split in splits:
        if (out / split).is_dir() and not (out / split).is_symlink():
            shutil.rmtree(out / split)
    clean_temporaries(out)


def _readable_dataset(out: Path) -> bool:
    """Whether ``out``, unmarked, is a dataset an earlier version wrote (before :data:`MARKER`): its manifest
    reads as a Cerberus manifest. Such a folder is resumed or replaced like a marked one."""
    try:
        Manifest.read(out)
    except DatasetError:
        return False
    return True


def check_folder(out: Path, config: dict, overwrite: bool, *, holding_lock: bool = False) -> tuple[str, Manifest | None]:
    """What generating ``config`` (the manifest's form) into ``out`` will do; changes nothing. The folder
    must pass the one output rule (:func:`~cerberus_core.plumbing.outputs.check_output`: new, empty or a
    dataset the toolkit wrote; never a folder of other files, whatever ``overwrite`` says).

    Returns:
        ``(action, old)``: ``"new"`` (``out`` is missing or empty), ``"resume"`` (it holds this
        dataset; ``old`` is its manifest) or ``"overwrite"`` (``overwrite`` and it holds another
        dataset; ``old`` is the manifest replaced, if readable).

    Raises:
        ConfigError: ``out`` is a file, or holds anything but a dataset (:func:`check_output`).
        DatasetError: it holds another dataset and not ``overwrite``.
    """
    if not check_output(out, "dataset", legacy=_readable_dataset, holding_lock=holding_lock):
        return "new", None
    if not (out / MANIFEST).exists():  # marked, stopped before its manifest was written: nothing to keep
        return "overwrite", None
    try:
        old = Manifest.read(out)
    except DatasetError as exc:
        if not overwrite:
            raise DatasetError(f"{out} holds a dataset this version cannot resume ({exc}); pass `overwrite=True` to "
                               "replace it, or choose another `out`") from exc
        return "overwrite", None
    stored = jsonable(old.config.to_dict())
    if stored == config:
        return "resume", old
    if not overwrite:
        diff = "; ".join(_differences(stored, config)[:6])
        raise DatasetError(f"{out} holds a different dataset ({diff}); resume it with the same options, pass "
                           "`overwrite=True` to replace it, or choose another `out`")
    foreign = sorted(s for s in (config.get("splits") or {}) if s not in old.splits and os.path.lexists(out / s))
    if foreign:
        raise DatasetError(f"{out} holds {foreign[0]}, which the dataset there did not write, and the new dataset "
                           f"would write its split {foreign[0]!r} there; move it away, or choose another `out`")
    return "overwrite", old


def _prepare(out: Path, config: GenerationConfig, cfg: dict, overwrite: bool,
             log: Callable[[str], None]) -> Manifest | None:
    """Decide between a fresh run and a resume (:func:`check_folder`); return the manifest to resume from.
    The folder is marked as a dataset (:data:`MARKER`) before anything else is written into it."""
    action, old = check_folder(out, cfg, overwrite, holding_lock=True)
    if action == "overwrite":
        log(f"overwriting the dataset in {out}")
        _remove_dataset(out, list(old.splits) if old is not None else [])
    out.mkdir(parents=True, exist_ok=True)
    write_marker(out, "dataset")
    return old if action == "resume" else None


def _manifest(out: Path, config: GenerationConfig, cfg: dict, source: BodySource, source_options: dict,
              plan: DatasetPlan) -> Manifest:
    """The manifest of a dataset about to be generated: the plan's counts, no shard written yet."""
    splits = {}
    for name, split_cfg in config.splits.items():
        t = plan.totals(name)
        splits[name] = SplitRecord(split_cfg.layout, split_cfg.meshes, t["shards"], t["images"], t["quadruplets"],
                                   t["meshes"])
    return Manifest(dataset=config.dataset, preset=config.preset, config=config, config_sha256=config_hash(cfg),
                    scene=config.scene, image_size=config.image_size, part_names=tuple(source.part_names),
                    subjects=tuple(plan.subjects), source=SourceRecord(source.name, jsonable(source_options)),
                    splits=splits, generator={"cerberus_core": VERSION}, root=out)


# ------------------------------------------------------------------------------------ driver
def write_dataset(job: GenerationJob, out: str | Path, *, overwrite: bool = False, device: str = "cpu",
                  batch_size: int = 64, progress: bool = True, log: Callable[[str], None] = print,
                  on_shard: ShardCallback | None = None) -> Manifest:
    """Generate (or resume) the dataset of a validated ``job`` in ``out``: the engine of
    :meth:`cerberus_core.datasets.dataset.Dataset.generate`, which checks the job and holds the folder's
    lock around this call.

    Args:
        job: what :func:`validate_generation` gave.
        out: the dataset folder (created if needed).
        overwrite: replace a different dataset the toolkit wrote in ``out`` (its own files only).
        device: torch device for posing and rendering (not part of the dataset's identity).
        batch_size: views per render call (results do not depend on it).
        progress: show a tqdm bar.
        on_shard: called as ``on_shard(split, record)`` after each shard is listed in the manifest.

    Returns:
        The final manifest.

    Raises:
        DatasetError: ``out`` holds something else (see :func:`_prepare`).
    """
    out = Path(out)
    config, source, plan, source_options = job.config, job.source, job.plan, job.source_options
    cfg = jsonable(config.to_dict())
    resume = _prepare(out, config, cfg, overwrite, log)
    clean_temporaries(out)
    for split in config.splits:
        if not plan.shards[split]:
            log(f"split {split!r} has no subject and is left empty")
    manifest = _manifest(out, config, cfg, source, source_options, plan)
    done: dict[str, dict[int, ShardRecord]] = {s: {} for s in config.splits}
    if resume is not None:
        for split, info in resume.splits.items():
            for rec in info.shards:
                problems = check_shard_files(out, rec, checksums=True)
                if problems:
                    log(f"shard {split}/{rec.name} is damaged and will be rebuilt: {problems[0]}")
                elif split in done and rec.index < len(plan.shards[split]):
                    done[split][rec.index] = rec
        n_done = sum(len(d) for d in done.values())
        log(f"resuming {out}: {n_done} of {sum(len(s) for s in plan.shards.values())} shards already done")
    manifest = manifest.with_shards({split: done[split].values() for split in config.splits})
    manifest.write()

    todo: list[ShardPlan] = [s for split in config.splits for s in plan.shards[split] if s.index not in done[split]]
    if todo:
        # One-time costs before the bar, so it neither hides them nor counts them in its rate: the body
        # source's load (anny builds its model cache on a machine's first use) and the renderer's first call.
        source.prepare()
        renderer = make_renderer(config.renderer)
        warm_up(renderer, config.scene, device)
        from tqdm import tqdm

        bar = tqdm(total=sum(len(s.views) for s in todo), unit="img", disable=not progress,
                   desc=f"{config.dataset}/{config.preset}")
        try:
            for shard in todo:
                bar.set_postfix_str(f"{shard.split} shard {shard.index + 1}/{len(plan.shards[shard.split])}")
                rec = _build_shard(out, config, source, plan, shard, renderer, device, batch_size, bar.update)
                manifest = manifest.with_shard(shard.split, rec)
                manifest.write()
                if on_shard is not None:
                    on_shard(shard.split, rec)
        finally:
            bar.close()
    manifest = manifest.finished()
    manifest.write()
    return manifest


def _build_shard(out: Path, config: GenerationConfig, source: BodySource, plan: DatasetPlan, shard: ShardPlan,
                 renderer: Renderer, device: str, batch_size: int, on_batch: Callable[[int], None]) -> ShardRecord:
    bodies = build_bodies(source, plan.subjects, shard.meshes, len(source.part_names))
    images = render_views(renderer, bodies, shard.views["mesh"], shard.views["azimuth"], config.scene,
                          config.image_size, batch_size=batch_size, device=device, on_batch=on_batch,
                          supersample=config.supersample)
    views = shard.views.copy()
    meshes = None
    if config.splits[shard.split].meshes:
        meshes = pack_meshes(bodies, [s for s, _ in shard.meshes])
    else:
        views["mesh"] = -1
    return write_shard(out, shard.split, shard.index, images, views, shard.quads, meshes,
                       subjects=tuple(shard.subjects))
