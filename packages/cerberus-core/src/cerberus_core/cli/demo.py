"""``cerberus demo``: render a demo scene of deformed parts with every installed backend."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

from cerberus_core.cli.checks import OVERWRITE_HELP, positive_int
from cerberus_core.cli.flags import FlagNames
from cerberus_core.errors import ConfigError
from cerberus_core.plumbing.outputs import check_output, writing_results
from cerberus_core.render.api import render_parts
from cerberus_core.render.backends import available_renderers, make_renderer
from cerberus_core.render.demo import demo_scene
from cerberus_core.render.light import Light
from cerberus_core.viz import atomic_save_png, image_grid, part_colors

#: Largest --image-size (4 views of it are rendered per backend).
MAX_IMAGE_SIZE = 2048


def configure(p: argparse.ArgumentParser) -> None:
    """The arguments, description and examples of ``cerberus demo`` (:data:`cerberus_core.cli.COMMANDS`)."""
    p.description = ("Render a stick figure of 9 deformed sphere parts from 4 viewpoints with each "
                       "installed renderer backend (or the one named) and write shaded and part-coloured PNGs.")
    p.add_argument("--out", type=Path, default=Path("out/demo"),
                   help=f"output folder, replaced whole (default: out/demo); {OVERWRITE_HELP}")
    p.add_argument("--renderer", action="append", help="backend(s) to use (default: all installed)")
    p.add_argument("--image-size", type=positive_int, default=128,
                   help=f"image size in pixels, 1..{MAX_IMAGE_SIZE} (default: 128)")
    p.set_defaults(func=run, flag_names=FlagNames({"out": "--out"}))


def run(args: argparse.Namespace) -> int:
    if args.image_size > MAX_IMAGE_SIZE:
        raise ConfigError(f"--image-size {args.image_size}: at most {MAX_IMAGE_SIZE}", key="image_size", value=args.image_size)
    out = args.out
    check_output(out, "demo")
    names = args.renderer or available_renderers()
    if not names:
        raise ConfigError("no renderer backend is installed: pip install cerberus-render-torch "
                          "(or cerberus-render-warp)", key="renderer")
    renderers = {name: make_renderer(name) for name in names}  # every backend found before anything is written
    parts, faces, camera = demo_scene(image_size=args.image_size)
    light = Light.following(camera)
    colours = part_colors(parts.shape[1])
    lines = []
    with writing_results(out, "demo") as tmp:  # out is replaced whole once every picture is written
        for name, renderer in renderers.items():
            t0 = time.perf_counter()
            shaded = render_parts(renderer, parts, faces, camera, light, background=(1.0, 1.0, 1.0))
            coloured = render_parts(renderer, parts, faces, camera, light, albedo=colours, background=(1.0, 1.0, 1.0))
            ms = (time.perf_counter() - t0) * 1000
            grid = image_grid([shaded.image, coloured.image], row_titles=["shaded", "parts"])
            atomic_save_png(grid, tmp / f"demo_{name}.png")
            lines.append(f"{name:<8} {ms:8.1f} ms  -> {out / f'demo_{name}.png'}")
    print("\n".join(lines))
    return 0
