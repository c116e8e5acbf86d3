"""``cerberus reconstruct``: part meshes and pictures from images with a trained model."""
from __future__ import annotations

import argparse
from pathlib import Path

import torch

from cerberus_core.plugins import make_renderer


def add_parser(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "reconstruct", help="3D part meshes (GLB, OBJ) and pictures from one or more images",
        description="Run a trained model on images. For each image writes the posed part meshes as one GLB (parts "
        "as named nodes, each a distinct colour) and OBJ files, and PNGs: the input, the reconstruction, the parts "
        "in colours, a turntable, a new lighting direction, and a new pose (this image's parts posed with the "
        "rotations and translations predicted from the next image), and index.html, an interactive 3D viewer of "
        "them that works offline. Images of another size are centre-cropped and "
        "resized (with a warning); an alpha channel is composited over the training background.")
    p.add_argument("run", type=Path, help="run folder, model.safetensors or checkpoint .pt")
    p.add_argument("images", type=Path, nargs="+", help="input image files (PNG, JPEG, ...)")
    p.add_argument("--out", type=Path, default=Path("out/reconstruct"), help="output folder (default: out/reconstruct)")
    p.add_argument("--data", type=Path, help="dataset whose scene set-up (camera elevation, distance, fov, light) "
                   "the images follow (default: the run's training data, else the toolkit's default scene)")
    p.add_argument("--azimuth", type=float, default=0.0,
                   help="camera azimuth assumed for the inputs, degrees (default 0; it only fixes the world frame)")
    p.add_argument("--renderer", help="renderer backend for the pictures (default: the run's)")
    p.add_argument("--device", default="cpu", help="device for the model (default: cpu)")
    p.add_argument("--viewer-images", type=int, default=12, metavar="N",
                   help="images in the interactive 3D viewer OUT/index.html (default: the first 12; 0: no viewer)")
    p.set_defaults(func=run)


def scene_for(config, data: Path | None):
    """The scene set-up the model was trained with: from ``data`` (which must be a dataset), else from
    the run's training data if it is still there, else the toolkit's default scene."""
    from cerberus_core.data.format import MANIFEST, read_manifest
    from cerberus_core.data.scene import SceneSetup

    if data is None and (Path(config.data.root) / MANIFEST).is_file():
        data = Path(config.data.root)
    return SceneSetup.from_dict(read_manifest(data)["scene"]) if data is not None else SceneSetup()


def run(args: argparse.Namespace) -> int:
    from cerberus_core.eval.export import export_reconstruction
    from cerberus_core.eval.figures import save_image_pictures
    from cerberus_core.eval.images import ImageInputError, load_images
    from cerberus_core.eval.reconstruction import as_part_reconstruction
    from cerberus_core.eval.viewer import write_reconstruction_viewer
    from cerberus_core.train.checkpoint import load_model

    model, config = load_model(args.run, args.device)
    scene = scene_for(config, args.data)
    size = int(config.data.image_size or 64)
    try:
        images, loaded = load_images(args.images, size, scene.background)
    except ImageInputError as exc:
        print(f"cerberus reconstruct: {exc}")
        return 2
    camera = scene.cameras([args.azimuth] * len(images), size)
    with torch.no_grad():
        recon = as_part_reconstruction(model.reconstruct(images.to(args.device), camera.to(args.device))).to("cpu")
    renderer = make_renderer(args.renderer or config.renderer)
    stems = [p.stem for p in args.images]
    written = export_reconstruction(recon, args.out, stems)
    for i, stem in enumerate(stems):
        donor = recon.index([(i + 1) % len(stems)]) if len(stems) > 1 else None
        written += save_image_pictures(renderer, images[i], recon.index([i]), camera.index([i]),
                                       args.out, stem, pose_donor=donor, background=scene.background)
    written += write_reconstruction_viewer(args.out, images, recon, camera, stems, limit=args.viewer_images,
                                           limit_hint="--viewer-images", title=f"cerberus reconstruct: {args.run}",
                                           background=scene.background)
    print(f"wrote {len(written)} files for {len(stems)} image(s) to {args.out}")
    if args.viewer_images > 0:
        print(f"3D viewer: {args.out / 'index.html'}")
    return 0
