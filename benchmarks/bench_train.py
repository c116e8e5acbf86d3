"""Training speed: steps per second of the ``cpu`` preset and of the ``paper`` preset's network, and
the share of each step spent rendering.

For each preset and each renderer backend (``--renderers``, default torch and warp) the script builds the model and optimiser, takes one batch of the preset's batch size
from a small ``primitives`` dataset rendered at the preset's training resolution (generated into a
temporary folder, or ``--data ROOT``), runs a few warm-up steps, then times full optimisation steps
(objective, backward, Adam). The rendering share is the time of the step's render call alone
(forward and backward of ``render_parts`` on the same scenes, all 8 B of them, anti-aliased when the
preset's ``render.antialias`` is on) over the step time.

    python benchmarks/bench_train.py                 # 2 threads, both presets, both backends
    python benchmarks/bench_train.py --threads 1 --steps 5 --renderers warp
    python benchmarks/bench_train.py --device cuda --renderers torch --steps 50 --warmup 10   # on a GPU
    python benchmarks/bench_train.py --switches --presets cpu --renderers warp --threads 1 --steps 20

``--precision`` times the preset with ``speed.autocast`` at ``null`` (float32), ``bf16`` and ``auto``
side by side (its other switches as the preset has them), interleaved like ``--switches``, and prints
the CPU's bfloat16 flags and what ``auto`` picked on this machine:

    python benchmarks/bench_train.py --precision --presets cpu --renderers warp --threads 1 --steps 20

``--losses NAME=W [...]`` times loss terms the same way (the preset as it is, then each ``losses.NAME``
at weight ``W`` alone, interleaved): what a term beyond the preset adds to a step, e.g. issue 30's limb
terms on human data:

    python benchmarks/bench_train.py --losses coverage=0.3 keypoint_coverage=0.1 overlap=0.1 rotation=0.1 \
        --presets cpu --renderers warp --threads 1 --steps 20 --data DATA --cpu-time

On a machine other jobs load, ``--cpu-time`` times the process's CPU seconds instead of wall-clock (with
one thread, the step's own work, without the waits for the other jobs).

``--switches [NAME ...]`` times the training speed switches instead (``speed.autocast: bf16``,
``speed.channels_last``, ``speed.compile``, ``speed.smoothness_once``; all of them without NAMEs):
one model per variant (off, each switch alone, all together), steps interleaved round by round,
medians and the speed-up over ``off``, with each variant's first-step loss (same weights, same
batch: they differ by rounding only).

Timings on a shared machine are noisy: the load average is printed with the results.
"""
from __future__ import annotations

import argparse
import os
import statistics
import tempfile
import time
from pathlib import Path

import torch


def make_data(root: Path, image_size: int) -> Path:
    from dataclasses import replace

    from cerberus_core.datasets.dataset import Dataset
    from cerberus_core.datasets.plan import preset_config
    from cerberus_core.datasets.settings import SplitConfig

    cfg = preset_config("primitives", "tiny", image_size=image_size)
    cfg = replace(cfg, splits={"train": SplitConfig("pairs", subjects=2, pairs=16, meshes=False)})
    Dataset.generate(cfg, root, progress=False, log=lambda _: None)
    return root


def setup(preset: str, renderer_name: str, data_root: Path, batch_size: int | None, device: str = "cpu"):
    """The preset's config (depth offset resolved), the scene, one batch on ``device`` and the renderer."""
    from cerberus_core import make_renderer, resolve_renderer
    from cerberus_core.datasets.readers import QuadrupletDataset
    from cerberus_core.train.config import load_config
    from cerberus_core.train.data import quadruplet_batch

    cfg = load_config(preset=preset)
    data = QuadrupletDataset(data_root)
    scene = data.scene
    cfg.model.depth_offset = scene.distance
    bsz = batch_size or cfg.train.batch_size
    size = cfg.data.image_size or data.image_size
    renderer_name = resolve_renderer(renderer_name)
    raw = torch.utils.data.default_collate([data[i % len(data)] for i in range(bsz)])
    batch = quadruplet_batch(raw, torch.device(device), scene, size)
    return cfg, scene, batch, renderer_name, make_renderer(renderer_name)


