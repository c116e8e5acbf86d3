"""Time the Cerberus training render (forward + backward) per backend and split it into stages.

The workload of the issue: a batch of scenes, each ``--parts`` icosphere-level-2 parts of radius 0.1
placed in a [-0.5, 0.5]^3 body, seen from distance 2.5 with a 30 degree field of view, rendered with
:func:`cerberus_core.render_parts` and back-propagated to the part vertices. Stages (milliseconds):

* ``core_fwd``: world_to_clip + ``renderer.vertex_normals`` (before rasterization),
* ``raster``: ``renderer.rasterize``; ``shade``: ``renderer.shade``,
* ``composite``: core's alpha / background / part-id code after the backend,
* ``*_bwd``: the backward of the same groups (core, backend shading, compositing).

Columns: one per backend (default ``torch`` and ``warp``). Prints one table per image size with the median over ``--repeats`` runs (after one warm-up run) and the ratios to ``torch``.
Example: ``python scripts/profile_split.py --batch 128 --sizes 64 128 --threads 2``.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

import torch

from cerberus_core import Camera, Light, icosphere, make_renderer, render_parts
from cerberus_core.render.api import pack_parts


def make_scene(batch: int, parts: int, size: int, seed: int = 0):
    gen = torch.Generator().manual_seed(seed)
    sphere = icosphere(2)
    centres = torch.rand(batch, parts, 1, 3, generator=gen) - 0.5
    part_vertices = (0.1 * sphere.vertices).expand(batch, parts, -1, -1) + centres
    cam = Camera.look_at(torch.rand(batch, generator=gen) * 360, torch.rand(batch, generator=gen) * 40 - 20, 2.5,
                         fov_y_deg=30.0, image_size=size)
    return part_vertices, sphere.faces, cam


CLOCK = time.perf_counter
"""Wall clock by default; ``--clock cpu`` uses the process CPU time (all threads), which a busy
shared machine inflates less (compare backends at ``--threads 1`` then)."""


def staged(renderer, part_vertices, faces, cam):
    """One forward + backward, timed per stage (ms), mirroring :func:`cerberus_core.render.api.render`."""
    clock = CLOCK
    pv = part_vertices.clone().requires_grad_(True)
    t0 = clock()
    vertices, packed, face_part = pack_parts(pv, faces)
    clip = cam.world_to_clip(vertices)
    normals = renderer.vertex_normals(vertices, packed)
    t1 = clock()
    with torch.no_grad():
        face_id = renderer.rasterize(clip.detach(), packed, cam.height, cam.width, cam.near)
    t2 = clock()
    light = Light.following(cam)
    albedo = torch.tensor([0.8, 0.8, 0.8]).expand(vertices.shape)
    rgb, depth = renderer.shade(clip, packed, face_id, normals, albedo, light)
    t3 = clock()
    alpha = (face_id >= 0).to(vertices.dtype).unsqueeze(-1)
    image = (rgb + (1 - alpha) * torch.zeros(1, 1, 1, 3)).permute(0, 3, 1, 2)
    part_id = torch.cat([face_part, face_part.new_full((1,), -1)])[face_id]
    loss = image.square().mean() + depth.unsqueeze(1).mean()
    t4 = clock()
    g_rgb, g_depth = torch.autograd.grad(loss, [rgb, depth], retain_graph=True)
    t5 = clock()
    g_clip, g_normals = torch.autograd.grad([rgb, depth], [clip, normals], [g_rgb, g_depth], retain_graph=True)
    t6 = clock()
    torch.autograd.grad([clip, normals], [pv], [g_clip, g_normals])
    t7 = clock()
    del part_id
    t = dict(core_fwd=t1 - t0, raster=t2 - t1, shade=t3 - t2, composite=t4 - t3,
             composite_bwd=t5 - t4, shade_bwd=t6 - t5, core_bwd=t7 - t6)
    return {k: 1e3 * v for k, v in t.items()}


def end_to_end(renderer, part_vertices, faces, cam):
    """The plain ``render_parts`` forward and ``loss.backward()`` (ms)."""
    pv = part_vertices.clone().requires_grad_(True)
    t0 = CLOCK()
    out = render_parts(renderer, pv, faces, cam, Light.following(cam))
    loss = out.image.square().mean() + out.depth.mean()
    t1 = CLOCK()
    loss.backward()
    t2 = CLOCK()
    return {"fwd": 1e3 * (t1 - t0), "bwd": 1e3 * (t2 - t1)}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--batch", type=int, default=128)
    p.add_argument("--parts", type=int, default=9)
    p.add_argument("--sizes", type=int, nargs="+", default=[64, 128])
    p.add_argument("--backends", nargs="+", default=["torch", "warp"], help="backend names")
    p.add_argument("--repeats", type=int, default=5)
    p.add_argument("--threads", type=int, default=None, help="torch intra-op threads (default: torch's choice)")
    p.add_argument("--clock", choices=["wall", "cpu"], default="wall",
                   help="wall-clock time, or process CPU time (summed over threads)")
    args = p.parse_args()
    global CLOCK
    CLOCK = time.process_time if args.clock == "cpu" else time.perf_counter
    if args.threads:
        torch.set_num_threads(args.threads)
    print(f"torch threads: {torch.get_num_threads()}; {args.clock} clock; batch {args.batch}, "
          f"{args.parts} parts x 320 faces; load average {os.getloadavg()[0]:.1f}")
    for size in args.sizes:
        scene = make_scene(args.batch, args.parts, size)
        rows = {}
        for name in args.backends:
            r = make_renderer(name)
            end_to_end(r, *scene)  # warm-up (and kernel load)
            e2e = [end_to_end(r, *scene) for _ in range(args.repeats)]
            st = [staged(r, *scene) for _ in range(args.repeats)]
            row = {k: statistics.median(x[k] for x in e2e) for k in e2e[0]}
            row.update({k: statistics.median(x[k] for x in st) for k in st[0]})
            rows[name] = row
        keys = list(next(iter(rows.values())))
        print(f"\n{size}x{size}  (median ms, {args.clock} clock)")
        names = list(rows)
        print(f"{'stage':<14}" + "".join(f"{n:>14}" for n in names) + "".join(f"{'/' + n:>14}" for n in names[1:]))
        for k in keys:
            vals = [rows[n][k] for n in names]
            ratios = "".join(f"{vals[0] / v:>13.1f}x" if v > 0 else f"{'-':>14}" for v in vals[1:])
            print(f"{k:<14}" + "".join(f"{v:>14.1f}" for v in vals) + ratios)


if __name__ == "__main__":
    main()
