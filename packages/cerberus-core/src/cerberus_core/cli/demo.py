"""``cerberus demo``: render a demo scene of deformed parts with every installed backend."""
from __future__ import annotations

import argparse
import time
from pathlib import Path

import torch

from cerberus_core.cli.checks import output_folder, positive_int
from cerberus_core.errors import ConfigError
from cerberus_core.plugins import available_renderers, make_renderer
from cerberus_core.render.api import render_parts
from cerberus_core.render.camera import Camera
from cerberus_core.render.interface import Light
from cerberus_core.render.templates import icosphere
from cerberus_core.viz import part_colors, save_image_grid

#: Largest --image-size (4 views of it are rendered per backend).
MAX_IMAGE_SIZE = 2048

# A stick figure of 9 ellipsoids: (centre xyz, radii xyz), normalised units.
_FIGURE = [
    ((0.0, 0.33, 0.0), (0.07, 0.08, 0.07)),     # head
    ((0.0, 0.12, 0.0), (0.11, 0.14, 0.07)),     # torso
    ((-0.06, -0.12, 0.0), (0.045, 0.10, 0.045)),  # left thigh
    ((0.06, -0.12, 0.0), (0.045, 0.10, 0.045)),   # right thigh
    ((-0.06, -0.33, 0.02), (0.035, 0.10, 0.035)),  # left shin
    ((0.06, -0.33, -0.02), (0.035, 0.10, 0.035)),  # right shin
    ((-0.17, 0.13, 0.0), (0.03, 0.12, 0.03)),   # left arm
    ((0.17, 0.13, 0.0), (0.03, 0.12, 0.03)),    # right arm
    ((0.0, 0.23, 0.0), (0.035, 0.04, 0.035)),   # neck
]


def demo_scene(batch: int = 4, image_size: int = 128, seed: int = 0):
    """Deformed parts of a stick figure seen from ``batch`` azimuths.

    Returns:
        ``(parts (B, 9, 162, 3), faces (320, 3), camera)``.
    """
    g = torch.Generator().manual_seed(seed)
    t = icosphere(2)
    centres = torch.tensor([c for c, _ in _FIGURE])
    radii = torch.tensor([r for _, r in _FIGURE])
    bump = 1 + 0.08 * torch.sin(3 * t.vertices[:, :1] + torch.rand(len(_FIGURE), 1, 1, generator=g) * 6)
    parts = t.vertices.unsqueeze(0) * bump * radii.unsqueeze(1) + centres.unsqueeze(1)
    parts = parts.unsqueeze(0).expand(batch, -1, -1, -1).contiguous()
    camera = Camera.look_at(torch.linspace(0, 270, batch), 15.0, 2.2, fov_y_deg=30.0, image_size=image_size)
    return parts, t.faces, camera


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="render a demo scene with every installed renderer backend",
                       description="Render a stick figure of 9 deformed sphere parts from 4 viewpoints with each "
                       "installed renderer backend (or the one named) and write shaded and part-coloured PNGs.")
    p.add_argument("--out", type=Path, default=Path("out/demo"), help="output folder (default: out/demo)")
    p.add_argument("--renderer", action="append", help="backend(s) to use (default: all installed)")
    p.add_argument("--image-size", type=positive_int, default=128,
                   help=f"image size in pixels, 1..{MAX_IMAGE_SIZE} (default: 128)")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.image_size > MAX_IMAGE_SIZE:
        raise ConfigError(f"--image-size {args.image_size}: at most {MAX_IMAGE_SIZE}")
    out = output_folder(args.out)
    names = args.renderer or available_renderers()
    if not names:
        raise ConfigError("no renderer backend is installed: pip install cerberus-render-torch "
                          "(or cerberus-render-warp)")
    renderers = {name: make_renderer(name) for name in names}  # every backend found before anything is written
    parts, faces, camera = demo_scene(image_size=args.image_size)
    light = Light.following(camera)
    colours = part_colors(parts.shape[1])
    out.mkdir(parents=True, exist_ok=True)
    for name, renderer in renderers.items():
        t0 = time.perf_counter()
        shaded = render_parts(renderer, parts, faces, camera, light, background=(1.0, 1.0, 1.0))
        coloured = render_parts(renderer, parts, faces, camera, light, albedo=colours, background=(1.0, 1.0, 1.0))
        ms = (time.perf_counter() - t0) * 1000
        path = out / f"demo_{name}.png"
        save_image_grid([shaded.image, coloured.image], path, titles=["shaded", "parts"])
        print(f"{name:<8} {ms:8.1f} ms  -> {path}")
    return 0