def stepper(cfg, scene, batch, renderer, speed=None):
    """A fresh model (seed 0, with the speed switches ``speed`` applied, on the batch's device), its
    Adam, and a function running one full optimisation step ``i`` that returns the step's loss."""
    from cerberus_core.model import Cerberus
    from cerberus_core.train.objective import quadruplet_objective
    from cerberus_core.train.speed import SpeedConfig, apply_speed

    speed = speed or SpeedConfig()
    torch.manual_seed(0)
    model = apply_speed(Cerberus(cfg.model).to(batch.images.device), speed)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.optim.lr)

    def step(i: int) -> float:
        out = quadruplet_objective(model, renderer, batch, scene, cfg.losses, torch.Generator().manual_seed(i),
                                   smoothness_once=speed.smoothness_once, antialias=cfg.render.antialias)
        opt.zero_grad(set_to_none=True)
        out.total.backward()
        opt.step()
        return float(out.total.detach())
    return model, step


def sync(device: torch.device) -> None:
    """Wait for the device's queued work, so a timer reads finished work (a no-op on the CPU)."""
    if device.type == "cuda":
        torch.cuda.synchronize(device)


def bench(preset: str, renderer_name: str, data_root: Path, steps: int, warmup: int, batch_size: int | None,
          device: str = "cpu") -> dict:
    from cerberus_core.losses import viewpoint_scenes
    from cerberus_core.render.api import render_parts
    from cerberus_core.render.camera import Camera
    from cerberus_core.train.objective import partner_cameras, unwrap

    cfg, scene, batch, renderer_name, renderer = setup(preset, renderer_name, data_root, batch_size, device)
    bsz, size = batch.num_quadruplets, batch.images.shape[-1]
    model, step = stepper(cfg, scene, batch, renderer)
    dev = batch.images.device

    for i in range(warmup):
        step(i)
    sync(dev)
    t0 = time.perf_counter()
    for i in range(steps):
        step(warmup + i)
    sync(dev)
    step_s = (time.perf_counter() - t0) / steps

    # The same render call as the objective's, on the current predictions, forward + backward.
    with torch.no_grad():
        pred = model(batch.images.flatten(0, 1))
        rot, trans, _, _ = unwrap(model).world_pose(pred, batch.camera)
        n, v = pred.local_vertices.shape[1:3]
        own, cross = viewpoint_scenes(pred.local_vertices.view(bsz, 4, n, v, 3), rot.view(bsz, 4, n, 3, 3),
                                      trans.view(bsz, 4, n, 3))
    if cfg.losses.viewpoint_consistency:
        verts = torch.cat([own.flatten(0, 1), cross.flatten(0, 1)])
        cams = Camera.cat([batch.camera, partner_cameras(batch.camera, bsz)])
    else:
        verts, cams = own.flatten(0, 1), batch.camera
    verts.requires_grad_(True)
    grad = torch.rand(verts.shape[0], 3, size, size, device=dev)

    def render_once():
        img = render_parts(renderer, verts, model.faces, cams, scene.light(cams), albedo=scene.albedo,
                           background=scene.background, antialias=cfg.render.antialias).image
        img.backward(grad)

    render_once()
    sync(dev)
    t0 = time.perf_counter()
    for _ in range(steps):
        render_once()
    sync(dev)
    render_s = (time.perf_counter() - t0) / steps
    return {"preset": preset, "renderer": renderer_name, "device": str(dev), "batch": bsz, "size": size, "width": cfg.model.width, "images": 4 * bsz,
            "renders": verts.shape[0], "step_s": step_s, "steps_per_s": 1 / step_s, "render_s": render_s,
            "render_share": render_s / step_s}


SWITCHES = {"autocast": {"autocast": "bf16"}, "channels_last": {"channels_last": True}, "compile": {"compile": True},
            "smoothness_once": {"smoothness_once": True}}
"""``--switches`` names and the ``speed:`` settings (:mod:`cerberus_core.train.speed`) each one turns on."""


def switch_variants(names: list[str]) -> list[tuple[str, dict]]:
    """``off``, each named switch alone, and (with two or more) all of them together."""
    variants = [("off", {})] + [(n, SWITCHES[n]) for n in names]
    if len(names) > 1:
        variants.append(("+".join(names), {k: v for n in names for k, v in SWITCHES[n].items()}))
    return variants


def precision_variants(preset: str) -> list[tuple[str, dict]]:
    """``fp32``, ``bf16`` and ``auto``: the preset's speed switches with ``speed.autocast`` set to each."""
    from dataclasses import asdict

    from cerberus_core.train.config import load_config

    base = asdict(load_config(preset=preset).speed)
    return [(label, base | {"autocast": value}) for label, value in (("fp32", None), ("bf16", "bf16"), ("auto", "auto"))]


