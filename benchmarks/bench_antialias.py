"""Benchmark: the cost of analytic antialiasing (visibility gradients) in render_parts, per backend.

Renders a Cerberus-like batch (the first 16 renders of ``bench_render.py``'s training batch: 9 parts
of 162-vertex icospheres per scene) at each size, with ``antialias`` off and on, and prints side by
side the median milliseconds of the forward pass (render_parts + an MSE loss on image and alpha)
and of forward + backward (down to the part vertices), and what antialiasing adds.

Run:  python benchmarks/bench_antialias.py [--sizes 64 128] [--batch 16] [--repeats 7]
                                           [--backends torch warp] [--threads N]
"""
from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import torch

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_render import training_batch  # noqa: E402  (the shared workload)

from cerberus_core.render.api import render_parts  # noqa: E402
from cerberus_core.render.backends import available_renderers, make_renderer  # noqa: E402
from cerberus_core.render.light import Light  # noqa: E402

HEADER = (f"{'size':>4}  {'backend':<8} {'aa':<4} {'fwd ms':>8} {'fwd+bwd ms':>11} {'+fwd ms':>8} "
          f"{'+fwd+bwd ms':>12} {'edge px':>8}")


def measure(name: str, size: int, batch: int, repeats: int, warmup: int) -> list[tuple]:
    """Rows ``(size, backend, aa, fwd_ms, total_ms, soft_pixels)`` for antialias off and on."""
    work = training_batch(size)
    parts, camera = work.parts[:batch].contiguous(), work.camera.index(slice(0, batch))
    target = work.target[:batch]
    with torch.no_grad():
        target_alpha = render_parts(make_renderer(name), parts.roll(1, 0), work.faces, camera).alpha
    renderer = make_renderer(name)
    light = Light.following(camera)
    rows = []
    for aa in (False, True):
        def step(aa: bool = aa) -> tuple[float, float, int]:
            p = parts.clone().requires_grad_(True)
            t0 = time.perf_counter()
            out = render_parts(renderer, p, work.faces, camera, light, albedo=work.albedo, antialias=aa)
            mse = torch.nn.functional.mse_loss
            loss = mse(out.image, target) + mse(out.alpha, target_alpha)
            t1 = time.perf_counter()
            loss.backward()
            t2 = time.perf_counter()
            soft = int(((out.alpha > 0) & (out.alpha < 1)).sum())
            return t1 - t0, t2 - t0, soft

        for _ in range(warmup):
            step()
        samples = [step() for _ in range(repeats)]
        rows.append((size, name, "on" if aa else "off", statistics.median(s[0] for s in samples) * 1e3,
                     statistics.median(s[1] for s in samples) * 1e3, samples[0][2]))
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    p.add_argument("--batch", type=int, default=16, help="renders per batch (default 16)")
    p.add_argument("--repeats", type=int, default=7)
    p.add_argument("--warmup", type=int, default=2)
    p.add_argument("--backends", nargs="+", default=None, help="default: every installed backend")
    p.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's)")
    args = p.parse_args(argv)
    if args.threads:
        torch.set_num_threads(args.threads)
    backends = args.backends or available_renderers()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"render_parts, {args.batch} scenes x 9 parts x 320 faces; median of {args.repeats} after {args.warmup} "
          f"warm-up; torch threads {torch.get_num_threads()}; load average at start {load:.1f}")
    print("fwd: render + MSE(image) + MSE(alpha); fwd+bwd: plus backward to the vertices; +: antialias on minus off; "
          "edge px: pixels with 0 < alpha < 1\n")
    print(HEADER)
    print("-" * len(HEADER))
    for size in args.sizes:
        for name in backends:
            (_, _, _, f_off, t_off, _), (_, _, _, f_on, t_on, soft) = measure(name, size, args.batch, args.repeats,
                                                                              args.warmup)
            print(f"{size:>4}  {name:<8} {'off':<4} {f_off:>8.1f} {t_off:>11.1f} {'':>8} {'':>12} {'':>8}")
            print(f"{size:>4}  {name:<8} {'on':<4} {f_on:>8.1f} {t_on:>11.1f} {f_on - f_off:>+8.1f} "
                  f"{t_on - t_off:>+12.1f} {soft:>8}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
