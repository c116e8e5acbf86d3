"""Benchmark: dataset generation speed (images per second) and projected preset times.

Measures, on ``--threads`` CPU threads (default 2), each stage of human-dataset generation at
``--image-size`` (default 64): anny model load, per-subject scale, posing (bodies/s, batched), and
rendering (images/s, batches of ``--batch``) with every installed renderer backend; then one real
end-to-end ``generate`` run (posing + rendering + atomic shard writes) per backend. From these it
projects the wall time of the ``small`` and ``paper`` presets (targets: under 5 minutes and under
2 hours). ``--source primitives`` benchmarks the capsule-figure source instead.

Run:  python benchmarks/bench_data.py [--pairs 64] [--threads 2] [--source human|primitives]
"""
from __future__ import annotations

import argparse
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import torch

from cerberus_core.bodies.body import source_class
from cerberus_core.datasets.dataset import Dataset
from cerberus_core.datasets.generate import render_views
from cerberus_core.datasets.plan import make_plan, preset_config
from cerberus_core.datasets.settings import GenerationConfig, SplitConfig
from cerberus_core.render.backends import available_renderers, make_renderer

CPU = {"wall": 0.0, "cpu": 0.0}
"""Totals of wall-clock and process CPU seconds over every timed call (to report machine contention)."""


def _time(fn, repeat: int = 1) -> float:
    """Best wall-clock seconds of ``repeat`` calls."""
    best = float("inf")
    for _ in range(repeat):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wall = time.perf_counter() - t0
        CPU["wall"] += wall
        CPU["cpu"] += time.process_time() - c0
        best = min(best, wall)
    return best


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--source", default="human", choices=["human", "primitives"])
    ap.add_argument("--pairs", type=int, default=64, help="training pairs of the end-to-end run (4 images each)")
    ap.add_argument("--image-size", type=int, default=64)
    ap.add_argument("--batch", type=int, default=64, help="views per render call")
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--renderer", action="append", help="backends (default: all installed)")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    backends = args.renderer or available_renderers()
    print(f"source={args.source} image={args.image_size}px threads={torch.get_num_threads()} backends={backends}")

    # --- stages ------------------------------------------------------------------------------------
    t0 = time.perf_counter()
    source = source_class(args.source)()
    subjects = source.subjects("train", 2, 0)
    source.bodies(subjects[0], [1])  # loads the model (anny) and computes subject 0's scale
    t_load = time.perf_counter() - t0
    t_subject = _time(lambda: source.bodies(subjects[1], [1]))  # scale of a new subject + one pose
    ids = list(range(2, 2 + args.batch))
    t_pose = _time(lambda: source.bodies(subjects[0], ids), repeat=2)
    pose_rate = len(ids) / t_pose
    bodies = source.bodies(subjects[0], ids)
    scene = preset_config("human", "small").scene
    az = np.random.default_rng(0).uniform(0, 360, len(bodies)).astype(np.float32)
    render_rate = {}
    for name in backends:
        r = make_renderer(name)
        render_views(r, bodies[:4], np.arange(4), az[:4], scene, args.image_size)  # warm-up (kernel compile)
        t = _time(lambda r=r: render_views(r, bodies, np.arange(len(bodies)), az, scene, args.image_size,
                                       batch_size=args.batch), repeat=2)
        render_rate[name] = len(bodies) / t
    print(f"model load + first subject scale: {t_load:6.2f} s")
    print(f"new subject (scale + 1 pose):     {t_subject:6.2f} s")
    print(f"posing:                           {pose_rate:6.1f} bodies/s (batch {len(ids)})")
    for name, rate in render_rate.items():
        ratio = rate / render_rate[backends[0]]
        print(f"render {name:<8}                   {rate:6.1f} images/s  ({ratio:.2f}x {backends[0]})")

    # --- end to end ----------------------------------------------------------------------------------
    splits = {"train": SplitConfig("pairs", subjects=1, pairs=args.pairs, meshes=False)}
    cfg = GenerationConfig(args.source, "bench", splits, image_size=args.image_size, shard_images=256)
    e2e = {}
    for name in backends:
        with tempfile.TemporaryDirectory() as tmp:
            c = replace(cfg, renderer=name)
            t = _time(lambda c=c, tmp=tmp: Dataset.generate(c, Path(tmp) / "ds", source=source, progress=False, log=lambda s: None,
                                       batch_size=args.batch))
            if name == backends[0]:
                ds = Dataset.open(Path(tmp) / "ds").quadruplets()
                t_read = _time(lambda ds=ds: [ds[i] for i in range(len(ds))])
                read_rate = len(ds) / t_read
        e2e[name] = 4 * args.pairs / t
        print(f"end-to-end {name:<8} {4 * args.pairs} images in {t:6.2f} s = {e2e[name]:6.1f} images/s "
              "(posing + rendering + writing; model already loaded)")

    print(f"reading: QuadrupletDataset {read_rate:8.0f} quadruplets/s (one process, memory-mapped shards)")

    # --- projections -----------------------------------------------------------------------------------
    print("\nprojected preset times (model load + subjects + images at the end-to-end rate; "
          "test poses need 1 body per 4 images instead of 2):")
    busy = CPU["cpu"] / max(CPU["wall"], 1e-9)
    print(f"(this process got {busy:.2f} of the {args.threads} cores it asked for while timed; on a busy machine the "
          f"times below are up to {args.threads / max(busy, 1e-9):.1f}x what {args.threads} free cores would give)")
    print(f"{'preset':<8} {'images':>7} {'bodies':>7} " + " ".join(f"{n:>12}" for n in backends) + "   target")
    for preset, target in (("small", 300.0), ("paper", 7200.0)):
        plan = make_plan(preset_config("human", preset), source_class("human")() if args.source == "human" else source)
        images = sum(plan.totals(s)["images"] for s in plan.shards)
        meshes = sum(plan.totals(s)["meshes"] for s in plan.shards)
        row = []
        for name in backends:
            # the e2e rate covers 2 bodies per 4 images; correct for the split's actual body count
            per_image = 1.0 / e2e[name] - (0.5 / pose_rate)
            total = t_load + len(plan.subjects) * t_subject + images * per_image + meshes / pose_rate
            row.append(f"{total / 60:9.1f} min")
        cells = " ".join(f"{x:>12}" for x in row)
        print(f"{preset:<8} {images:>7} {meshes:>7} {cells}   < {target / 60:.0f} min")


if __name__ == "__main__":
    main()