def loss_variants(settings: list[str]):
    """For ``--losses``: ``preset`` (its speed switches and loss weights as they are), then each
    ``NAME=W`` setting alone on top, as ``variants_of(preset)`` of :func:`bench_switches`."""
    from dataclasses import asdict

    from cerberus_core.train.config import load_config

    def variants(preset: str) -> list[tuple[str, dict, dict]]:
        base = asdict(load_config(preset=preset).speed)
        pairs = [s.split("=", 1) for s in settings]
        return [(preset, base, {})] + [(f"+ {k}={w}", base, {k: float(w)}) for k, w in pairs]
    return variants


def bench_switches(preset: str, renderer_name: str, data_root: Path, steps: int, warmup: int,
                   batch_size: int | None, names: list[str] | None, variants_of=None,
                   timer=time.perf_counter) -> list[dict]:
    """Full steps of one model per switch variant, interleaved: each round times one step of every
    variant in turn (so load changes hit all alike); the median over rounds is reported. The variants
    are :func:`switch_variants` of ``names``, or ``variants_of(preset)``: ``(label, speed settings)``
    or ``(label, speed settings, loss weights)``."""
    from dataclasses import replace

    from cerberus_core.train.speed import SpeedConfig

    cfg, scene, batch, renderer_name, renderer = setup(preset, renderer_name, data_root, batch_size)
    variants = []
    for label, speed, *weights in (variants_of(preset) if variants_of else switch_variants(names)):
        config = replace(cfg, losses=replace(cfg.losses, **weights[0])) if weights else cfg
        _, step = stepper(config, scene, batch, renderer, SpeedConfig(**speed))
        t0 = time.perf_counter()
        first = step(0)  # the first step's loss (same weights and batch for every variant)
        for i in range(1, warmup):
            step(i)
        variants.append({"label": label, "step": step, "first_loss": first, "warmup_s": time.perf_counter() - t0,
                         "times": []})
    for i in range(steps):
        for v in variants:
            t0 = timer()
            v["step"](warmup + i)
            v["times"].append(timer() - t0)
    rows = []
    for v in variants:
        step_s = statistics.median(v["times"])
        rows.append({"preset": preset, "renderer": renderer_name, "switches": v["label"], "step_s": step_s,
                     "steps_per_s": 1 / step_s, "first_loss": v["first_loss"], "warmup_s": v["warmup_s"]})
    for r in rows:
        r["speedup"] = rows[0]["step_s"] / r["step_s"]
    return rows


def print_cpu_precision() -> None:
    """The CPU's vector and bfloat16 flags, and what ``speed.autocast: auto`` picks on it."""
    from cerberus_core.devices import NATIVE_BF16_FLAGS, cpu_flags
    from cerberus_core.train.speed import resolve_autocast

    picked, why = resolve_autocast("auto", "cpu")
    have = sorted(f for f in cpu_flags() if f.startswith(("avx", "amx")) or f in NATIVE_BF16_FLAGS)
    print(f"CPU flags: {' '.join(have) or 'none of avx/amx/bf16'}")
    print(f"speed.autocast auto -> {picked or 'null (float32)'} ({why})")


def print_switches(rows: list[dict]) -> None:
    w = max(10, *(len(r["switches"]) + 2 for r in rows))
    base = "x " + rows[0]["switches"]
    head = f"{'preset':<8}{'renderer':>9}  {'switches':<{w}}{'s/step':>8}{'steps/s':>9}{base:>{max(7, len(base) + 1)}}" \
           f"{'loss 1st step':>15}{'warm-up s':>11}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['preset']:<8}{r['renderer']:>9}  {r['switches']:<{w}}{r['step_s']:>8.3f}{r['steps_per_s']:>9.2f}"
              f"{r['speedup']:>{max(7, len(base) + 1)}.2f}{r['first_loss']:>15.7f}{r['warmup_s']:>11.1f}")


