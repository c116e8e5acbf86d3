"""Benchmark: the memory one view takes per pixel while ``render_views`` draws it (the basis of
``cerberus_core.datasets.generate.RENDER_BYTES_PER_PIXEL``, which ``validate_generation`` uses to
refuse a generation that cannot fit in memory).

For each installed backend and image size, a fresh process renders ``--views`` views of a tiny
primitives shard in one batch and reports the growth of its peak resident memory divided by
``views x size^2`` (CPU).

Run:  python benchmarks/bench_render_memory.py [--sizes 256 512] [--views 16]
"""
from __future__ import annotations

import argparse
import subprocess
import sys

PROBE = """
import resource, sys
import numpy as np
from cerberus_core.bodies.body import source_class
from cerberus_core.datasets.generate import build_bodies, render_views
from cerberus_core.datasets.plan import make_plan, preset_config
from cerberus_core.render.backends import make_renderer
name, size, views = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
config = preset_config("primitives", "tiny", image_size=size)
source = source_class("primitives")()
plan = make_plan(config, source)
shard = plan.shards["train"][0]
bodies = build_bodies(source, plan.subjects, shard.meshes, len(source.part_names))
renderer = make_renderer(name)
pick = np.arange(views) % len(shard.views)
mesh, azimuth = shard.views["mesh"][pick], shard.views["azimuth"][pick]
render_views(renderer, bodies, mesh[:2], azimuth[:2], config.scene, 16, batch_size=2)  # warm-up
before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
render_views(renderer, bodies, mesh, azimuth, config.scene, size, batch_size=views)
grown = (resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) * 1024
print(f"{name:<6} {size:>5} px {views:>3} views  {grown / 2**20:8.1f} MiB  {grown / (views * size * size):6.1f} B/pixel")
"""


def main() -> None:
    from cerberus_core.render.backends import available_renderers

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=int, nargs="+", default=[256, 512])
    parser.add_argument("--views", type=int, default=16)
    args = parser.parse_args()
    for name in available_renderers():
        for size in args.sizes:
            out = subprocess.run([sys.executable, "-c", PROBE, name, str(size), str(args.views)], capture_output=True,
                                 text=True, check=True)
            print(out.stdout.strip().splitlines()[-1])


if __name__ == "__main__":
    main()
