"""Training speed: steps per second of the ``cpu`` preset and of the ``paper`` preset's network, and
the share of each step spent rendering.

For each preset and each renderer backend (``--renderers``, default torch and warp) the script builds the model and optimiser, takes one batch of the preset's batch size
from a small ``primitives`` dataset rendered at the preset's training resolution (generated into a
temporary folder, or ``--data ROOT``), runs a few warm-up steps, then times full optimisation steps
(objective, backward, Adam). The rendering share is the time of the step's render call alone
(forward and backward of ``render_parts`` on the same scenes, all 8 B of them) over the step time.

    python benchmarks/bench_train.py                 # 2 threads, both presets, both backends
    python benchmarks/bench_train.py --threads 1 --steps 5 --renderers warp

Timings on a shared machine are noisy: the load average is printed with the results.
"""
from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

import torch


def make_data(root: Path, image_size: int) -> Path:
    from dataclasses import replace

    from cerberus_core.datasets.generate import generate
    from cerberus_core.datasets.plan import SplitConfig, preset_config

    cfg = preset_config("primitives", "tiny", image_size=image_size)
    cfg = replace(cfg, splits={"train": SplitConfig("pairs", subjects=2, pairs=16, meshes=False)})
    generate(cfg, root, progress=False, log=lambda _: None)
    return root


def bench(preset: str, renderer_name: str, data_root: Path, steps: int, warmup: int, batch_size: int | None) -> dict:
    from cerberus_core.datasets.readers import QuadrupletDataset
    from cerberus_core.losses import viewpoint_scenes
    from cerberus_core.model import Cerberus
    from cerberus_core.plugins import make_renderer, resolve_renderer
    from cerberus_core.render.api import render_parts
    from cerberus_core.render.camera import Camera
    from cerberus_core.train.config import load_config
    from cerberus_core.train.data import quadruplet_batch
    from cerberus_core.train.objective import partner_cameras, quadruplet_objective, unwrap

    cfg = load_config(preset=preset)
    data = QuadrupletDataset(data_root)
    scene = data.scene
    cfg.model.depth_offset = scene.distance
    bsz = batch_size or cfg.train.batch_size
    size = cfg.data.image_size or data.image_size
    torch.manual_seed(0)
    model = Cerberus(cfg.model)
    opt = torch.optim.Adam(model.parameters(), lr=cfg.optim.lr)
    renderer_name = resolve_renderer(renderer_name)
    renderer = make_renderer(renderer_name)
    raw = torch.utils.data.default_collate([data[i % len(data)] for i in range(bsz)])
    batch = quadruplet_batch(raw, torch.device("cpu"), scene, size)

    def step(i: int):
        out = quadruplet_objective(model, renderer, batch, scene, cfg.losses, torch.Generator().manual_seed(i))
        opt.zero_grad(set_to_none=True)
        out.total.backward()
        opt.step()

    for i in range(warmup):
        step(i)
    t0 = time.perf_counter()
    for i in range(steps):
        step(warmup + i)
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
    grad = torch.rand(verts.shape[0], 3, size, size)

    def render_once():
        img = render_parts(renderer, verts, model.faces, cams, scene.light(cams), albedo=scene.albedo,
                           background=scene.background).image
        img.backward(grad)

    render_once()
    t0 = time.perf_counter()
    for _ in range(steps):
        render_once()
    render_s = (time.perf_counter() - t0) / steps
    return {"preset": preset, "renderer": renderer_name, "batch": bsz, "size": size, "width": cfg.model.width, "images": 4 * bsz,
            "renders": verts.shape[0], "step_s": step_s, "steps_per_s": 1 / step_s, "render_s": render_s,
            "render_share": render_s / step_s}


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
    args = p.parse_args()
    torch.set_num_threads(args.threads)
    from cerberus_core.train.config import load_config

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
                rows.append(bench(preset, name, root, args.steps, args.warmup, args.batch_size))
                r = rows[-1]
                print(f"  {preset} / {r['renderer']}: {r['step_s']:.3f} s/step", flush=True)
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"\ntorch {torch.__version__}, {args.threads} threads, load average {load:.1f} "
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