def run_switches(args: argparse.Namespace) -> None:
    """``--switches`` / ``--precision``: the variants side by side, interleaved."""
    from cerberus_core.train.config import load_config

    names = None if args.precision or args.losses else (args.switches or list(SWITCHES))
    if names and "compile" in names:
        args.warmup = max(args.warmup, 3)  # compilation, then its recompilation-free steady state
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for preset in args.presets:
            root = args.data or make_data(Path(tmp) / preset, load_config(preset=preset).data.image_size or 64)
            for name in args.renderers:
                rows += bench_switches(preset, name, root, args.steps, args.warmup, args.batch_size, names,
                                       loss_variants(args.losses) if args.losses else
                                       precision_variants if args.precision else None,
                                       time.process_time if args.cpu_time else time.perf_counter)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\ntorch {torch.__version__}, {args.threads} threads, load average {load:.1f} (on {os.cpu_count()} "
          f"CPUs), median of {args.steps} interleaved rounds after {args.warmup} warm-up steps"
          + (", CPU seconds of this process (time.process_time)" if args.cpu_time else ""))
    if args.precision:
        print_cpu_precision()
    print_switches(rows)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--presets", nargs="+", default=["cpu", "paper"], help="training presets to time")
    p.add_argument("--renderers", nargs="+", default=["torch", "warp"],
                   help="renderer backends to time each preset with (default: torch warp; 'auto' as training picks)")
    p.add_argument("--threads", type=int, default=2, help="torch CPU threads (default 2)")
    p.add_argument("--steps", type=int, default=5, help="timed steps per preset")
    p.add_argument("--warmup", type=int, default=2, help="untimed steps first")
    p.add_argument("--batch-size", type=int, default=None, help="override the presets' batch sizes")
    p.add_argument("--data", type=Path, default=None, help="a quadruplet dataset (default: generate primitives)")
    p.add_argument("--device", default="cpu",
                   help="device of the timed steps: cpu (default) or cuda[:N] (the renderer follows the tensors; "
                        "not with --switches/--precision)")
    p.add_argument("--precision", action="store_true",
                   help="instead: time speed.autocast null (fp32), bf16 and auto side by side, interleaved, "
                        "with the preset's other speed switches")
    p.add_argument("--switches", nargs="*", default=None, choices=sorted(SWITCHES), metavar="NAME",
                   help="instead: time the speed switches (speed.* of the config) side by side, interleaved: "
                        "off, each NAME alone and all NAMEs together (default with no NAME: "
                        f"{' '.join(SWITCHES)}); the median of --steps rounds")
    p.add_argument("--cpu-time", action="store_true",
                   help="with --switches/--precision/--losses: time the process's CPU seconds (time.process_time), "
                        "not wall-clock, so waits for other jobs on a loaded machine do not count")
    p.add_argument("--losses", nargs="+", default=None, metavar="NAME=W",
                   help="instead: time the preset, then each losses.NAME at weight W alone on top, interleaved")
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    from cerberus_core.train.config import load_config

    if args.switches is not None or args.precision or args.losses:
        if args.device != "cpu":
            p.error("--switches, --precision and --losses time the CPU; leave out --device")
        run_switches(args)
        return
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for preset in args.presets:
            root = args.data
            if root is None:
                size = load_config(preset=preset).data.image_size or 64
                root = Path(tmp) / f"prim{size}"
                if not root.exists():
                    make_data(root, size)
            for name in args.renderers:
                rows.append(bench(preset, name, root, args.steps, args.warmup, args.batch_size, args.device))
                r = rows[-1]
                print(f"  {preset} / {r['renderer']}: {r['step_s']:.3f} s/step", flush=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    where = torch.cuda.get_device_name(args.device) if args.device.startswith("cuda") else "CPU"
    print(f"\ntorch {torch.__version__}, {where}, {args.threads} threads, load average {load:.1f} "
          f"(on {os.cpu_count()} CPUs), {args.steps} timed steps after {args.warmup} warm-up")
    head = f"{'preset':<14}{'renderer':>9}{'batch':>6}{'px':>5}{'width':>6}{'images':>7}{'renders':>8}{'s/step':>9}" \
           f"{'steps/s':>9}{'render s':>10}{'render %':>9}"
    print(head)
    print("-" * len(head))
    for r in rows:
        print(f"{r['preset']:<14}{r['renderer']:>9}{r['batch']:>6}{r['size']:>5}{r['width']:>6}{r['images']:>7}{r['renders']:>8}"
              f"{r['step_s']:>9.3f}{r['steps_per_s']:>9.3f}{r['render_s']:>10.3f}{100 * r['render_share']:>8.1f}%")
    base = {r["renderer"]: r for r in rows if r["preset"] == rows[0]["preset"]}
    for r in rows:
        if r["preset"] != rows[0]["preset"] and r["renderer"] in base:
            print(f"{r['preset']} step / {rows[0]['preset']} step ({r['renderer']}): "
                  f"{r['step_s'] / base[r['renderer']]['step_s']:.2f}x")
    by = {(r["preset"], r["renderer"]): r for r in rows}
    for preset in dict.fromkeys(r["preset"] for r in rows):
        if (preset, "torch") in by and (preset, "warp") in by:
            print(f"{preset}: torch step / warp step = "
                  f"{by[preset, 'torch']['step_s'] / by[preset, 'warp']['step_s']:.2f}")


if __name__ == "__main__":
    main()
